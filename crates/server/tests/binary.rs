//! The `treemanip-server` binary on its own: what it says when it cannot
//! run. (The endpoints are tested in the workspace's integration tests,
//! `tests/it/server_*.rs`, which start this binary; this file is also what
//! makes cargo build it for them.)

use std::process::Command;

fn server() -> Command {
    Command::new(env!("CARGO_BIN_EXE_treemanip-server"))
}

#[test]
fn health_check_fails_when_nothing_listens() {
    // A port just released by the OS: nothing listens there.
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let out = server()
        .args(["--bind", &format!("127.0.0.1:{port}"), "--health-check"])
        .output()
        .unwrap();
    assert!(!out.status.success());
}

/// A broken ONNX Runtime library: with the `tract` feature the models run
/// on tract; without it (the default build) start-up stops with an error
/// that says how to get an engine. CI builds and runs this test both ways.
#[test]
fn a_broken_onnx_runtime_library_falls_back_to_tract_or_says_how_to_get_an_engine() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("treemanip-no-ort-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let library = dir.join("libonnxruntime.so");
    std::fs::write(&library, b"not a shared library").unwrap();
    let models = concat!(env!("CARGO_MANIFEST_DIR"), "/../../models");
    let mut child = server()
        .args([
            "--bind",
            "127.0.0.1:0",
            "--models-dir",
            models,
            "--ort-dylib",
        ])
        .arg(&library)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    if cfg!(feature = "tract") {
        use std::io::BufRead;
        let mut line = String::new();
        std::io::BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        let _ = child.kill();
        let _ = child.wait();
        assert!(line.starts_with("listening on http://"), "{line:?}");
    } else {
        let out = child.wait_with_output().unwrap();
        assert!(!out.status.success());
        let stderr = String::from_utf8_lossy(&out.stderr);
        for says in [
            "no ONNX engine",
            "could not be loaded",
            "--ort-dylib",
            "scripts/fetch-onnxruntime",
            "--features tract",
        ] {
            assert!(stderr.contains(says), "missing {says:?} in {stderr}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
