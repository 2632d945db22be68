//! Soak and overload: the server driven at saturation with a mix of every
//! endpoint (plans with their full budget included) from more clients than
//! `--max-in-flight` admits, for `SOAK_SECONDS` (default 600). Reports the
//! answers by status (only 200, 503 shed and 504 deadline are acceptable),
//! connection errors, the p50/p99 latency of admitted (200) requests, and
//! the server's resident memory after the first minute and at the end.
//!
//!     cargo bench --bench soak
//!     SOAK_SECONDS=60 cargo bench --bench soak
//!
//! Prints numbers; asserts nothing.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use serde_json::{Value, json};
use treemanip::api::types::TreeJson;
use treemanip::sim::{Push, SimConfig, simulate};
use treemanip::tree::{ScaParams, generate};

#[allow(dead_code)] // the bench uses part of the tests' helper
#[path = "../crates/server/tests/it/common/server.rs"]
mod server;

const CLIENTS: usize = 16;
const MAX_IN_FLIGHT: &str = "6";

fn rss_kib(pid: u32) -> u64 {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmRSS:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse().ok())
        })
        .unwrap_or(0)
}

/// One request of the mix, by index: forward (1 and 64 actions), policy,
/// plan (full 2 s budget), simulate, and a malformed one.
fn request(k: usize, bodies: &[(&'static str, Value)]) -> (&'static str, Vec<u8>) {
    let (path, body) = &bodies[k % bodies.len()];
    (path, serde_json::to_vec(body).unwrap())
}

fn main() {
    let seconds: f64 = std::env::var("SOAK_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(600.0);
    let server = server::Server::start(&[
        "--max-in-flight",
        MAX_IN_FLIGHT,
        "--models-dir",
        concat!(env!("CARGO_MANIFEST_DIR"), "/models"),
    ]);
    let pid = server.child.id();
    let mut bodies = Vec::new();
    for (n, seed) in [(12usize, 1u64), (20, 2), (30, 3)] {
        let tree = generate(n, seed, &ScaParams::default()).unwrap();
        let push = Push {
            node: n / 2,
            vector: nalgebra::Vector3::new(0.0, 0.08, 0.0),
        };
        let Ok(outcome) = simulate(&tree, &push, &SimConfig::default()) else {
            continue;
        };
        let t = TreeJson::from_tree(&tree);
        let target: Vec<[f64; 3]> = outcome
            .final_positions
            .iter()
            .map(|p| [p.x, p.y, p.z])
            .collect();
        bodies.push(("/v1/forward", json!({"tree": t, "contact_node": n / 2, "push": [0, 0.08, 0], "allow_out_of_domain": true})));
        bodies.push((
            "/v1/forward",
            json!({"tree": t, "contact_nodes": (0..64).map(|k| 1 + k % (n - 1)).collect::<Vec<_>>(),
                   "pushes": (0..64).map(|k| [0.05, 0.001 * k as f64, 0.0]).collect::<Vec<_>>(), "allow_out_of_domain": true}),
        ));
        bodies.push((
            "/v1/policy",
            json!({"tree": t, "target_positions": target, "allow_out_of_domain": true}),
        ));
        bodies.push(("/v1/plan", json!({"tree": t, "target_positions": target, "budget_ms": 2000, "allow_out_of_domain": true})));
        bodies.push((
            "/v1/simulate",
            json!({"tree": t, "contact_node": n / 2, "push": [0, 0.08, 0]}),
        ));
        bodies.push((
            "/v1/forward",
            json!({"tree": t, "contact_node": 0, "push": [0, 0.08, 0]}),
        ));
    }
    println!(
        "soak: {CLIENTS} clients, --max-in-flight {MAX_IN_FLIGHT}, {} request kinds, {seconds:.0} s",
        bodies.len()
    );
    let started = Instant::now();
    let deadline = started + Duration::from_secs_f64(seconds);
    let after_first_minute = std::sync::Mutex::new(None::<u64>);
    // The resident set every minute: a plateau and a leak look different.
    let timeline = std::sync::Mutex::new(Vec::<(f64, u64)>::new());
    let results: Vec<(String, u16, f64)> = std::thread::scope(|scope| {
        scope.spawn(|| {
            let minute = started + Duration::from_secs_f64(60f64.min(seconds / 2.0));
            while Instant::now() < minute {
                std::thread::sleep(Duration::from_millis(200));
            }
            *after_first_minute.lock().unwrap() = Some(rss_kib(pid));
        });
        scope.spawn(|| {
            let mut next = started;
            while Instant::now() < deadline {
                if Instant::now() >= next {
                    let t = started.elapsed().as_secs_f64();
                    timeline.lock().unwrap().push((t, rss_kib(pid)));
                    next += Duration::from_secs(60);
                }
                std::thread::sleep(Duration::from_millis(200));
            }
        });
        let handles: Vec<_> = (0..CLIENTS)
            .map(|c| {
                let (addr, bodies) = (&server.addr, &bodies);
                scope.spawn(move || {
                    let agent = server::client();
                    let mut out = Vec::new();
                    let mut k = c;
                    while Instant::now() < deadline {
                        let (path, body) = request(k, bodies);
                        k += CLIENTS;
                        let t = Instant::now();
                        let status = match agent
                            .post(format!("http://{addr}{path}"))
                            .header("content-type", "application/json")
                            .send(&body[..])
                        {
                            Ok(mut r) => {
                                let _ = r.body_mut().with_config().limit(64 << 20).read_to_vec();
                                r.status().as_u16()
                            }
                            Err(_) => 0,
                        };
                        out.push((path.to_string(), status, t.elapsed().as_secs_f64() * 1e3));
                    }
                    out
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap())
            .collect()
    });
    let elapsed = started.elapsed().as_secs_f64();
    let end_rss = rss_kib(pid);
    let first = after_first_minute.lock().unwrap().unwrap_or(0);
    let mut by_route: BTreeMap<String, BTreeMap<u16, usize>> = BTreeMap::new();
    let mut statuses: BTreeMap<u16, usize> = BTreeMap::new();
    let mut admitted: Vec<f64> = Vec::new();
    for (path, status, ms) in &results {
        *by_route
            .entry(path.clone())
            .or_default()
            .entry(*status)
            .or_default() += 1;
        *statuses.entry(*status).or_default() += 1;
        if *status == 200 {
            admitted.push(*ms);
        }
    }
    admitted.sort_by(f64::total_cmp);
    let pct = |p: f64| {
        admitted
            .get(((admitted.len() as f64 * p) as usize).min(admitted.len().saturating_sub(1)))
            .copied()
            .unwrap_or(f64::NAN)
    };
    println!(
        "{} requests in {elapsed:.0} s ({:.1}/s); by status (0 = connection error): {statuses:?}",
        results.len(),
        results.len() as f64 / elapsed
    );
    for (route, s) in &by_route {
        println!("  {route:<14} {s:?}");
    }
    let unexpected: usize = statuses
        .iter()
        .filter(|(s, _)| !matches!(s, 200 | 422 | 503 | 504))
        .map(|(_, c)| c)
        .sum();
    println!("unexpected answers (not 200/422/503/504): {unexpected}");
    println!(
        "admitted (200) latency: p50 {:.1} ms, p99 {:.1} ms",
        pct(0.5),
        pct(0.99)
    );
    println!(
        "server RSS: {:.1} MiB after the first minute, {:.1} MiB at the end ({:+.1} %)",
        first as f64 / 1024.0,
        end_rss as f64 / 1024.0,
        100.0 * (end_rss as f64 - first as f64) / (first as f64).max(1.0)
    );
    let timeline: Vec<String> = timeline
        .lock()
        .unwrap()
        .iter()
        .map(|(t, kib)| format!("{:.0} s {:.1}", t, *kib as f64 / 1024.0))
        .collect();
    println!("server RSS by minute (MiB): {}", timeline.join(", "));
}
