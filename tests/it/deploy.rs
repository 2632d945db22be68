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
