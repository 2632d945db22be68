//! Property-based API testing: schemathesis (PyPI) generates requests from
//! openapi.yaml, valid and invalid, sends them to a real server on the
//! committed models, and runs every check it has (no server errors,
//! status codes, content types and bodies as the spec says, schema-valid
//! data accepted and invalid data rejected). The rules JSON Schema cannot
//! state are declared in `schemathesis.toml`. A bounded run here (about two
//! minutes, a few thousand cases, fixed seed); a longer one by hand:
//!
//!     st run openapi.yaml --url http://127.0.0.1:8080 --checks all --max-time 600

use std::process::Command;

use crate::common::server::Server;

const MODELS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../models");

#[test]
fn schemathesis_finds_no_failures() {
    let available = Command::new("st").arg("--version").output();
    if !available.as_ref().is_ok_and(|o| o.status.success()) {
        assert!(
            std::env::var_os("TREEMANIP_REQUIRE_PYTHON").is_none(),
            "schemathesis (st) is required here: {available:?}"
        );
        println!("skipped: schemathesis not installed (pip install -r requirements-dev.txt)");
        return;
    }
    // Plans get a small budget cap so that generated plan requests do not
    // dominate the run.
    let server = Server::start(&["--models-dir", MODELS, "--max-plan-budget-ms", "200"]);
    let out = Command::new("st")
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
        .args(["--no-color", "run", "openapi.yaml", "--checks", "all"])
        .args(["--url", &format!("http://{}", server.addr)])
        .args(["--max-time", "90", "--workers", "1", "--seed", "20261123"])
        .args(["--generation-database", "none", "--request-timeout", "30"])
        .output()
        .expect("st runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let summary: String = stdout
        .lines()
        .skip_while(|l| !l.contains("SUMMARY"))
        .collect::<Vec<_>>()
        .join("\n");
    println!("{summary}");
    assert!(
        out.status.success(),
        "schemathesis found failures:\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("generated"), "{stdout}");
}
