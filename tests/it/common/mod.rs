//! Helpers shared by the integration tests that drive the binaries.

#![allow(dead_code)] // each test binary uses a different subset

pub mod server;

use std::path::PathBuf;
use std::process::{Command, Output};

/// Runs the `treemanip` binary with `args`.
pub fn treemanip(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_treemanip"))
        .args(args)
        .output()
        .expect("binary runs")
}

/// A fresh, empty directory unique to this test process and `tag`.
pub fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("treemanip-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}
