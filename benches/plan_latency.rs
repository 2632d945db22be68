//! `/v1/plan` latency against the running server on the default backend:
//! one request at a time (the latency one user sees), on test episodes of
//! N = 10, 15, …, 30 (target = the episode's final shape, the request
//! carries only tree and target), for `paper`, `model` and `physics`, with
//! the default base and with the evaluation's base region, default budgets
//! and limits; then `clear` objectives (a 4 cm fruit across a branch, as
//! `eval tasks` poses them) for `model` and `physics`.
//!
//!     cargo bench --bench plan_latency
//!     PLAN_EPISODES=4 cargo bench --bench plan_latency     (per size)
//!     PLAN_ROBOT=panda cargo bench --bench plan_latency    (a shipped arm,
//!                                  robots/panda.toml, as the default robot)
//!
//! Prints p50/p95/max client-side latency and the planned share; asserts
//! nothing. Run with nothing else busy on the machine.

use std::time::Instant;

use serde_json::{Value, json};
use treemanip::api::types::TreeJson;
use treemanip::dataset::Split;
use treemanip::dataset::collect::{CollectConfig, collect_size};
use treemanip::eval::plan::percentile;
use treemanip::eval::tasks::{TaskKind, make_task, task_rng};
use treemanip::geometry::shape::Shape;
use treemanip::planner::Objective;

#[allow(dead_code)] // the bench uses part of the tests' helper
#[path = "../crates/server/tests/it/common/server.rs"]
mod server;

fn main() {
    let per_size: usize = std::env::var("PLAN_EPISODES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(8);
    let robot = std::env::var("PLAN_ROBOT").ok();
    let mut args = vec![
        "--models-dir".to_owned(),
        concat!(env!("CARGO_MANIFEST_DIR"), "/models").to_owned(),
    ];
    if let Some(name) = &robot {
        args.push("--robot".to_owned());
        args.push(format!(
            "{name}={}/robots/{name}.toml",
            env!("CARGO_MANIFEST_DIR")
        ));
    }
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let server = server::Server::start(&args);
    let (_, ready) = server.get("/readyz");
    let cpu = treemanip::nn::train::checkpoint::cpu_model();
    println!(
        "/v1/plan latency, robot {}, backend {}, CPU {cpu}, {} cores; {per_size} test episodes per size, N = 10, 15, 20, 25, 30, one request at a time",
        robot.as_deref().unwrap_or("ur5 (built in)"),
        ready["backend"],
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    let config = CollectConfig {
        seed: 7,
        ..CollectConfig::default()
    };
    let mut requests: Vec<Value> = Vec::new();
    let mut clear_requests: Vec<Value> = Vec::new();
    for n in [10, 15, 20, 25, 30] {
        let (data, _) = collect_size(Split::Test, n, per_size, &config, &|| {}).unwrap();
        for (k, e) in data.episodes.iter().enumerate() {
            let tree = data.tree_of(e);
            let targets: Vec<[f64; 3]> =
                e.final_positions.iter().map(|p| [p.x, p.y, p.z]).collect();
            requests
                .push(json!({ "tree": TreeJson::from_tree(tree), "target_positions": targets }));
            let mut rng = task_rng(7, n * 1000 + k);
            if let Some(Objective::Clear { regions, .. }) =
                make_task(TaskKind::Clear, tree, e, &mut rng)
                && let Some(Shape::Sphere { centre, radius }) = regions.first()
            {
                clear_requests.push(json!({
                    "tree": TreeJson::from_tree(tree),
                    "objective": { "kind": "clear", "regions": [
                        { "kind": "sphere", "centre": [centre.x, centre.y, centre.z], "radius": radius }
                    ] },
                    "limits": { "max_stress": 40e6 },
                }));
            }
        }
    }
    let base = treemanip::robot::arm::PAPER_BASE.translation.vector;
    let region = json!({ "base_region": {
        "min": [base.x - 0.5, base.y - 0.5, 0.1], "max": [base.x + 0.5, base.y + 0.5, 1.0] } });
    println!(
        "{:<22} {:>8} {:>9} {:>9} {:>9} {:>9}",
        "setting", "planned", "p50 ms", "p95 ms", "max ms", "mean ms"
    );
    let runs = ["paper", "model", "physics"]
        .into_iter()
        .map(|s| (s, "shape", &requests))
        .chain(
            ["model", "physics"]
                .into_iter()
                .map(|s| (s, "clear", &clear_requests)),
        );
    for (strategy, objective, requests) in runs {
        for (stance, robot) in [("fixed", None), ("region", Some(&region))] {
            let mut ms = Vec::new();
            let mut planned = 0;
            for request in requests {
                let mut body = request.clone();
                body["strategy"] = json!(strategy);
                if let Some(robot) = robot {
                    body["robot"] = robot.clone();
                }
                let started = Instant::now();
                let (status, answer) = server.json("POST", "/v1/plan", &body);
                ms.push(started.elapsed().as_secs_f64() * 1e3);
                // A start the tree collides with (another arm at the fixed
                // base) answers 422 and counts as not planned.
                let start_collides =
                    status == 422 && answer["error"]["details"]["field"] == "robot.start";
                assert!(status == 200 || start_collides, "{answer}");
                planned += usize::from(answer["status"] == "planned");
            }
            ms.sort_by(f64::total_cmp);
            println!(
                "{:<22} {:>7.0}% {:>9.1} {:>9.1} {:>9.1} {:>9.1}",
                format!("{objective} {strategy}/{stance}"),
                100.0 * planned as f64 / requests.len() as f64,
                percentile(&ms, 0.5),
                percentile(&ms, 0.95),
                ms.last().copied().unwrap_or(f64::NAN),
                ms.iter().sum::<f64>() / ms.len() as f64
            );
        }
    }
}
