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

pub fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("treemanip-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Whether `python3` can import `module`; if not, the test says why it
/// skips, or fails when `TREEMANIP_REQUIRE_PYTHON` is set (CI installs
/// `requirements-dev.txt`).
pub fn python_has(module: &str) -> bool {
    let ok = Command::new("python3")
        .args(["-c", &format!("import {module}")])
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        assert!(
            std::env::var_os("TREEMANIP_REQUIRE_PYTHON").is_none(),
            "{module} is required (pip install -r requirements-dev.txt)"
        );
        eprintln!("skipped: the Python module {module} is not installed");
    }
    ok
}

/// Runs a Python `script` with `input` (JSON) on its standard input and
/// returns its standard output; panics with its standard error if it fails.
pub fn python_json(script: &str, input: &serde_json::Value) -> Vec<u8> {
    use std::io::Write;
    let mut child = Command::new("python3")
        .args(["-c", script])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("python3 runs");
    child
        .stdin
        .take()
        .unwrap()
        .write_all(input.to_string().as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}
