//! Our URDF loads in yourdfpy, an independent Python parser, which sees the
//! same node positions (through its own forward kinematics), joint damping,
//! spring stiffness and branch cylinders. Skipped, with the reason printed,
//! when python3 or yourdfpy is missing (`.ci/run` installs it).

use std::process::Command;

use serde_json::Value;
use treemanip_core::tree::{ScaParams, Wood, generate, urdf};

fn python_with_yourdfpy() -> Result<(), String> {
    match Command::new("python3")
        .args(["-c", "import yourdfpy"])
        .output()
    {
        Err(e) => Err(format!("python3 not runnable: {e}")),
        Ok(out) if !out.status.success() => Err(format!(
            "yourdfpy not importable (pip install -r requirements-dev.txt): {}",
            String::from_utf8_lossy(&out.stderr)
                .lines()
                .last()
                .unwrap_or("")
        )),
        Ok(_) => Ok(()),
    }
}

/// yourdfpy's own number handling may move the last bit.
fn assert_close(value: &Value, expected: f64, what: &str) {
    let got = value
        .as_f64()
        .unwrap_or_else(|| panic!("{what}: {value} is not a number"));
    assert!(
        (got - expected).abs() <= 1e-12 * expected.abs(),
        "{what}: {got} vs {expected}"
    );
}

#[test]
fn yourdfpy_reads_what_we_wrote() {
    if let Err(reason) = python_with_yourdfpy() {
        if std::env::var_os("TREEMANIP_REQUIRE_PYTHON").is_some() {
            panic!("TREEMANIP_REQUIRE_PYTHON is set but {reason}");
        }
        println!("skipped: {reason}");
        return;
    }
    let dir = crate::common::temp_dir("yourdfpy");
    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../tests/python/load_tree_urdf.py"
    );
    let params = ScaParams::default();
    for (n, seed) in [(10usize, 1u64), (21, 2), (30, 3)] {
        let tree = generate(n, seed, &params).unwrap();
        let path = dir.join(format!("tree_{n}.urdf"));
        urdf::write_file(&tree, "py", &Wood::default(), &path).unwrap();
        let out = Command::new("python3")
            .arg(script)
            .arg(&path)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let seen: Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(seen["base_link"], "world");
        assert_eq!(seen["actuated_joints"], 3 * (n - 1));
        let positions = seen["positions"].as_array().unwrap();
        assert_eq!(positions.len(), n);
        for (j, p) in positions.iter().enumerate() {
            let ours = tree.position(j);
            for k in 0..3 {
                let theirs = p[k].as_f64().unwrap();
                assert!(
                    (theirs - ours[k]).abs() < 1e-9,
                    "N={n} node {j} axis {k}: {theirs} vs {}",
                    ours[k]
                );
            }
        }
        for (j, b) in tree.branches_iter() {
            for axis in ["rx", "ry", "rz"] {
                let joint = format!("branch_{j}_{axis}");
                assert_close(&seen["damping"][&joint], b.damping, &joint);
                assert_close(&seen["stiffness"][&joint], b.stiffness, &joint);
            }
            let cyl = &seen["cylinders"][format!("branch_{j}")];
            assert_close(&cyl[0], b.radius, "radius");
            assert_close(&cyl[1], b.length, "length");
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}
