//! The viewer and the endpoints it draws with: `/viewer` and its embedded
//! files, URDF → tree, example trees, the arm's link poses, and the page
//! itself driven in headless Chromium (`tests/python/viewer_browser.py`).

use std::path::Path;
use std::process::Command;

use nalgebra::{Isometry3, Vector3};
use serde_json::{Value, json};
use treemanip_core::robot::Arm;
use treemanip_core::tree::sca::{ScaParams, generate};
use treemanip_core::tree::urdf::to_urdf_string;
use treemanip_core::tree::{MAX_NODES, OrchardParams, Wood, generate_orchard};
use treemanip_server::api::types::TreeJson;

use crate::common::server::Server;

fn server() -> Server {
    Server::start(&[
        "--models-dir",
        concat!(env!("CARGO_MANIFEST_DIR"), "/../../models"),
    ])
}

#[test]
fn the_page_and_its_files_are_served_from_the_binary() {
    let server = Server::start(&[]);
    let (status, head, html) = server.request("GET", "/viewer", "text/plain", b"");
    assert_eq!(status, 200);
    assert!(head.contains("content-type: text/html"), "{head}");
    assert!(
        head.contains("content-security-policy: default-src 'self'"),
        "{head}"
    );
    // Every file the page and its scripts load is served, with its type.
    assert!(html.contains("/viewer/viewer.js") && html.contains("/viewer/viewer.css"));
    let script = std::fs::read_to_string(
        Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("assets/viewer/viewer.js"),
    )
    .unwrap();
    assert!(script.contains("from './vendor/three.module.min.js'"));
    assert!(script.contains("from './meshes.js'"));
    for (path, media) in [
        ("/viewer/viewer.js", "text/javascript"),
        ("/viewer/meshes.js", "text/javascript"),
        ("/viewer/viewer.css", "text/css"),
        ("/viewer/vendor/three.module.min.js", "text/javascript"),
        ("/viewer/vendor/OrbitControls.js", "text/javascript"),
        ("/viewer/vendor/PLYLoader.js", "text/javascript"),
        ("/viewer/api.js", "text/javascript"),
        ("/viewer/cloud.js", "text/javascript"),
        ("/viewer/vendor/LICENSE-three.txt", "text/plain"),
    ] {
        let (status, head, body) = server.request("GET", path, "text/plain", b"");
        assert_eq!(status, 200, "{path}");
        assert!(
            head.contains(&format!("content-type: {media}")),
            "{path}: {head}"
        );
        assert!(!body.is_empty(), "{path}");
    }
    // The vendored three.js is the pinned release, with its licence, and
    // its controls import the vendored module (no bare `three`, no CDN).
    let (_, _, controls) = server.request("GET", "/viewer/vendor/OrbitControls.js", "", b"");
    assert!(controls.contains("from './three.module.min.js';"));
    let (_, _, three) = server.request("GET", "/viewer/vendor/three.module.min.js", "", b"");
    assert!(three.contains("REVISION=\"170\"") || three.contains("=\"170\""));
    let (_, _, licence) = server.request("GET", "/viewer/vendor/LICENSE-three.txt", "", b"");
    assert!(licence.contains("MIT License") || licence.contains("The MIT License"));
    for text in [&html, &script] {
        assert!(
            !text.contains("https://"),
            "the page must not load from the network"
        );
    }
    let (status, body) = server.get("/viewer/nope.js");
    assert_eq!(status, 404);
    assert!(
        body["error"]["message"]
            .as_str()
            .unwrap()
            .contains("nope.js")
    );
}

#[test]
fn urdf_becomes_the_same_tree_json() {
    let server = Server::start(&[]);
    let tree = generate(12, 4, &ScaParams::default()).unwrap();
    let urdf = to_urdf_string(&tree, "t", &Wood::default());
    let (status, body) = server.json("POST", "/v1/trees/urdf", &json!({ "urdf": urdf }));
    assert_eq!(status, 200, "{body}");
    assert_eq!(body["nodes"], 12);
    let got: TreeJson = serde_json::from_value(body["tree"].clone()).unwrap();
    let back = got.to_tree(MAX_NODES).unwrap();
    assert_eq!(back.parents(), tree.parents());
    for (a, b) in back.positions().iter().zip(tree.positions()) {
        assert!((a - b).norm() < 1e-9, "{a} vs {b}");
    }
    for (a, b) in back.branches().iter().zip(tree.branches()) {
        if let (Some(a), Some(b)) = (a, b) {
            assert!((a.radius - b.radius).abs() < 1e-12);
            assert!((a.stiffness - b.stiffness).abs() < 1e-9 * b.stiffness);
        }
    }
    // Not XML, not a tree URDF, too many nodes: 4xx naming the problem.
    let (status, body) = server.json("POST", "/v1/trees/urdf", &json!({ "urdf": "<robot" }));
    assert_eq!(status, 422, "{body}");
    assert!(
        body["error"]["message"].as_str().unwrap().contains("URDF"),
        "{body}"
    );
    let arm = treemanip_core::robot::ur5::URDF;
    let (status, body) = server.json("POST", "/v1/trees/urdf", &json!({ "urdf": arm }));
    assert_eq!(status, 422, "{body}");
    let small = Server::start(&["--max-nodes", "10"]);
    let (status, body) = small.json("POST", "/v1/trees/urdf", &json!({ "urdf": urdf }));
    assert_eq!(status, 413, "{body}");
}

#[test]
fn examples_are_the_generators_trees() {
    let server = Server::start(&[]);
    let (status, body) = server.get("/v1/trees/example?nodes=12&seed=5");
    assert_eq!(status, 200, "{body}");
    let expected = generate(12, 5, &ScaParams::default()).unwrap();
    assert_eq!(
        body["tree"],
        serde_json::to_value(TreeJson::from_tree(&expected)).unwrap()
    );
    assert_eq!(
        (body["nodes"].as_u64(), body["seed"].as_u64()),
        (Some(12), Some(5))
    );
    let (_, again) = server.get("/v1/trees/example?nodes=12&seed=5");
    assert_eq!(again, body, "deterministic for a seed");
    let (_, default) = server.get("/v1/trees/example");
    assert_eq!(default["nodes"], 15);
    // Above the SCA generator's 64 nodes: an orchard tree.
    let (status, body) = server.get("/v1/trees/example?nodes=300&seed=2");
    assert_eq!(status, 200, "{body}");
    let orchard = generate_orchard(300, 2, &OrchardParams::default()).unwrap();
    assert_eq!(
        body["tree"],
        serde_json::to_value(TreeJson::from_tree(&orchard)).unwrap()
    );
    for bad in ["?nodes=3", "?nodes=513", "?seed=x", "?size=4"] {
        let (status, body) = server.get(&format!("/v1/trees/example{bad}"));
        assert_eq!(status, 422, "{bad}: {body}");
        assert_eq!(body["error"]["code"], "invalid_argument");
    }
}

fn pose_of(v: &Value) -> Isometry3<f64> {
    let p: Vec<f64> = serde_json::from_value(v.clone()).unwrap();
    let q = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
        p[6], p[3], p[4], p[5],
    ));
    Isometry3::from_parts(Vector3::new(p[0], p[1], p[2]).into(), q)
}

#[test]
fn link_poses_are_the_planners_kinematics() {
    let server = Server::start(&[]);
    let qs = [
        [0.0, -1.2, 1.4, -0.3, 1.57, 0.2],
        [0.5, -0.7, 0.9, 0.1, -1.0, 2.0],
    ];
    let request =
        json!({ "base": { "position": [-0.4, 0.3, 0.2], "yaw": 0.7 }, "configurations": qs });
    let (status, body) = server.json("POST", "/v1/robot/link-poses", &request);
    assert_eq!(status, 200, "{body}");
    let robot = Arm::default().with_base(Isometry3::new(
        Vector3::new(-0.4, 0.3, 0.2),
        Vector3::z() * 0.7,
    ));
    let names: Vec<&str> = robot.link_names().collect();
    let links = body["links"].as_array().unwrap();
    assert_eq!(links.len(), names.len());
    let tool = robot.link_index("tool").unwrap();
    for (k, q) in qs.iter().enumerate() {
        let expected = robot.link_poses(q);
        let got = body["poses"][k].as_array().unwrap();
        for (i, (e, g)) in expected.iter().zip(got).enumerate() {
            assert_eq!(links[i]["name"], names[i]);
            let g = pose_of(g);
            assert!((g.translation.vector - e.translation.vector).norm() < 1e-12);
            assert!(g.rotation.angle_to(&e.rotation) < 1e-9);
        }
        let t = pose_of(&got[tool]);
        assert!((t.translation.vector - robot.tool_pose(q).translation.vector).norm() < 1e-12);
    }
    // Every capsule and box the collision checker uses is listed.
    let shapes: usize = links
        .iter()
        .map(|l| l["shapes"].as_array().unwrap().len())
        .sum();
    let expected: usize = robot.link_shapes().map(|(_, s)| s.len()).sum();
    assert_eq!(shapes, expected);
    assert!(shapes >= 12);
    // Defaults to the paper's mount; bad joints and sizes are 422.
    let (status, body) = server.json(
        "POST",
        "/v1/robot/link-poses",
        &json!({ "configurations": [[0, 0, 0, 0, 0, 0]] }),
    );
    assert_eq!(status, 200);
    assert_eq!(body["base"]["position"], json!([-0.5, 0.0, 0.1]));
    for (bad, field) in [
        (json!({ "configurations": [] }), "configurations"),
        (
            json!({ "configurations": [[0, 0, 0]] }),
            "configurations[0]",
        ),
        (
            json!({ "configurations": [[0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 99]] }),
            "configurations[1]",
        ),
        (
            json!({ "robot": "abb", "configurations": [[0, 0, 0, 0, 0, 0]] }),
            "robot",
        ),
        (
            json!({ "base": { "position": [9, 0, 0] }, "configurations": [[0, 0, 0, 0, 0, 0]] }),
            "base.position",
        ),
    ] {
        let (status, body) = server.json("POST", "/v1/robot/link-poses", &bad);
        assert_eq!(status, 422, "{bad}: {body}");
        assert_eq!(body["error"]["details"]["field"], field, "{body}");
    }
    let many = vec![[0.0; 6]; treemanip_server::api::scene::MAX_CONFIGURATIONS + 1];
    let (status, _) = server.json(
        "POST",
        "/v1/robot/link-poses",
        &json!({ "configurations": many }),
    );
    assert_eq!(status, 422);
}

/// Chromium, its driver and selenium, or why not.
fn browser_available() -> Result<(), String> {
    for tool in ["chromium", "chromedriver"] {
        let found = Command::new("sh")
            .args(["-c", &format!("command -v {tool}")])
            .output()
            .is_ok_and(|o| o.status.success());
        if !found {
            return Err(format!(
                "{tool} is not installed (apt-get install chromium chromium-driver)"
            ));
        }
    }
    let selenium = Command::new("python3")
        .args(["-c", "import selenium"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !selenium {
        return Err("selenium is not installed (pip install -r requirements-dev.txt)".into());
    }
    Ok(())
}

#[test]
fn the_viewer_runs_its_flows_in_chromium() {
    if let Err(why) = browser_available() {
        assert!(
            std::env::var_os("TREEMANIP_REQUIRE_BROWSER").is_none(),
            "the browser test must run here: {why}"
        );
        println!("skipped: {why}");
        return;
    }
    let server = server();
    let dir = crate::common::temp_dir("viewer");
    let tree = generate(11, 2, &ScaParams::default()).unwrap();
    let urdf = dir.join("tree.urdf");
    std::fs::write(&urdf, to_urdf_string(&tree, "example", &Wood::default())).unwrap();
    // A scan of another tree, to upload as a cloud.
    let scanned = treemanip_core::scan::scan(
        &generate(14, 4, &ScaParams::default()).unwrap(),
        &treemanip_core::scan::ScanParams {
            samples_per_view: 15_000,
            ..Default::default()
        },
    )
    .unwrap();
    let ply = dir.join("scan.ply");
    let mut bytes = Vec::new();
    treemanip_core::scan::io::ply::write(&scanned.cloud, &mut bytes).unwrap();
    std::fs::write(&ply, bytes).unwrap();
    let mut command = Command::new("python3");
    command
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../tests/python/viewer_browser.py"
        ))
        .arg(format!("http://{}", server.addr))
        .arg("--urdf")
        .arg(&urdf)
        .args(["--urdf-nodes", "11"])
        .arg("--ply")
        .arg(&ply)
        .arg("--ply-points")
        .arg(scanned.cloud.len().to_string());
    if let Some(shots) = std::env::var_os("TREEMANIP_VIEWER_SCREENSHOTS") {
        command.arg("--screenshots").arg(shots);
    }
    let out = command.output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    println!("{stdout}");
    assert!(
        out.status.success(),
        "viewer checks failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("all viewer checks passed"));
    let _ = std::fs::remove_dir_all(dir);
}
