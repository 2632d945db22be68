//! Push-simulation throughput: `cargo bench --bench simulate`.
//!
//! One thread, paper-distributed pushes on generated trees: attempts/s,
//! kept/s, discard reasons and solver iterations, per tree size. Numbers
//! only, no thresholds. The whole-dataset rate on all cores is printed by
//! `treemanip dataset collect`.

use std::collections::BTreeMap;
use std::time::Instant;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use treemanip::sim::sampling::PushDistribution;
use treemanip::sim::{ContactModel, SimConfig, simulate};
use treemanip::tree::{ScaParams, generate};

fn main() {
    let trees_per_size = 50;
    let pushes_per_tree = 40;
    println!("one thread, {trees_per_size} trees x {pushes_per_tree} pushes per row");
    println!(
        "{:<7} {:>4} {:>11} {:>9} {:>8} {:>9} {:>6}  discards",
        "contact", "N", "attempts/s", "kept/s", "kept %", "µs/push", "iters"
    );
    for contact in [ContactModel::Slot, ContactModel::Pinned] {
        let config = SimConfig {
            contact,
            ..SimConfig::default()
        };
        for n in [10usize, 15, 20, 30] {
            let trees: Vec<_> = (0..trees_per_size)
                .map(|s| generate(n, s, &ScaParams::default()).unwrap())
                .collect();
            let mut rng = ChaCha8Rng::seed_from_u64(n as u64);
            let pushes: Vec<_> = trees
                .iter()
                .flat_map(|t| {
                    (0..pushes_per_tree)
                        .map(|_| PushDistribution::default().sample(t, &mut rng))
                        .collect::<Vec<_>>()
                })
                .collect();
            let mut kept = 0usize;
            let mut iterations = 0usize;
            let mut discards = BTreeMap::<&str, usize>::new();
            let start = Instant::now();
            for (k, push) in pushes.iter().enumerate() {
                match simulate(&trees[k / pushes_per_tree], push, &config) {
                    Ok(o) => {
                        kept += 1;
                        iterations += o.report.iterations;
                    }
                    Err(e) => *discards.entry(e.kind()).or_default() += 1,
                }
            }
            let seconds = start.elapsed().as_secs_f64();
            let attempts = pushes.len() as f64;
            println!(
                "{:<7} {n:>4} {:>11.0} {:>9.0} {:>8.1} {:>9.1} {:>6.2}  {discards:?}",
                format!("{contact:?}").to_lowercase(),
                attempts / seconds,
                kept as f64 / seconds,
                100.0 * kept as f64 / attempts,
                1e6 * seconds / attempts,
                iterations as f64 / kept.max(1) as f64
            );
        }
    }
}
