//! `/v1/identify` and `/v1/identify/probes` latency against the running
//! server: test trees of N = 30 (and 15 for comparison) with hidden
//! stiffness (ε ~ N(0, 0.3)), 5 chosen probes observed with 3 mm noise,
//! one request at a time.
//!
//!     cargo bench --bench identify_latency
//!     IDENTIFY_TREES=8 cargo bench --bench identify_latency
//!
//! Prints p50/p95/max client-side latency; asserts nothing. Run with
//! nothing else busy on the machine.

use std::time::Instant;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde_json::{Value, json};
use treemanip::api::types::TreeJson;
use treemanip::dataset::Split;
use treemanip::dataset::collect::{CollectConfig, collect_size};
use treemanip::eval::plan::percentile;
use treemanip::identify::probes::{ProbeRequest, choose_probes};
use treemanip::identify::{IdentifyConfig, Noise, Posterior, observe};
use treemanip::sim::ContactModel;
use treemanip::tree::StiffnessVariation;

#[allow(dead_code)] // the bench uses part of the tests' helper
#[path = "../crates/server/tests/it/common/server.rs"]
mod server;

fn main() {
    let trees: usize = std::env::var("IDENTIFY_TREES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20);
    let empty = std::env::temp_dir().join("treemanip-identify-bench-models");
    std::fs::create_dir_all(&empty).unwrap();
    let server = server::Server::start(&["--models-dir", empty.to_str().unwrap()]);
    let cpu = treemanip::nn::train::checkpoint::cpu_model();
    println!(
        "/v1/identify latency, CPU {cpu}, {} cores; {trees} test trees per size, 5 chosen probes, 3 mm noise, one request at a time",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    println!(
        "{:<24} {:>9} {:>9} {:>9} {:>9}",
        "request", "p50 ms", "p95 ms", "max ms", "mean ms"
    );
    let config = CollectConfig {
        seed: 7,
        trees_per_size: trees,
        ..CollectConfig::default()
    };
    for n in [15, 30] {
        let (data, _) = collect_size(Split::Test, n, trees, &config, &|| {}).unwrap();
        let mut identify = Vec::new();
        let mut propose = Vec::new();
        for (k, (_, nominal)) in data.trees.iter().enumerate().take(trees) {
            let mut rng = ChaCha8Rng::seed_from_u64(k as u64);
            let variation = StiffnessVariation {
                branch_log_sigma: 0.3,
                global_factor: 1.0,
            };
            let truth = variation.apply(nominal, &mut rng);
            let prior = Posterior::prior(nominal, &IdentifyConfig::default());
            let chosen = choose_probes(
                nominal,
                &prior,
                &ProbeRequest::default(),
                &IdentifyConfig::default(),
                &|_| true,
            );
            let probes: Vec<Value> = chosen
                .iter()
                .filter_map(|c| {
                    let p = observe(&truth, c.push, ContactModel::Slot, &Noise::default(), false, &mut rng)?;
                    Some(json!({
                        "contact_node": p.push.node,
                        "push": [p.push.vector.x, p.push.vector.y, p.push.vector.z],
                        "observed_positions": p.observed.iter().map(|o| o.map(|o| [o.x, o.y, o.z])).collect::<Vec<_>>(),
                    }))
                })
                .collect();
            let mut tree = serde_json::to_value(TreeJson::from_tree(nominal)).unwrap();
            tree.as_object_mut().unwrap().remove("stiffness");
            propose.push(json!({ "tree": tree.clone(), "count": 5 }));
            identify.push(json!({ "tree": tree, "probes": probes }));
        }
        for (route, bodies) in [
            ("/v1/identify", &identify),
            ("/v1/identify/probes", &propose),
        ] {
            let mut ms = Vec::new();
            for body in bodies {
                let started = Instant::now();
                let (status, answer) = server.json("POST", route, body);
                ms.push(started.elapsed().as_secs_f64() * 1e3);
                assert_eq!(status, 200, "{answer}");
            }
            ms.sort_by(f64::total_cmp);
            println!(
                "{:<24} {:>9.1} {:>9.1} {:>9.1} {:>9.1}",
                format!("{route} N={n}"),
                percentile(&ms, 0.5),
                percentile(&ms, 0.95),
                ms.last().copied().unwrap_or(f64::NAN),
                ms.iter().sum::<f64>() / ms.len() as f64
            );
        }
    }
}
