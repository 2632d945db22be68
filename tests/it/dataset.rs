//! Dataset collection: deterministic files, a lossless reader, numpy
//! readability, and the CLI around them.

use std::process::Command;

use crate::common::{temp_dir, treemanip};
use serde_json::Value;
use treemanip::dataset::collect::{CAUGHT_AT_BASE, CollectConfig, collect_size};
use treemanip::dataset::{Split, read_size_file, write_size_file};
use treemanip::sim::{Hold, Push, SimConfig, simulate};

fn small_config() -> CollectConfig {
    CollectConfig {
        trees_per_size: 5,
        seed: 11,
        ..CollectConfig::default()
    }
}

#[test]
fn collection_is_deterministic_and_reads_back_losslessly() {
    let dir = temp_dir("det");
    let config = small_config();
    let (a, stats) = collect_size(Split::Train, 12, 40, &config, &|| {}).unwrap();
    let (b, _) = collect_size(Split::Train, 12, 40, &config, &|| {}).unwrap();
    assert_eq!(a, b);
    assert_eq!(stats.kept, 40);
    assert_eq!(a.trees.len(), 5);
    // Episodes cycle through the trees.
    assert!(a.episodes.iter().enumerate().all(|(k, e)| e.tree == k % 5));
    let (pa, pb) = (dir.join("a.npz"), dir.join("b.npz"));
    write_size_file(&a, &pa).unwrap();
    write_size_file(&b, &pb).unwrap();
    assert!(
        std::fs::read(&pa).unwrap() == std::fs::read(&pb).unwrap(),
        "files differ"
    );
    let back = read_size_file(&pa, Split::Train).unwrap();
    assert_eq!(back.episodes, a.episodes);
    for ((_, x), (_, y)) in back.trees.iter().zip(&a.trees) {
        assert_eq!(x, y);
    }
    assert_eq!(
        back.trees.iter().map(|t| t.0.seed).collect::<Vec<_>>(),
        a.trees.iter().map(|t| t.0.seed).collect::<Vec<_>>()
    );
    // Each episode is what the simulator says for its tree and push.
    for episode in a.episodes.iter().take(10) {
        let tree = a.tree_of(episode);
        let again = simulate(tree, &episode.push, &SimConfig::default()).unwrap();
        assert_eq!(again.final_positions, episode.final_positions);
    }
    // A different seed or split gives different data.
    let (c, _) = collect_size(Split::Test, 12, 40, &config, &|| {}).unwrap();
    assert_ne!(c.episodes, a.episodes);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn pushes_follow_the_papers_distribution() {
    let (data, stats) = collect_size(Split::Test, 15, 200, &small_config(), &|| {}).unwrap();
    for episode in &data.episodes {
        let Push { node, vector } = episode.push;
        let tree = data.tree_of(episode);
        assert!((1..15).contains(&node));
        let length = vector.norm();
        assert!((0.05..=0.15).contains(&length), "{length}");
        // Within 45° of the plane perpendicular to the branch.
        let along = vector
            .normalize()
            .dot(&tree.branch_direction(node).unwrap());
        assert!(along.abs() <= 45f64.to_radians().sin() + 1e-12, "{along}");
    }
    // No-Action error is the mean of each episode's largest displacement.
    let mean: f64 = data
        .episodes
        .iter()
        .map(|e| {
            e.final_positions
                .iter()
                .zip(data.tree_of(e).positions())
                .map(|(a, b)| (a - b).norm())
                .fold(0.0, f64::max)
        })
        .sum::<f64>()
        / 200.0;
    assert!((stats.no_action_error - mean).abs() < 1e-12);
    assert!(stats.max_kkt_residual < 1e-8);
    // A push whose slot slid back to its branch's base fork moved that
    // fork, not its node: it is left out (as a lost branch was before
    // the simulator caught it there), so the data keep the pushes they had.
    assert!(data.episodes.iter().all(|e| e.hold != Hold::AtBase));
    assert!(
        stats.discarded.get(CAUGHT_AT_BASE).is_some_and(|&k| k > 0),
        "{:?}",
        stats.discarded
    );
}

#[test]
fn damaged_files_are_clear_errors() {
    let dir = temp_dir("bad");
    let path = dir.join("x.npz");
    std::fs::write(&path, b"not a zip").unwrap();
    let err = read_size_file(&path, Split::Test).unwrap_err().to_string();
    assert!(err.contains("not an npz archive"), "{err}");
    let err = read_size_file(&dir.join("missing.npz"), Split::Test)
        .unwrap_err()
        .to_string();
    assert!(err.contains("missing.npz"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn cli_collects_renders_and_numpy_reads_the_files() {
    let dir = temp_dir("cli");
    let out = dir.to_str().unwrap();
    let run = treemanip(&[
        "dataset",
        "collect",
        "--out",
        out,
        "--seed",
        "3",
        "--train-sizes",
        "11",
        "--train-episodes",
        "30",
        "--test-sizes",
        "10,12",
        "--test-episodes",
        "20",
        "--trees-per-size",
        "4",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        stdout.contains("train_N11") && stdout.contains("test_N12"),
        "{stdout}"
    );
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["files"].as_array().unwrap().len(), 3);
    assert_eq!(summary["files"][0]["kept"], 30);
    assert_eq!(summary["config"]["seed"], 3);
    for file in ["train_N11.npz", "test_N10.npz", "test_N12.npz"] {
        assert!(dir.join(file).exists(), "{file}");
    }

    let render = treemanip(&[
        "dataset",
        "render",
        &format!("{out}/test_N12.npz"),
        "--episodes",
        "0,3",
        "--out",
        out,
    ]);
    assert!(
        render.status.success(),
        "{}",
        String::from_utf8_lossy(&render.stderr)
    );
    let svg = std::fs::read_to_string(dir.join("episode_3.svg")).unwrap();
    assert!(svg.contains("<polygon"), "a push arrow is drawn");
    let missing = treemanip(&[
        "dataset",
        "render",
        &format!("{out}/test_N12.npz"),
        "--episodes",
        "20",
        "--out",
        out,
    ]);
    assert!(!missing.status.success());
    assert!(String::from_utf8_lossy(&missing.stderr).contains("no episode 20"));

    // numpy alone reads the schema (skipped, with a reason, without numpy).
    let script = format!(
        "import numpy as np, json; d = np.load('{out}/test_N12.npz'); \
         print(json.dumps({{k: [str(d[k].dtype), list(d[k].shape)] for k in d.files}}))"
    );
    match Command::new("python3").args(["-c", &script]).output() {
        Ok(o) if o.status.success() => {
            let shapes: Value = serde_json::from_slice(&o.stdout).unwrap();
            assert_eq!(
                shapes["final_positions"],
                serde_json::json!(["float64", [20, 12, 3]])
            );
            assert_eq!(
                shapes["initial_positions"],
                serde_json::json!(["float64", [20, 12, 3]])
            );
            assert_eq!(shapes["push"], serde_json::json!(["float64", [20, 3]]));
            assert_eq!(shapes["contact_node"], serde_json::json!(["int64", [20]]));
            assert_eq!(shapes["parents"], serde_json::json!(["int64", [4, 12]]));
            assert_eq!(shapes["stiffness"], serde_json::json!(["float64", [4, 12]]));
            assert_eq!(shapes["tree_seed"], serde_json::json!(["uint64", [4]]));
        }
        other => {
            assert!(
                std::env::var_os("TREEMANIP_REQUIRE_PYTHON").is_none(),
                "numpy check failed: {other:?}"
            );
            println!("skipped numpy check: {other:?}");
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn sim_push_prints_one_checkable_json_object() {
    let dir = temp_dir("push");
    let out = dir.to_str().unwrap();
    assert!(
        treemanip(&[
            "trees",
            "generate",
            "--nodes",
            "12",
            "--per-size",
            "1",
            "--out",
            out
        ])
        .status
        .success()
    );
    let tree = format!("{out}/N12/tree_000.urdf");
    let run = treemanip(&[
        "sim",
        "push",
        "--tree",
        &tree,
        "--node",
        "5",
        "--push",
        "0.03,-0.02,-0.01",
        "--json",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let v: Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(v["parents"][0], Value::Null);
    assert_eq!(v["radius"][0], Value::Null);
    assert_eq!(v["stiffness"][0], Value::Null);
    assert_eq!(v["positions"].as_array().unwrap().len(), 12);
    assert_eq!(v["final_positions"].as_array().unwrap().len(), 12);
    assert_eq!(v["contact_node"], 5);
    assert_eq!(v["push"], serde_json::json!([0.03, -0.02, -0.01]));
    assert!(v["solver"]["kkt_residual"].as_f64().unwrap() < 1e-8);
    assert!(v["solver"]["iterations"].as_u64().unwrap() >= 1);
    // The root does not move.
    assert_eq!(v["final_positions"][0], v["positions"][0]);

    let table = treemanip(&[
        "sim",
        "push",
        "--tree",
        &tree,
        "--node",
        "5",
        "--push",
        "0.03,-0.02,-0.01",
        "--contact",
        "pinned",
    ]);
    assert!(
        table.status.success(),
        "{}",
        String::from_utf8_lossy(&table.stderr)
    );
    assert!(String::from_utf8_lossy(&table.stdout).contains("iterations"));

    let root = treemanip(&[
        "sim", "push", "--tree", &tree, "--node", "0", "--push", "0.03,0,0",
    ]);
    assert!(!root.status.success());
    assert!(
        String::from_utf8_lossy(&root.stderr).contains("root"),
        "{}",
        String::from_utf8_lossy(&root.stderr)
    );
    let bad = treemanip(&[
        "sim", "push", "--tree", &tree, "--node", "5", "--push", "0.03,0",
    ]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("three comma-separated numbers"));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn plan_cli_reports_attempts_and_trajectory_as_json() {
    let dir = temp_dir("plan");
    let out = dir.to_str().unwrap();
    assert!(
        treemanip(&[
            "trees",
            "generate",
            "--nodes",
            "12",
            "--per-size",
            "1",
            "--out",
            out
        ])
        .status
        .success()
    );
    let tree = format!("{out}/N12/tree_000.urdf");
    // The target is what a paper-style push does to the tree.
    let loaded = treemanip::tree::urdf::read_file(std::path::Path::new(&tree)).unwrap();
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(2);
    let push = loop {
        let p = treemanip::sim::sampling::PushDistribution::default().sample(&loaded, &mut rng);
        if treemanip::sim::simulate(&loaded, &p, &Default::default()).is_ok() {
            break p;
        }
    };
    let node = push.node.to_string();
    let vector = format!("{},{},{}", push.vector.x, push.vector.y, push.vector.z);
    let run = treemanip(&[
        "plan", "--tree", &tree, "--node", &node, "--push", &vector, "--json",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let v: Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(v["joint_names"].as_array().unwrap().len(), 6);
    assert_eq!(v["strategy"], "model");
    assert!(!v["attempts"].as_array().unwrap().is_empty());
    assert!(v["no_action_error"].as_f64().unwrap() > 0.0);
    match v["status"].as_str().unwrap() {
        "planned" => {
            let trajectory = v["plan"]["trajectory"].as_array().unwrap();
            assert!(v["plan"]["push_start_index"].as_u64().unwrap() < trajectory.len() as u64);
            assert_eq!(trajectory[0]["q"].as_array().unwrap().len(), 6);
            assert!(
                v["predicted_error"].as_f64().unwrap() < v["no_action_error"].as_f64().unwrap()
            );
        }
        "no_plan" => assert!(v["plan"].is_null()),
        other => panic!("status {other}"),
    }
    // A push that cannot be simulated makes no target: a clear error.
    let far = treemanip(&[
        "plan",
        "--tree",
        &tree,
        "--node",
        "2",
        "--push",
        "0,-0.6,0.01",
    ]);
    assert!(!far.status.success());
    assert!(String::from_utf8_lossy(&far.stderr).contains("cannot be simulated"));
    let bad = treemanip(&[
        "plan",
        "--tree",
        &tree,
        "--node",
        "2",
        "--push",
        "0,-0.06,0.01",
        "--start",
        "0,0,0,0,0",
    ]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--start needs 6 values"));
    std::fs::remove_dir_all(&dir).ok();
}

/// The files of `dir`, name → bytes.
fn files_of(dir: &std::path::Path) -> std::collections::BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .map(|p| {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            (name, std::fs::read(&p).unwrap())
        })
        .collect()
}

#[test]
fn sharded_collection_merges_into_the_one_run_files_byte_for_byte() {
    let dir = temp_dir("shards");
    let settings = [
        "--seed",
        "5",
        "--train-sizes",
        "11,13",
        "--train-episodes",
        "24",
        "--test-sizes",
        "10..=13",
        "--test-episodes",
        "8",
        "--trees-per-size",
        "3",
    ];
    let collect = |out: &std::path::Path, extra: &[&str], index: Option<usize>| {
        let mut command = Command::new(env!("CARGO_BIN_EXE_treemanip"));
        command
            .args(["dataset", "collect", "--out", out.to_str().unwrap()])
            .args(settings)
            .args(extra);
        if let Some(i) = index {
            command.env("JOB_COMPLETION_INDEX", i.to_string());
        }
        let run = command.output().unwrap();
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
    };
    let one = dir.join("one");
    collect(&one, &[], None);
    // Three shards on three "machines" (directories), the index from
    // JOB_COMPLETION_INDEX as in an Indexed Job, then merged.
    let shard_dirs: Vec<_> = (0..3).map(|i| dir.join(format!("shard{i}"))).collect();
    for (i, d) in shard_dirs.iter().enumerate() {
        collect(d, &["--shards", "3"], Some(i));
    }
    let merged = dir.join("merged");
    let mut merge = vec!["dataset", "merge", "--out", merged.to_str().unwrap()];
    for d in &shard_dirs {
        merge.extend(["--from", d.to_str().unwrap()]);
    }
    // With a shard missing, merge refuses and says which.
    let partial = treemanip(&merge[..merge.len() - 2]);
    assert!(!partial.status.success());
    assert!(String::from_utf8_lossy(&partial.stderr).contains("shard 2/3 is missing"));
    let run = treemanip(&merge);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let (a, b) = (files_of(&one), files_of(&merged));
    assert_eq!(a.len(), 7, "6 data files and summary.json: {:?}", a.keys());
    assert_eq!(
        a.keys().collect::<Vec<_>>(),
        b.keys().collect::<Vec<_>>(),
        "same files"
    );
    for (name, bytes) in &a {
        assert!(bytes == &b[name], "{name} differs");
    }
    // A shard index out of range is refused.
    let bad = treemanip(&[
        "dataset",
        "collect",
        "--out",
        one.to_str().unwrap(),
        "--shard",
        "3/3",
    ]);
    assert!(!bad.status.success());
    std::fs::remove_dir_all(&dir).ok();
}

/// With a stiffness variation, the trees keep their geometry, their
/// stiffness leaves the radius formula (log factors of the stated spread),
/// the file stores the varied stiffness, and the episodes are the
/// simulator's answers on the varied trees.
#[test]
fn stiffness_variation_is_collected_and_stored() {
    use treemanip::tree::StiffnessVariation;
    let plain = small_config();
    let varied = CollectConfig {
        stiffness: StiffnessVariation::TRAINING,
        ..small_config()
    };
    let (a, _) = collect_size(Split::Train, 12, 20, &plain, &|| {}).unwrap();
    let (b, _) = collect_size(Split::Train, 12, 20, &varied, &|| {}).unwrap();
    let mut logs = Vec::new();
    for ((_, x), (_, y)) in a.trees.iter().zip(&b.trees) {
        assert_eq!(x.positions(), y.positions());
        for ((_, p), (_, q)) in x.branches_iter().zip(y.branches_iter()) {
            assert_eq!(p.radius, q.radius);
            logs.push((q.stiffness / p.stiffness).ln());
        }
    }
    let spread = logs.iter().map(|l| l * l).sum::<f64>() / logs.len() as f64;
    assert!(
        spread.sqrt() > 0.3,
        "log factors too narrow: rms {}",
        spread.sqrt()
    );
    // The stored stiffness is the varied one, and the episodes follow it.
    let dir = temp_dir("stiffness");
    let path = dir.join("train_N12.npz");
    write_size_file(&b, &path).unwrap();
    let back = read_size_file(&path, Split::Train).unwrap();
    assert_eq!(back.trees[0].1, b.trees[0].1);
    let e = &b.episodes[0];
    let again = simulate(&b.trees[e.tree].1, &e.push, &SimConfig::default()).unwrap();
    assert_eq!(again.final_positions, e.final_positions);
    // The paper's data is unchanged by the option's existence.
    assert!(
        !serde_json::to_string(&plain).unwrap().contains("stiffness"),
        "a default config records no variation"
    );
}
