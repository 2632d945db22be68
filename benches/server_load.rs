//! Load benchmark of `POST /v1/forward` over loopback: throughput and
//! p50/p99 latency at N = 15 and 30, 1 and 64 actions per call, with
//! several keep-alive connections. The backend is tract, or native ONNX
//! Runtime when `ORT_DYLIB_PATH` is set (it is passed to the server):
//!
//!     cargo bench --bench server_load
//!     ORT_DYLIB_PATH=$(scripts/fetch-onnxruntime) cargo bench --bench server_load
//!
//! Prints numbers; asserts nothing.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::json;
use treemanip::api::tree_json::TreeJson;
use treemanip::tree::{ScaParams, generate};

const CONNECTIONS: usize = 4;
const SECONDS: f64 = 6.0;

/// One keep-alive HTTP/1.1 POST; returns the status.
fn post(stream: &mut BufReader<TcpStream>, path: &str, body: &[u8]) -> u16 {
    // One write per request: separate small writes meet Nagle's algorithm
    // and delayed ACKs, which add ~40 ms to every call.
    let mut request = format!(
        "POST {path} HTTP/1.1\r\nHost: bench\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n",
        body.len()
    )
    .into_bytes();
    request.extend_from_slice(body);
    stream.get_mut().write_all(&request).unwrap();
    let mut status_line = String::new();
    stream.read_line(&mut status_line).unwrap();
    let status = status_line
        .split_whitespace()
        .nth(1)
        .unwrap()
        .parse()
        .unwrap();
    let mut length = 0usize;
    loop {
        let mut line = String::new();
        stream.read_line(&mut line).unwrap();
        let line = line.trim_end();
        if line.is_empty() {
            break;
        }
        if let Some(v) = line.to_ascii_lowercase().strip_prefix("content-length:") {
            length = v.trim().parse().unwrap();
        }
    }
    let mut body = vec![0u8; length];
    stream.read_exact(&mut body).unwrap();
    status
}

fn main() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_treemanip-server"))
        .args(["--bind", "127.0.0.1:0", "--max-in-flight", "64"])
        .args([
            "--models-dir",
            concat!(env!("CARGO_MANIFEST_DIR"), "/models"),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("server starts");
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let addr = line
        .trim()
        .strip_prefix("listening on http://")
        .unwrap()
        .to_owned();
    let backend =
        std::env::var("ORT_DYLIB_PATH").map_or("tract".to_owned(), |_| "onnxruntime".to_owned());
    println!("POST /v1/forward, backend {backend}, {CONNECTIONS} connections, {SECONDS} s per row");
    for n in [15usize, 30] {
        let tree = generate(n, 8, &ScaParams::default()).unwrap();
        for actions in [1usize, 64] {
            let body = serde_json::to_vec(&json!({
                "tree": TreeJson::from_tree(&tree),
                "contact_nodes": (0..actions).map(|k| 1 + k % (n - 1)).collect::<Vec<_>>(),
                "pushes": (0..actions).map(|k| [0.0, 0.05 + 0.001 * k as f64, 0.02]).collect::<Vec<_>>(),
            }))
            .unwrap();
            let deadline = Instant::now() + Duration::from_secs_f64(SECONDS);
            let started = Instant::now();
            let latencies: Vec<f64> = std::thread::scope(|scope| {
                let handles: Vec<_> = (0..CONNECTIONS)
                    .map(|_| {
                        let (addr, body) = (&addr, &body);
                        scope.spawn(move || {
                            let socket = TcpStream::connect(addr).unwrap();
                            socket.set_nodelay(true).unwrap();
                            let mut stream = BufReader::new(socket);
                            let mut times = Vec::new();
                            while Instant::now() < deadline {
                                let t = Instant::now();
                                let status = post(&mut stream, "/v1/forward", body);
                                assert_eq!(status, 200);
                                times.push(t.elapsed().as_secs_f64() * 1e3);
                            }
                            times
                        })
                    })
                    .collect();
                handles
                    .into_iter()
                    .flat_map(|h| h.join().unwrap())
                    .collect()
            });
            let elapsed = started.elapsed().as_secs_f64();
            let mut sorted = latencies.clone();
            sorted.sort_by(f64::total_cmp);
            let pct = |p: f64| sorted[((sorted.len() as f64 * p) as usize).min(sorted.len() - 1)];
            println!(
                "  N={n:<3} actions={actions:<3} {:>8.1} req/s {:>9.1} actions/s  p50 {:>7.2} ms  p99 {:>7.2} ms",
                sorted.len() as f64 / elapsed,
                (sorted.len() * actions) as f64 / elapsed,
                pct(0.5),
                pct(0.99)
            );
        }
    }
    let _ = child.kill();
    let _ = child.wait();
}
