//! Helpers shared by the integration tests that drive the binaries.

#![allow(dead_code)] // each test binary uses a different subset

#[path = "../../../crates/server/tests/it/common/server.rs"]
pub mod server;
#[path = "../../../crates/core/tests/it/common.rs"]
mod support;
#[allow(unused_imports)]
pub use support::{
    assert_ros2_round_trip, episode, python_has, python_json, random_tree_and_pushes, robot_data,
    temp_dir,
};

use std::process::{Command, Output};

/// Runs the `treemanip` binary with `args`.
pub fn treemanip(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_treemanip"))
        .args(args)
        .output()
        .expect("binary runs")
}

/// A fresh, empty directory unique to this test process and `tag`.
/// A tiny dataset in `dir`: 160 episodes of sizes 6 and 8 on 10 trees
/// each, per split asked for (seconds to collect).
pub fn tiny_dataset(dir: &std::path::Path, splits: &[treemanip::dataset::Split]) {
    use treemanip::dataset::collect::{CollectConfig, collect_size};
    let config = CollectConfig {
        trees_per_size: 10,
        distinct_topologies: false,
        seed: 3,
        ..CollectConfig::default()
    };
    for &split in splits {
        for n in [6, 8] {
            let (data, _) = collect_size(split, n, 160, &config, &|| {}).unwrap();
            treemanip::dataset::write_size_file(&data, &dir.join(split.file_name(n))).unwrap();
        }
    }
}
