//! `treemanip trees …` end to end, through the real binary.

use std::path::Path;

use crate::common::{temp_dir, treemanip};
use serde_json::Value;
use treemanip::tree::urdf;

fn generate(out: &Path, extra: &[&str]) -> Value {
    let mut args = vec!["trees", "generate", "--out", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    let result = treemanip(&args);
    assert!(
        result.status.success(),
        "{}",
        String::from_utf8_lossy(&result.stderr)
    );
    serde_json::from_str(&std::fs::read_to_string(out.join("index.json")).unwrap()).unwrap()
}

#[test]
fn generate_writes_urdf_files_and_an_index() {
    let out = temp_dir("gen");
    let index = generate(
        &out,
        &["--nodes", "10..=12", "--per-size", "4", "--seed", "3"],
    );
    assert_eq!(index["base_seed"], 3);
    let trees = index["trees"].as_array().unwrap();
    assert_eq!(trees.len(), 12);
    let mut keys_per_size = std::collections::HashMap::<u64, Vec<String>>::new();
    for entry in trees {
        let n = entry["n"].as_u64().unwrap();
        let tree = urdf::read_file(&out.join(entry["file"].as_str().unwrap())).unwrap();
        assert_eq!(tree.len() as u64, n);
        assert!((tree.height() - entry["height"].as_f64().unwrap()).abs() < 1e-12);
        // The recorded seed regenerates the very same file.
        let again = treemanip::tree::generate(
            n as usize,
            entry["seed"].as_u64().unwrap(),
            &treemanip::tree::ScaParams::default(),
        )
        .unwrap();
        let name = format!("tree_N{n}_{:03}", entry["index"].as_u64().unwrap());
        let written = std::fs::read_to_string(out.join(entry["file"].as_str().unwrap())).unwrap();
        assert!(
            urdf::to_urdf_string(&again, &name, &Default::default()) == written,
            "seed of {} does not regenerate it",
            entry["file"]
        );
        keys_per_size
            .entry(n)
            .or_default()
            .push(tree.topology_key());
    }
    for (n, keys) in keys_per_size {
        let unique: std::collections::HashSet<_> = keys.iter().collect();
        assert_eq!(unique.len(), keys.len(), "N={n}: topologies repeat");
    }
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn generate_is_deterministic() {
    let (a, b) = (temp_dir("det-a"), temp_dir("det-b"));
    let args = ["--nodes", "13,20", "--per-size", "3", "--seed", "11"];
    let (ia, ib) = (generate(&a, &args), generate(&b, &args));
    assert_eq!(ia, ib);
    for entry in ia["trees"].as_array().unwrap() {
        let file = entry["file"].as_str().unwrap();
        assert_eq!(
            std::fs::read(a.join(file)).unwrap(),
            std::fs::read(b.join(file)).unwrap()
        );
    }
    std::fs::remove_dir_all(&a).ok();
    std::fs::remove_dir_all(&b).ok();
}

#[test]
fn show_and_render_a_tree() {
    let out = temp_dir("show");
    let index = generate(&out, &["--nodes", "15", "--per-size", "1"]);
    let file = out.join(index["trees"][0]["file"].as_str().unwrap());
    let tree = urdf::read_file(&file).unwrap();

    let shown = treemanip(&["trees", "show", file.to_str().unwrap()]);
    assert!(shown.status.success());
    let text = String::from_utf8(shown.stdout).unwrap();
    assert!(text.contains("nodes 15"), "{text}");
    assert!(text.contains("(fixed root)"));
    // Path, two summary lines, a blank line, the header, one row per node.
    assert_eq!(text.lines().count(), 5 + 15);

    let json = treemanip(&["trees", "show", "--json", file.to_str().unwrap()]);
    let value: Value = serde_json::from_slice(&json.stdout).unwrap();
    assert_eq!(value["parents"][0], Value::Null);
    assert_eq!(value["radius"][0], Value::Null);
    assert_eq!(value["positions"].as_array().unwrap().len(), 15);
    for j in 1..15 {
        let b = tree.branch(j).unwrap();
        assert_eq!(value["stiffness"][j].as_f64(), Some(b.stiffness));
        assert_eq!(
            value["parents"][j].as_u64(),
            tree.parent(j).map(|p| p as u64)
        );
    }

    let svg = out.join("tree.svg");
    let rendered = treemanip(&[
        "trees",
        "render",
        file.to_str().unwrap(),
        "--out",
        svg.to_str().unwrap(),
    ]);
    assert!(
        rendered.status.success(),
        "{}",
        String::from_utf8_lossy(&rendered.stderr)
    );
    let doc = std::fs::read_to_string(&svg).unwrap();
    assert!(doc.starts_with("<svg"));
    // Two views, each with one line per branch plus the ground and scale bar.
    assert_eq!(doc.matches("<line").count(), 2 * (14 + 2));
    assert!(doc.contains("front (x–z)") && doc.contains("side (y–z)"));
    assert!(doc.contains("N = 15"));
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn errors_are_clear_and_fail_the_command() {
    let bad = treemanip(&[
        "trees",
        "generate",
        "--out",
        "/tmp/unused",
        "--nodes",
        "2..=5",
    ]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("outside the generator's range"));

    let missing = treemanip(&["trees", "show", "/definitely/not/here.urdf"]);
    assert!(!missing.status.success());
    assert!(
        String::from_utf8_lossy(&missing.stderr).contains("cannot read /definitely/not/here.urdf")
    );

    let out = temp_dir("bad-urdf");
    std::fs::create_dir_all(&out).unwrap();
    let file = out.join("robot.urdf");
    std::fs::write(&file, "<robot name=\"arm\"><link name=\"base\"/></robot>").unwrap();
    let not_tree = treemanip(&[
        "trees",
        "render",
        file.to_str().unwrap(),
        "--out",
        "/tmp/x.svg",
    ]);
    assert!(!not_tree.status.success());
    assert!(String::from_utf8_lossy(&not_tree.stderr).contains("not a treemanip tree URDF"));
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn help_is_available_everywhere() {
    for args in [
        &["--help"][..],
        &["trees", "--help"],
        &["trees", "generate", "--help"],
        &["trees", "show", "--help"],
        &["trees", "render", "--help"],
    ] {
        let out = treemanip(args);
        assert!(out.status.success(), "{args:?}");
        assert!(
            String::from_utf8_lossy(&out.stdout).contains("Usage"),
            "{args:?}"
        );
    }
}

/// `trees scan` prints where its scanner stood in the form `trees
/// from-points` takes (negative coordinates included), and told so,
/// `from-points` bridges what leaves and branches in front hid: the tree
/// comes back with more of the true branches than without.
#[test]
fn a_scan_tells_from_points_where_it_was_seen_from() {
    let out = temp_dir("scan_viewpoints");
    let tree = treemanip::tree::generate(20, 2, &treemanip::tree::ScaParams::default()).unwrap();
    let file = out.join("tree.urdf");
    urdf::write_file(&tree, "tree", &treemanip::tree::Wood::default(), &file).unwrap();
    let cloud = out.join("cloud.ply");
    let scanned = treemanip(&[
        "trees",
        "scan",
        file.to_str().unwrap(),
        "--views",
        "1",
        "--noise",
        "0.003",
        "--leaves",
        "8",
        "--seed",
        "2",
        "--out",
        cloud.to_str().unwrap(),
    ]);
    assert!(
        scanned.status.success(),
        "{}",
        String::from_utf8_lossy(&scanned.stderr)
    );
    let printed = String::from_utf8_lossy(&scanned.stdout).to_string();
    let viewpoints: Vec<&str> = printed
        .lines()
        .find_map(|l| l.strip_prefix("viewpoints: "))
        .unwrap_or_else(|| panic!("{printed}"))
        .split(' ')
        .collect();
    assert_eq!(viewpoints.len(), 1, "{printed}");
    assert!(viewpoints[0].starts_with("--viewpoint="), "{printed}");
    let recall = |extra: &[&str]| {
        let json = out.join("found.json");
        let mut args = vec![
            "trees",
            "from-points",
            cloud.to_str().unwrap(),
            "--out",
            json.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let run = treemanip(&args);
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let answer: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let t = &answer["tree"];
        let positions: Vec<[f64; 3]> = serde_json::from_value(t["positions"].clone()).unwrap();
        let radius: Vec<Option<f64>> = serde_json::from_value(t["radius"].clone()).unwrap();
        let found = treemanip::scan::Skeleton {
            positions: positions
                .iter()
                .map(|p| nalgebra::Point3::from(*p))
                .collect(),
            parents: serde_json::from_value(t["parents"].clone()).unwrap(),
            radius: radius.iter().map(|r| r.unwrap_or(0.005)).collect(),
        };
        let score = treemanip::scan::score(&treemanip::scan::Skeleton::of_tree(&tree), &found);
        (
            score.recall[1],
            String::from_utf8_lossy(&run.stderr).to_string(),
        )
    };
    let (blind, _) = recall(&[]);
    let (told, said) = recall(&viewpoints);
    assert!(told > blind, "{told} {blind}");
    assert!(said.contains("behind what the sensor saw"), "{said}");
    // A viewpoint with a negative coordinate in the next argument's form.
    let (_, _) = recall(&["--viewpoint", "-1.5,0,0.8"]);
    // The same cloud as a PCD file whose header records the viewpoint: read
    // from it on request, the same tree.
    let at = viewpoints[0]
        .strip_prefix("--viewpoint=")
        .unwrap()
        .replace(',', " ");
    let points = treemanip::scan::io::read_path(&cloud, 10_000_000)
        .unwrap()
        .points;
    let mut pcd = format!(
        "VERSION 0.7\nFIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT {at} 1 0 0 0\nPOINTS {n}\nDATA ascii\n",
        n = points.len()
    );
    for p in &points {
        pcd.push_str(&format!("{} {} {}\n", p.x, p.y, p.z));
    }
    let recorded = out.join("cloud.pcd");
    std::fs::write(&recorded, pcd).unwrap();
    let read_from = |file: &std::path::Path, how: &str| {
        let run = treemanip(&["trees", "from-points", file.to_str().unwrap(), how]);
        let said = String::from_utf8_lossy(&run.stderr).to_string();
        let tree = run
            .status
            .success()
            .then(|| serde_json::from_slice::<Value>(&run.stdout).unwrap()["tree"].clone());
        (tree, said)
    };
    let (recorded_tree, said) = read_from(&recorded, "--viewpoint-from-file");
    assert!(said.contains("behind what the sensor saw"), "{said}");
    let (told_tree, said) = read_from(&recorded, viewpoints[0]);
    assert!(told_tree.is_some(), "{said}");
    assert_eq!(recorded_tree, told_tree);
    // A PLY file records none: a clear error.
    let (none, said) = read_from(&cloud, "--viewpoint-from-file");
    assert!(
        none.is_none() && said.contains("records no viewpoint"),
        "{said}"
    );
    // Told a laser made it: the silhouettes; a beam without a laser is
    // named.
    let (_, said) = recall(&["--sensor", "laser", "--beam-radius", "0.001"]);
    assert!(said.contains("silhouettes"), "{said}");
    let (none, said) = read_from(&cloud, "--beam-radius=0.001");
    assert!(none.is_none() && said.contains("beam_radius"), "{said}");
}
