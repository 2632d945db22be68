//! Helpers the integration tests of every crate share: a scratch
//! directory, and Python oracles (the server's and the trainer's tests
//! include this file with `#[path]`, so there is one copy).

#![allow(dead_code)] // each test binary uses a different subset

use std::path::PathBuf;
use std::process::Command;

/// A fresh scratch directory for one test process, under cargo's own
/// scratch space for integration tests (`target/tmp`), not the system's
/// temporary directory, which runs of the suite would otherwise fill.
pub fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("treemanip-{tag}-{}", std::process::id()));
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

/// A random tree of `n` nodes and the target made by a random paper-style
/// push on it (the planner's tests' episode).
pub fn episode(n: usize, seed: u64) -> (treemanip_core::tree::Tree, Vec<nalgebra::Point3<f64>>) {
    use rand::SeedableRng;
    use treemanip_core::sim::sampling::PushDistribution;
    use treemanip_core::sim::{SimConfig, simulate};
    use treemanip_core::tree::{ScaParams, generate};
    let tree = generate(n, seed, &ScaParams::default()).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    loop {
        let push = PushDistribution::default().sample(&tree, &mut rng);
        if let Ok(o) = simulate(&tree, &push, &SimConfig::default()) {
            return (tree, o.final_positions);
        }
    }
}

/// A random tree of `n` nodes and `count` random paper-style pushes on it.
pub fn random_tree_and_pushes(
    seed: u64,
    n: usize,
    count: usize,
) -> (treemanip_core::tree::Tree, Vec<treemanip_core::sim::Push>) {
    use rand::SeedableRng;
    use treemanip_core::tree::{ScaParams, generate};
    let tree = generate(n, seed, &ScaParams::default()).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let pushes = (0..count)
        .map(|_| treemanip_core::sim::sampling::PushDistribution::default().sample(&tree, &mut rng))
        .collect();
    (tree, pushes)
}

/// Converts a `JointTrajectory` as JSON into `trajectory_msgs/msg/JointTrajectory`
/// with `rosbags`, serialises it to CDR and back, and checks every field
/// survives; returns the script's output (`CDR-bytes points`).
pub fn assert_ros2_round_trip(json: &serde_json::Value) -> Vec<u8> {
    let script = r#"
import json, sys, numpy as np
from rosbags.typesys import Stores, get_typestore
ts = get_typestore(Stores.ROS2_HUMBLE)
T = ts.types
data = json.load(sys.stdin)
msg = T['trajectory_msgs/msg/JointTrajectory'](
    header=T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](sec=0, nanosec=0), frame_id=''),
    joint_names=data['joint_names'],
    points=[T['trajectory_msgs/msg/JointTrajectoryPoint'](
        positions=np.array(p['positions'], dtype=np.float64),
        velocities=np.array(p['velocities'], dtype=np.float64),
        accelerations=np.array(p['accelerations'], dtype=np.float64),
        effort=np.array([], dtype=np.float64),
        time_from_start=T['builtin_interfaces/msg/Duration'](**p['time_from_start']))
        for p in data['points']])
cdr = ts.serialize_cdr(msg, msg.__msgtype__)
back = ts.deserialize_cdr(cdr, msg.__msgtype__)
assert back.joint_names == data['joint_names']
assert len(back.points) == len(data['points'])
for p, q in zip(back.points, data['points']):
    for field in ('positions', 'velocities', 'accelerations'):
        assert list(getattr(p, field)) == q[field], field
    assert (p.time_from_start.sec, p.time_from_start.nanosec) == (q['time_from_start']['sec'], q['time_from_start']['nanosec'])
print(len(cdr), len(back.points))
"#;
    python_json(script, json)
}

/// example-robot-data's robots folder (PyPI, `requirements-dev.txt`), or
/// `None`: the test then says why it skipped, unless Python is required.
pub fn robot_data() -> Option<PathBuf> {
    let out = std::process::Command::new("python3")
        .args([
            "-c",
            "import sysconfig, os; print(os.path.join(sysconfig.get_paths()['purelib'], 'cmeel.prefix', 'share', 'example-robot-data', 'robots'))",
        ])
        .output()
        .ok();
    let path = out
        .as_ref()
        .filter(|o| o.status.success())
        .map(|o| PathBuf::from(String::from_utf8_lossy(&o.stdout).trim()));
    if let Some(p) = path.filter(|p| p.is_dir()) {
        return Some(p);
    }
    assert!(
        std::env::var_os("TREEMANIP_REQUIRE_PYTHON").is_none(),
        "example-robot-data is required (pip install -r requirements-dev.txt)"
    );
    eprintln!("skipped: example-robot-data is not installed");
    None
}
