//! deploy/kubernetes/ validated offline against the Kubernetes schemas
//! (kubernetes-validate from PyPI) and against the Dockerfile and server it
//! deploys (`tests/python/validate_kubernetes.py`), and the dataset Job's
//! command line exists in the CLI.

use std::process::Command;

use crate::common::treemanip;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

#[test]
fn kubernetes_manifests_validate_offline() {
    let out = Command::new("python3")
        .arg(format!("{ROOT}/tests/python/validate_kubernetes.py"))
        .arg(format!("{ROOT}/deploy/kubernetes"))
        .arg(format!("{ROOT}/Dockerfile"))
        .arg("1.30.0")
        .output();
    match out {
        Ok(out) if String::from_utf8_lossy(&out.stderr).contains("ModuleNotFoundError") => {
            assert!(
                std::env::var_os("TREEMANIP_REQUIRE_PYTHON").is_none(),
                "kubernetes-validate is required here: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            println!(
                "skipped: kubernetes-validate not installed (pip install -r requirements-dev.txt)"
            );
        }
        Ok(out) => {
            let stdout = String::from_utf8_lossy(&out.stdout);
            println!("{stdout}");
            assert!(
                out.status.success(),
                "{stdout}\n{}",
                String::from_utf8_lossy(&out.stderr)
            );
            assert!(stdout.contains("all kubernetes checks passed"));
            assert!(stdout.contains("Deployment valid") && stdout.contains("Job valid"));
        }
        Err(e) => assert!(
            std::env::var_os("TREEMANIP_REQUIRE_PYTHON").is_none(),
            "python3: {e}"
        ),
    }
}

#[test]
fn the_dataset_job_command_exists() {
    let job =
        std::fs::read_to_string(format!("{ROOT}/deploy/kubernetes/dataset-job.yaml")).unwrap();
    assert!(job.contains(
        r#"args: ["dataset", "collect", "--out", "/data", "--seed", "7", "--shards", "4"]"#
    ));
    let help = treemanip(&["dataset", "collect", "--help"]);
    let help = String::from_utf8_lossy(&help.stdout);
    assert!(
        help.contains("--shards") && help.contains("JOB_COMPLETION_INDEX"),
        "{help}"
    );
    // Without the variable, --shards says what it needs.
    let run = Command::new(env!("CARGO_BIN_EXE_treemanip"))
        .args([
            "dataset",
            "collect",
            "--out",
            "/nonexistent/x",
            "--shards",
            "4",
        ])
        .env_remove("JOB_COMPLETION_INDEX")
        .output()
        .unwrap();
    assert!(!run.status.success());
    assert!(String::from_utf8_lossy(&run.stderr).contains("JOB_COMPLETION_INDEX"));
}

/// The shipped HAProxy configuration keeps what makes failover lose no
/// request (issue 33, docs/results/failover.md): whole bodies buffered so
/// every POST can be replayed, retries on the failures of a dying replica,
/// each on another replica. `haproxy -c` checks it where HAProxy is
/// installed (scripts/container/setup-podman installs it).
#[test]
fn the_haproxy_configuration_replays_requests_of_dead_replicas() {
    let cfg = std::fs::read_to_string(format!("{ROOT}/deploy/haproxy/haproxy.cfg")).unwrap();
    let lines: Vec<&str> = cfg
        .lines()
        .map(str::trim)
        .filter(|l| !l.starts_with('#'))
        .collect();
    for directive in [
        "option http-buffer-request",
        "option redispatch 1",
        "retry-on conn-failure empty-response junk-response 502 503",
        "option httpchk GET /readyz",
        "option httplog",
    ] {
        assert!(lines.contains(&directive), "missing `{directive}`");
    }
    assert!(
        !lines
            .iter()
            .any(|l| l.contains("504") || l.contains("response-timeout"))
    );
    let Ok(out) = Command::new("haproxy")
        .args(["-c", "-f", &format!("{ROOT}/deploy/haproxy/haproxy.cfg")])
        .env("LB_BIND", "127.0.0.1:18099")
        .env("REPLICA_1", "127.0.0.1:1")
        .env("REPLICA_2", "127.0.0.1:2")
        .env("REPLICA_3", "127.0.0.1:3")
        .output()
    else {
        println!("skipped haproxy -c: HAProxy is not installed");
        return;
    };
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
