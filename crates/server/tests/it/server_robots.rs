//! Several arms in one server: `--robot NAME=PATH` (imported descriptions
//! here), `GET /v1/robots`, `robot.name` in `/v1/plan` and `robot` in
//! `/v1/robot/link-poses`, joint vectors of each arm's own length, and a
//! broken robot file that stops start-up naming it unless skipped.

use std::process::Command;

use serde_json::{Value, json};
use treemanip_server::api::types::TreeJson;

use crate::common::server::Server;

/// A plan request on a random tree and a target made by a random push.
fn plan_body(robot: Value) -> Value {
    let (tree, targets) = crate::common::episode(12, 2);
    json!({
        "tree": serde_json::to_value(TreeJson::from_tree(&tree)).unwrap(),
        "target_positions": targets.iter().map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>(),
        "strategy": "paper",
        "budget_ms": 5000,
        "robot": robot,
    })
}

#[test]
fn the_server_plans_for_the_arm_each_request_names() {
    let server = Server::start(&[
        "--robot",
        "panda=robots/panda.toml",
        "--robot",
        "iiwa=robots/iiwa.toml",
    ]);
    let (status, answer) = server.get("/v1/robots");
    assert_eq!(status, 200, "{answer}");
    let robots = answer["robots"].as_array().unwrap();
    let names: Vec<&str> = robots.iter().map(|r| r["name"].as_str().unwrap()).collect();
    // The built-in, then robots/ by name (a --robot of the same name
    // takes its place).
    assert_eq!(names, ["ur5", "iiwa", "panda", "ur10"]);
    let panda = &robots[2];
    assert_eq!(panda["default"], true, "the first --robot is the default");
    assert_eq!(panda["dof"], 7);
    assert_eq!(panda["joint_names"].as_array().unwrap().len(), 7);
    assert_eq!(panda["limits"][3]["name"], "panda_joint4");
    assert_eq!(panda["limits"][3]["acceleration"], 12.5);
    assert_eq!(panda["base_link"], "panda_link0");
    assert_eq!(panda["tool_link"], "panda_hand");
    assert!((panda["tool_frame"]["xyz"][2].as_f64().unwrap() - 0.18).abs() < 1e-9);
    // Each says how its tool frame was chosen.
    assert_eq!(panda["tool_chosen"], "configured");
    assert!(
        robots[0]["tool_chosen"]
            .as_str()
            .unwrap()
            .starts_with("built in"),
        "{}",
        robots[0]
    );
    assert_eq!(robots[0]["closed_form_ik"], true);
    assert_eq!(panda["closed_form_ik"], false);

    // The default (panda) and a named one (ur5), each with its own joints.
    for (robot, dof) in [
        (
            json!({ "base_region": { "min": [-1.0, -0.5, 0.1], "max": [0.0, 0.5, 1.0] } }),
            7,
        ),
        (
            json!({ "name": "ur5", "base_region": { "min": [-1.0, -0.5, 0.1], "max": [0.0, 0.5, 1.0] } }),
            6,
        ),
    ] {
        let (status, answer) = server.json("POST", "/v1/plan", &plan_body(robot));
        assert_eq!(status, 200, "{answer}");
        assert_eq!(answer["joint_names"].as_array().unwrap().len(), dof);
        assert_eq!(answer["start"].as_array().unwrap().len(), dof);
        assert_eq!(answer["status"], "planned", "{answer}");
        if answer["status"] == "planned" {
            let jt = &answer["joint_trajectory"];
            assert_eq!(jt["joint_names"].as_array().unwrap().len(), dof);
            assert!(
                jt["points"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .all(|p| p["positions"].as_array().unwrap().len() == dof)
            );
            // The viewer's call: the plan's own robot draws it.
            let q: Vec<Value> = answer["trajectory"]
                .as_array()
                .unwrap()
                .iter()
                .map(|p| p["q"].clone())
                .collect();
            let (status, poses) = server.json(
                "POST",
                "/v1/robot/link-poses",
                &json!({ "robot": answer["robot"], "base": answer["base"], "configurations": q }),
            );
            assert_eq!(status, 200, "{poses}");
            assert_eq!(poses["joint_names"].as_array().unwrap().len(), dof);
        }
    }
    // Unknown robots and joint vectors of the wrong length are 422s that
    // say what is wrong.
    let (status, answer) = server.json("POST", "/v1/plan", &plan_body(json!({ "name": "abb" })));
    assert_eq!(status, 422, "{answer}");
    assert_eq!(answer["error"]["details"]["field"], "robot.name");
    assert!(
        answer["error"]["message"]
            .as_str()
            .unwrap()
            .contains("ur5, iiwa, panda, ur10")
    );
    let (status, answer) = server.json(
        "POST",
        "/v1/plan",
        &plan_body(json!({ "name": "panda", "start": [0, 0, 0, 0, 0, 0] })),
    );
    assert_eq!(status, 422, "{answer}");
    assert!(
        answer["error"]["message"]
            .as_str()
            .unwrap()
            .contains("7 joint values"),
        "{answer}"
    );
    let (status, answer) = server.json(
        "POST",
        "/v1/plan",
        &plan_body(json!({ "name": "panda", "start": [0, 0, 0, 0, 0, 0, 0] })),
    );
    assert_eq!(status, 422, "{answer}");
    assert!(
        answer["error"]["message"]
            .as_str()
            .unwrap()
            .contains("panda_joint4"),
        "{answer}"
    );
}

#[test]
fn a_broken_robot_stops_start_up_naming_it_unless_skipped() {
    let dir = crate::common::temp_dir("broken-robot");
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "name = \"bad\"\ndof = 6\n").unwrap();
    let spec = format!("bad={}", bad.display());
    let out = Command::new(crate::common::server::server_exe())
        .current_dir(crate::common::server::workspace_root())
        .args(["--bind", "127.0.0.1:0", "--robot", &spec])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("bad.toml"), "{stderr}");
    assert!(stderr.contains("--skip-broken-robots"), "{stderr}");
    let empty = dir.join("no-robots");
    let empty = empty.to_str().unwrap();
    let server = Server::start(&[
        "--robot",
        &spec,
        "--skip-broken-robots",
        "--robots-dir",
        empty,
    ]);
    let (status, answer) = server.get("/v1/robots");
    assert_eq!(status, 200);
    assert_eq!(answer["robots"].as_array().unwrap().len(), 1, "{answer}");

    // A broken description in the robots folder stops start-up too.
    std::fs::create_dir_all(dir.join("folder")).unwrap();
    std::fs::write(dir.join("folder/bad.toml"), "name = \"bad\"\ndof = 6\n").unwrap();
    let out = Command::new(crate::common::server::server_exe())
        .current_dir(crate::common::server::workspace_root())
        .args(["--bind", "127.0.0.1:0", "--robots-dir"])
        .arg(dir.join("folder"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("bad.toml"), "{stderr}");
}

/// Without `--robot`, the shipped descriptions in `robots/` are served by
/// name beside the built-in `ur5`, which stays the default; a plan names
/// one and gets its joints and its controller trajectory.
#[test]
fn the_shipped_arms_are_served_by_name() {
    let server = Server::start(&[]);
    let (status, answer) = server.get("/v1/robots");
    assert_eq!(status, 200, "{answer}");
    let robots = answer["robots"].as_array().unwrap();
    let names: Vec<&str> = robots.iter().map(|r| r["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["ur5", "iiwa", "panda", "ur10"]);
    let defaults: Vec<&str> = robots
        .iter()
        .filter(|r| r["default"] == true)
        .map(|r| r["name"].as_str().unwrap())
        .collect();
    assert_eq!(defaults, ["ur5"]);
    for (name, dof) in [("ur10", 6), ("panda", 7)] {
        let (status, answer) = server.json(
            "POST",
            "/v1/plan",
            &plan_body(json!({ "name": name,
                "base_region": { "min": [-1.0, -0.5, 0.1], "max": [0.0, 0.5, 1.0] } })),
        );
        assert_eq!(status, 200, "{answer}");
        assert_eq!(answer["robot"], name);
        assert_eq!(answer["joint_names"].as_array().unwrap().len(), dof);
        if answer["status"] == "planned" {
            assert!(
                answer["joint_trajectory"]["points"]
                    .as_array()
                    .unwrap()
                    .len()
                    > 2
            );
        }
    }
}

/// Every `planned` answer carries its controller trajectory, whatever the
/// arm: over the shipped arms, strategies and stances, each
/// planned push has a `joint_trajectory` whose push starts and ends at
/// valid points in order, and whose approach and push are the
/// `trajectory` the viewer plays (one timing).
#[test]
fn every_planned_answer_carries_its_controller_trajectory() {
    // A generous budget: the search stops at its first plan, and a debug
    // build sharing two cores with other tests is several times slower
    // than the release server the 2 s default is sized for.
    let server = Server::start(&["--max-plan-budget-ms", "10000"]);
    let mut planned = 0;
    for (k, name) in ["ur5", "panda", "iiwa", "ur10"].iter().enumerate() {
        for (e, strategy) in ["physics", "model", "physics"].iter().enumerate() {
            let (tree, targets) = crate::common::episode(10 + 4 * e, (10 * k + e) as u64);
            let robot = if e == 2 {
                json!({ "name": name })
            } else {
                json!({ "name": name, "base_region": { "min": [-1.0, -0.5, 0.1], "max": [0.0, 0.5, 1.0] } })
            };
            let body = json!({
                "tree": serde_json::to_value(TreeJson::from_tree(&tree)).unwrap(),
                "target_positions": targets.iter().map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>(),
                "strategy": strategy,
                "budget_ms": 10000,
                "robot": robot,
            });
            let (status, answer) = server.json("POST", "/v1/plan", &body);
            assert_eq!(status, 200, "{answer}");
            if answer["status"] != "planned" {
                assert!(answer["joint_trajectory"].is_null());
                continue;
            }
            planned += 1;
            let points = answer["joint_trajectory"]["points"]
                .as_array()
                .unwrap_or_else(|| panic!("{name}: planned without a trajectory: {answer}"));
            let start = answer["push_start_point"].as_u64().unwrap() as usize;
            let end = answer["push_end_point"].as_u64().unwrap() as usize;
            assert!(
                0 < start && start < end && end < points.len(),
                "{name}: {start} {end} {}",
                points.len()
            );
            let played = answer["trajectory"].as_array().unwrap();
            assert_eq!(played.len(), end + 1, "{name}");
            assert_eq!(answer["push_start_index"].as_u64(), Some(start as u64));
            for (p, t) in points.iter().zip(played) {
                assert_eq!(p["positions"], t["q"], "{name}");
            }
        }
    }
    assert!(planned >= 6, "only {planned} of 12 plans planned");
}
