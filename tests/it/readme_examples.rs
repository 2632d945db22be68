//! The README's HTTP examples work as written: its curl block runs under
//! `bash -euo pipefail` against a fresh server on the committed models
//! (only the address is substituted), and so does its Python example.

use std::process::Command;

use crate::common::server::Server;

const README: &str = include_str!("../../README.md");

/// The fenced block of `lang` that follows `marker`.
fn block(marker: &str, lang: &str) -> String {
    let after = README
        .split_once(marker)
        .unwrap_or_else(|| panic!("README lacks {marker}"))
        .1;
    let start = after
        .find(&format!("```{lang}\n"))
        .unwrap_or_else(|| panic!("no {lang} block after {marker}"))
        + lang.len()
        + 4;
    let end = after[start..].find("```").unwrap();
    after[start..start + end].to_owned()
}

fn server() -> Server {
    Server::start(&[
        "--models-dir",
        concat!(env!("CARGO_MANIFEST_DIR"), "/models"),
    ])
}

#[test]
fn the_curl_examples_run() {
    let server = server();
    let script = block("<!-- curl examples -->", "sh").replace("localhost:8080", &server.addr);
    for endpoint in [
        "/healthz",
        "/readyz",
        "/v1/models",
        "/v1/forward",
        "/v1/policy",
        "/v1/plan",
        "/v1/simulate",
        "/metrics",
    ] {
        assert!(script.contains(endpoint), "no curl example for {endpoint}");
    }
    let out = Command::new("bash")
        .args(["-euo", "pipefail", "-c", &script])
        .output()
        .expect("bash runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "README curl examples failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for expected in [
        "\"status\":\"ok\"",
        "\"displacements\"",
        "\"candidates\"",
        "\"attempts\"",
        "\"objective\":\"clear\"",
    ] {
        assert!(
            stdout.contains(expected),
            "{expected} missing from:\n{stdout}"
        );
    }
}

#[test]
fn the_viewer_curl_examples_run() {
    let server = server();
    let script =
        block("<!-- curl viewer examples -->", "sh").replace("localhost:8080", &server.addr);
    let out = Command::new("bash")
        .args(["-euo", "pipefail", "-c", &script])
        .output()
        .expect("bash runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}");
    assert!(
        stdout.contains("\"seed\":3") && stdout.contains("\"poses\""),
        "{stdout}"
    );
}

#[test]
fn the_python_example_runs() {
    let server = server();
    let script = block("<!-- python example -->", "python").replace("localhost:8080", &server.addr);
    let out = Command::new("python3").args(["-c", &script]).output();
    match out {
        Ok(out) if String::from_utf8_lossy(&out.stderr).contains("No module named 'requests'") => {
            assert!(
                std::env::var_os("TREEMANIP_REQUIRE_PYTHON").is_none(),
                "requests is required here"
            );
            println!("skipped: requests not installed (pip install -r requirements-dev.txt)");
        }
        Ok(out) => assert!(
            out.status.success(),
            "README Python example failed:\n{}\n{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        ),
        Err(e) => {
            assert!(
                std::env::var_os("TREEMANIP_REQUIRE_PYTHON").is_none(),
                "{e}"
            );
        }
    }
}

/// Every `cargo run --release -- …` command in the README and docs names a
/// command of the `treemanip` binary (its `--help` answers), and the
/// workspace makes `cargo run` pick that binary: the root package is a
/// default member with `default-run = "treemanip"`, and the server's binary
/// is in a default member too, so `cargo run --bin treemanip-server` finds
/// it without `-p`.
#[test]
fn the_cargo_run_commands_name_existing_commands() {
    let manifest = include_str!("../../Cargo.toml");
    assert!(manifest.contains("default-run = \"treemanip\""));
    let members = manifest
        .lines()
        .find(|l| l.starts_with("default-members"))
        .expect("default-members");
    assert!(
        members.contains("\".\"") && members.contains("\"crates/server\""),
        "{members}"
    );
    let docs = [
        README,
        include_str!("../../docs/dataset.md"),
        include_str!("../../docs/robot.md"),
    ];
    let mut checked = 0;
    for line in docs.iter().flat_map(|d| d.lines()) {
        let Some((_, rest)) = line.split_once("cargo run --release -- ") else {
            continue;
        };
        // The subcommand path: the words before the first flag or argument.
        let words: Vec<&str> = rest
            .split_whitespace()
            .take_while(|w| !w.starts_with('-') && !w.contains('/') && !w.contains('.'))
            .take(2)
            .collect();
        let mut args = words.clone();
        args.push("--help");
        let out = crate::common::treemanip(&args);
        assert!(
            out.status.success(),
            "`treemanip {}` from {line:?}: {}",
            words.join(" "),
            String::from_utf8_lossy(&out.stderr)
        );
        checked += 1;
    }
    assert!(checked >= 15, "{checked} commands");
    // The server's binary, as `cargo run --release --bin treemanip-server` runs it.
    assert!(README.contains("cargo run --release --bin treemanip-server"));
    let server = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/crates/server/Cargo.toml"
    ))
    .unwrap();
    assert!(server.contains("name = \"treemanip-server\""));
}
