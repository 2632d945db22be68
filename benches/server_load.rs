//! Load benchmark of `POST /v1/forward` over loopback: throughput and
//! p50/p99 latency at N = 15 and 30, 1 and 64 actions per call, with
//! several keep-alive connections. The backend is tract, or native ONNX
//! Runtime when `ORT_DYLIB_PATH` is set (it is passed to the server):
//!
//!     cargo bench --bench server_load
//!     ORT_DYLIB_PATH=$(scripts/fetch-onnxruntime) cargo bench --bench server_load
//!
//! Prints numbers; asserts nothing.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use serde_json::json;
use treemanip::api::tree_json::TreeJson;
use treemanip::tree::{ScaParams, generate};

#[allow(dead_code)] // the bench uses part of the tests' helper
#[path = "../tests/it/common/server.rs"]
mod server;

const CONNECTIONS: usize = 4;
const SECONDS: f64 = 6.0;

fn main() {
    let server = server::Server::start(&[
        "--max-in-flight",
        "64",
        "--models-dir",
        concat!(env!("CARGO_MANIFEST_DIR"), "/models"),
    ]);
    let addr = server.addr.clone();
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
            let results: Vec<(u16, f64)> = std::thread::scope(|scope| {
                let handles: Vec<_> = (0..CONNECTIONS)
                    .map(|_| {
                        let (addr, body) = (&addr, &body);
                        scope.spawn(move || {
                            // One keep-alive connection per client.
                            let agent = server::client();
                            let url = format!("http://{addr}/v1/forward");
                            let mut times = Vec::new();
                            while Instant::now() < deadline {
                                let t = Instant::now();
                                let status = match agent
                                    .post(&url)
                                    .header("content-type", "application/json")
                                    .send(&body[..])
                                {
                                    Ok(mut r) => {
                                        let _ = r.body_mut().read_to_vec();
                                        r.status().as_u16()
                                    }
                                    Err(_) => 0, // connection error
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
                    .collect()
            });
            let elapsed = started.elapsed().as_secs_f64();
            let mut statuses = BTreeMap::new();
            for (status, _) in &results {
                *statuses.entry(*status).or_insert(0usize) += 1;
            }
            // Latency of the answered requests (200s).
            let mut sorted: Vec<f64> = results
                .iter()
                .filter(|(s, _)| *s == 200)
                .map(|(_, t)| *t)
                .collect();
            if sorted.is_empty() {
                println!("  N={n:<3} actions={actions:<3} no request succeeded: {statuses:?}");
                continue;
            }
            sorted.sort_by(f64::total_cmp);
            let pct = |p: f64| sorted[((sorted.len() as f64 * p) as usize).min(sorted.len() - 1)];
            println!(
                "  N={n:<3} actions={actions:<3} {:>8.1} req/s {:>9.1} actions/s  p50 {:>7.2} ms  p99 {:>7.2} ms  statuses {statuses:?}",
                sorted.len() as f64 / elapsed,
                (sorted.len() * actions) as f64 / elapsed,
                pct(0.5),
                pct(0.99)
            );
        }
    }
    drop(server);
}
