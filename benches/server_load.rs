//! Load benchmark of `POST /v1/forward` over loopback, on both backends
//! (tract, and the default: the ONNX Runtime embedded in the binary), with
//! dynamic batching on (the default) and off (`--max-batch 1`):
//! - latency of one request at a time, N = 10, 15, 30;
//! - 64 concurrent single-action clients, and 4 clients of 64-action calls,
//!   at N = 15 and 30: requests/s, actions/s, p50/p99 of the answered ones,
//!   every status seen, and the server's compute as a fraction of the f32
//!   GEMM peak measured in the same run (actions/s × FLOPs of one forward
//!   pass at that N ÷ peak).
//!
//!     cargo bench --bench server_load
//!
//! Prints numbers; asserts nothing.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use serde_json::json;
use treemanip::api::types::TreeJson;
use treemanip::tree::{ScaParams, generate};

#[allow(dead_code)] // the bench uses part of the tests' helper
#[path = "../crates/server/tests/it/common/server.rs"]
mod server;

#[allow(dead_code)]
#[path = "common/peak.rs"]
mod peak;

const SECONDS: f64 = 5.0;

fn body(n: usize, actions: usize) -> Vec<u8> {
    let tree = generate(n, 8, &ScaParams::default()).unwrap();
    serde_json::to_vec(&json!({
        "tree": TreeJson::from_tree(&tree),
        "contact_nodes": (0..actions).map(|k| 1 + k % (n - 1)).collect::<Vec<_>>(),
        "pushes": (0..actions).map(|k| [0.0, 0.05 + 0.001 * k as f64, 0.02]).collect::<Vec<_>>(),
    }))
    .unwrap()
}

/// `clients` keep-alive clients posting `body` for `seconds`: (status, ms)
/// of every request (status 0: connection error).
fn drive(addr: &str, body: &[u8], clients: usize, seconds: f64) -> (Vec<(u16, f64)>, f64) {
    let deadline = Instant::now() + Duration::from_secs_f64(seconds);
    let started = Instant::now();
    let results = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..clients)
            .map(|_| {
                scope.spawn(move || {
                    let agent = server::client();
                    let url = format!("http://{addr}/v1/forward");
                    let mut times = Vec::new();
                    while Instant::now() < deadline {
                        let t = Instant::now();
                        let status = match agent
                            .post(&url)
                            .header("content-type", "application/json")
                            .send(body)
                        {
                            Ok(mut r) => {
                                let _ = r.body_mut().read_to_vec();
                                r.status().as_u16()
                            }
                            Err(ureq::Error::StatusCode(code)) => code,
                            Err(_) => 0,
                        };
                        times.push((status, t.elapsed().as_secs_f64() * 1e3));
                    }
                    times
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap())
            .collect::<Vec<_>>()
    });
    (results, started.elapsed().as_secs_f64())
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() as f64 * p) as usize).min(sorted.len() - 1)]
}

fn main() {
    let peak = peak::gemm_peak();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!("f32 GEMM peak (1024³, {cores} threads, best of 8): {peak:.1} GFLOP/s");
    // tract is forced with a library that does not exist; the default is
    // the ONNX Runtime embedded in the binary (or, in a build without it,
    // the library `scripts/fetch-onnxruntime` brings).
    let mut backends: Vec<(&str, Option<String>)> =
        vec![("tract", Some("/nonexistent/libonnxruntime.so".to_owned()))];
    if treemanip::infer::EMBEDDED {
        backends.push(("onnxruntime (embedded default)", None));
    } else {
        let script = concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/fetch-onnxruntime");
        match std::process::Command::new(script).output() {
            Ok(out) if out.status.success() => backends.push((
                "onnxruntime",
                Some(String::from_utf8_lossy(&out.stdout).trim().to_owned()),
            )),
            _ => println!("ONNX Runtime is not available: tract only"),
        }
    }
    let models = concat!(env!("CARGO_MANIFEST_DIR"), "/models");
    println!(
        "POST /v1/forward; {SECONDS} s per row; compute % = actions/s x FLOPs per forward pass / peak"
    );
    for (backend, library) in &backends {
        for batching in [true, false] {
            let mut args = vec!["--models-dir", models, "--max-in-flight", "64"];
            if let Some(l) = library {
                args.extend(["--ort-dylib", l.as_str()]);
            }
            if !batching {
                args.extend(["--max-batch", "1"]);
            }
            let server = server::Server::start(&args);
            let label = format!(
                "{backend}, batching {}",
                if batching {
                    "on"
                } else {
                    "off (--max-batch 1)"
                }
            );
            if batching {
                for n in [10usize, 15, 30] {
                    let (results, _) = drive(&server.addr, &body(n, 1), 1, 2.0);
                    let mut ms: Vec<f64> =
                        results.iter().filter(|r| r.0 == 200).map(|r| r.1).collect();
                    ms.sort_by(f64::total_cmp);
                    println!(
                        "{label}: one client, N={n:<3} latency p50 {:>7.2} ms  p99 {:>7.2} ms",
                        percentile(&ms, 0.5),
                        percentile(&ms, 0.99)
                    );
                }
            }
            for n in [15usize, 30] {
                for (clients, actions) in [(64usize, 1usize), (4, 64)] {
                    let (results, elapsed) =
                        drive(&server.addr, &body(n, actions), clients, SECONDS);
                    let mut statuses = BTreeMap::new();
                    for (status, _) in &results {
                        *statuses.entry(*status).or_insert(0usize) += 1;
                    }
                    let mut ms: Vec<f64> =
                        results.iter().filter(|r| r.0 == 200).map(|r| r.1).collect();
                    ms.sort_by(f64::total_cmp);
                    let rps = ms.len() as f64 / elapsed;
                    let aps = rps * actions as f64;
                    let compute = aps * peak::forward_gnn_flops(n) / 1e9 / peak;
                    println!(
                        "{label}: N={n:<3} {clients:>2} clients x {actions:>2} actions {rps:>8.1} req/s {aps:>8.1} actions/s  compute {:>5.1} %  p50 {:>7.1} ms  p99 {:>7.1} ms  statuses {statuses:?}",
                        100.0 * compute,
                        percentile(&ms, 0.5),
                        percentile(&ms, 0.99)
                    );
                }
            }
            drop(server);
        }
    }
}
