//! Tree generation throughput: `cargo bench --bench generate`.
//!
//! Prints trees per second for single-threaded generation at several sizes,
//! and for the URDF write/read round trip. No thresholds: numbers only.

use std::hint::black_box;
use std::time::{Duration, Instant};

use treemanip::tree::{ScaParams, Wood, generate, tree_seed, urdf};

/// Runs `f` on consecutive indices until `budget` has passed; returns calls/s.
fn throughput(budget: Duration, mut f: impl FnMut(u64)) -> (f64, u64) {
    let start = Instant::now();
    let mut count = 0u64;
    while start.elapsed() < budget {
        f(count);
        count += 1;
    }
    (count as f64 / start.elapsed().as_secs_f64(), count)
}

fn main() {
    let params = ScaParams::default();
    let budget = Duration::from_secs(2);
    println!("tree generation (Space Colonization), one thread, {budget:?} per row");
    println!(
        "{:>4} {:>12} {:>10} {:>14}",
        "N", "trees/s", "trees", "µs/tree"
    );
    for n in [10usize, 15, 20, 30] {
        let (rate, count) = throughput(budget, |i| {
            black_box(generate(n, tree_seed(7, n, i), &params).unwrap());
        });
        println!("{n:>4} {rate:>12.0} {count:>10} {:>14.1}", 1e6 / rate);
    }
    let tree = generate(30, 1, &params).unwrap();
    let text = urdf::to_urdf_string(&tree, "bench", &Wood::default());
    let (write_rate, _) = throughput(budget, |_| {
        black_box(urdf::to_urdf_string(&tree, "bench", &Wood::default()));
    });
    let (read_rate, _) = throughput(budget, |_| {
        black_box(urdf::from_urdf_str(&text).unwrap());
    });
    println!(
        "\nURDF at N = 30 ({} bytes): write {write_rate:.0}/s, read {read_rate:.0}/s",
        text.len()
    );
}
