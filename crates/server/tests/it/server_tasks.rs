//! `/v1/plan` with orchard objectives and load limits over HTTP, on the
//! committed models: a `clear` plan checked by simulating its push, the
//! loads and limits reported, `target_positions` still a shorthand, and
//! every bad objective answered with a 4xx naming its field.

use serde_json::{Value, json};
use treemanip_core::geometry::shape::Shape;
use treemanip_core::planner::Objective;
use treemanip_core::planner::objective::SATISFIED;
use treemanip_core::sim::guarded::guarded_push;
use treemanip_core::sim::loads::PushLoads;
use treemanip_core::sim::{Push, SimConfig, simulate};
use treemanip_core::tree::{Branch, ScaParams, Tree, generate};
use treemanip_server::api::types::TreeJson;

use crate::common::server::Server;

const MODELS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../models");

fn p(v: &nalgebra::Point3<f64>) -> Value {
    json!([v.x, v.y, v.z])
}

/// A 15-node tree and a 4 cm fruit across the middle of its deepest leaf's
/// branch (the kind of task `eval tasks` poses).
fn task() -> (Tree, nalgebra::Point3<f64>) {
    let tree = generate(15, 4, &ScaParams::default()).unwrap();
    let leaf = (1..tree.len())
        .filter(|&j| tree.is_leaf(j))
        .max_by_key(|&j| tree.depth(j))
        .unwrap();
    let parent = tree.parent(leaf).unwrap();
    let centre = nalgebra::center(&tree.position(parent), &tree.position(leaf))
        + nalgebra::Vector3::new(0.0, 0.0, 0.01);
    (tree, centre)
}

#[test]
fn plan_clears_a_fruit_and_reports_loads() {
    let server = Server::start(&["--models-dir", MODELS]);
    let (tree, centre) = task();
    let tree_json = serde_json::to_value(TreeJson::from_tree(&tree)).unwrap();
    let region = json!({ "kind": "sphere", "centre": p(&centre), "radius": 0.04 });
    let objective = Objective::Clear {
        regions: vec![Shape::Sphere {
            centre,
            radius: 0.04,
        }],
        margin: 0.01,
    };
    let no_action = objective.residual(&tree, tree.positions());
    assert!(no_action > 0.0);
    let base_region = json!({ "min": [-1.0, -0.5, 0.1], "max": [0.0, 0.5, 1.0] });
    for strategy in ["physics", "model"] {
        let body = json!({
            "tree": tree_json,
            "objective": { "kind": "clear", "regions": [region] },
            "limits": { "max_stress": 40e6 },
            "strategy": strategy,
            "robot": { "base_region": base_region },
        });
        let (status, plan) = server.json("POST", "/v1/plan", &body);
        assert_eq!(status, 200, "{plan}");
        assert_eq!(plan["objective"], "clear");
        assert!((plan["no_action_error"].as_f64().unwrap() - no_action).abs() < 1e-9);
        assert_eq!(plan["limits"]["max_stress"], 40e6);
        assert_eq!(plan["limits"]["max_contact_force"], 50.0, "the default");
        for a in plan["attempts"].as_array().unwrap() {
            if a["outcome"] == "over_limit" {
                let loads = if a["simulated_loads"].is_null() {
                    &a["predicted_loads"]
                } else {
                    &a["simulated_loads"]
                };
                let over = loads["peak_stress"].as_f64().unwrap() > 40e6
                    || loads["contact_force"].as_f64().unwrap() > 50.0;
                assert!(over, "{a}");
            }
        }
        if plan["status"] != "planned" {
            // The simulator predicts exactly: this fruit can be cleared.
            assert_ne!(strategy, "physics", "{plan}");
            continue;
        }
        let v = &plan["push"];
        let push = Push {
            node: plan["node"].as_u64().unwrap() as usize,
            vector: nalgebra::Vector3::new(
                v[0].as_f64().unwrap(),
                v[1].as_f64().unwrap(),
                v[2].as_f64().unwrap(),
            ),
        };
        let out = simulate(&tree, &push, &SimConfig::default()).unwrap();
        let loads = PushLoads::of_outcome(&tree, &out);
        let simulated = &plan["simulated_loads"];
        assert!((simulated["peak_stress"].as_f64().unwrap() - loads.peak_stress).abs() < 1.0);
        assert!(loads.peak_stress <= 40e6 && loads.contact_force <= 50.0);
        let margin = simulated["margin"]["stress"].as_f64().unwrap();
        assert!((margin - (1.0 - loads.peak_stress / 40e6)).abs() < 1e-9);
        assert!(plan["predicted_loads"]["peak_stress"].as_f64().unwrap() > 0.0);
        // The guard: the tree as sent never trips it; the same tree stiff
        // enough to take 1.5 times the guard for the push does, before its
        // wood passes the stress limit (the shape is the same, forces and
        // stresses scale with the stiffness).
        let guard = plan["guard_contact_force"].as_f64().unwrap();
        let at_end = loads.contact_force * 40e6 / loads.peak_stress;
        assert!(guard <= at_end.min(50.0) + 1e-9, "{guard} N");
        assert!(guard >= loads.contact_force, "{guard} N");
        let config = SimConfig::default();
        let as_sent = guarded_push(&tree, &push, &config, guard).unwrap();
        assert!(
            !as_sent.stopped,
            "{strategy}: the tree as planned tripped the guard"
        );
        let factor = 1.5 * guard / loads.contact_force;
        let stiffer = Tree::new(
            tree.positions().to_vec(),
            tree.parents().to_vec(),
            tree.branches()
                .iter()
                .map(|b| {
                    b.map(|b| Branch {
                        stiffness: factor * b.stiffness,
                        ..b
                    })
                })
                .collect(),
        )
        .unwrap();
        let unguarded =
            PushLoads::of_outcome(&stiffer, &simulate(&stiffer, &push, &config).unwrap());
        let guarded = guarded_push(&stiffer, &push, &config, guard).unwrap();
        let held = PushLoads::of_outcome(&stiffer, &guarded.outcome);
        assert!(guarded.stopped && guarded.fraction < 1.0);
        assert!(unguarded.contact_force > guard, "{unguarded:?}");
        assert!(unguarded.peak_stress > 40e6 || unguarded.contact_force > 50.0);
        assert!(
            held.contact_force <= guard && held.peak_stress <= 40e6,
            "{held:?}"
        );
        // `/v1/simulate` carries out the same guarded move on the stiffer
        // tree, sent with its stiffness.
        let body = json!({
            "tree": serde_json::to_value(TreeJson::from_tree(&stiffer)).unwrap(),
            "contact_node": push.node,
            "push": [push.vector.x, push.vector.y, push.vector.z],
            "stop_at_contact_force": guard,
        });
        let (status, sim) = server.json("POST", "/v1/simulate", &body);
        assert_eq!(status, 200, "{sim}");
        assert_eq!(sim["guarded"]["stopped"], true);
        let fraction = sim["guarded"]["fraction"].as_f64().unwrap();
        assert!((fraction - guarded.fraction).abs() < 1e-9, "{fraction}");
        let peak = sim["peak_stress"]["stress"].as_f64().unwrap();
        assert!((peak - held.peak_stress).abs() < 1.0, "{peak}");
        let executed = objective.residual(&tree, &out.final_positions);
        let clearance = plan["clearance"]["simulated"].as_f64().unwrap();
        let reached = objective
            .scorer()
            .clearance(&tree, &out.final_positions)
            .unwrap();
        assert!(
            (clearance - reached).abs() < 1e-9,
            "{clearance} vs {reached}"
        );
        assert!(
            executed <= SATISFIED || executed < no_action,
            "{strategy}: {executed}"
        );
    }
    // `paper` plans shapes only.
    let body = json!({
        "tree": tree_json,
        "objective": { "kind": "clear", "regions": [region] },
        "strategy": "paper",
    });
    let (status, e) = server.json("POST", "/v1/plan", &body);
    assert_eq!(
        (status, e["error"]["details"]["field"].as_str()),
        (422, Some("strategy")),
        "{e}"
    );
    // The shorthand and the shape objective plan the same.
    let targets: Vec<Value> = tree.positions().iter().map(p).collect();
    let mut moved = targets.clone();
    moved[3][0] = json!(moved[3][0].as_f64().unwrap() + 0.05);
    let short = json!({ "tree": tree_json, "target_positions": moved, "strategy": "physics" });
    let long = json!({
        "tree": tree_json,
        "objective": { "kind": "shape", "target_positions": moved },
        "strategy": "physics",
    });
    let (s1, a) = server.json("POST", "/v1/plan", &short);
    let (s2, b) = server.json("POST", "/v1/plan", &long);
    assert_eq!((s1, s2), (200, 200), "{a} {b}");
    assert_eq!(
        (a["node"].clone(), a["push"].clone()),
        (b["node"].clone(), b["push"].clone())
    );
    assert_eq!(a["objective"], "shape");
}

/// A sphere obstacle (the shape regions have) is taken, and a sphere
/// swallowing the tree's root blocks every plan from the start.
#[test]
fn sphere_obstacles_are_obstacles() {
    let server = Server::start(&["--models-dir", MODELS]);
    let (tree, _) = task();
    let tree_json = serde_json::to_value(TreeJson::from_tree(&tree)).unwrap();
    let targets: Vec<Value> = tree.positions().iter().map(p).collect();
    let body = |obstacle: Value| {
        json!({ "tree": tree_json, "target_positions": targets, "strategy": "physics",
                "max_evaluations": 8, "obstacles": [obstacle] })
    };
    let (status, answer) = server.json(
        "POST",
        "/v1/plan",
        &body(json!({ "kind": "sphere", "centre": [2.0, 2.0, 0.5], "radius": 0.1 })),
    );
    assert_eq!(status, 200, "{answer}");
    // Around the arm's default base (the paper's mount at (-0.5, 0, 0.1)).
    let (status, answer) = server.json(
        "POST",
        "/v1/plan",
        &body(json!({ "kind": "sphere", "centre": [-0.5, 0.0, 0.3], "radius": 0.4 })),
    );
    assert_eq!(status, 422, "{answer}");
    assert_eq!(
        answer["error"]["details"]["field"], "robot.start",
        "{answer}"
    );
    assert!(
        answer["error"]["message"]
            .as_str()
            .unwrap()
            .contains("obstacle"),
        "{answer}"
    );
}

/// Every kind of the one shape schema is an obstacle (a turned box, a
/// cylinder on its side), a box takes `yaw` or `rotation` but not both, and
/// the arm's link shapes `/v1/robot/link-poses` answers are that schema:
/// sent back as obstacles (moved 3 m away) they are accepted as they are.
#[test]
fn every_shape_kind_is_an_obstacle_and_the_scene_speaks_the_same_schema() {
    let server = Server::start(&["--models-dir", MODELS]);
    let (tree, _) = task();
    let tree_json = serde_json::to_value(TreeJson::from_tree(&tree)).unwrap();
    let targets: Vec<Value> = tree.positions().iter().map(p).collect();
    let body = |obstacles: Value| {
        json!({ "tree": tree_json, "target_positions": targets, "strategy": "physics",
                "max_evaluations": 8, "obstacles": obstacles })
    };
    // Around the arm's default base (the paper's mount at (-0.5, 0, 0.1)):
    // a box turned 45° about x, a cylinder lying along y.
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let around_base = [
        json!({ "kind": "box", "centre": [-0.5, 0.0, 0.3], "half_extents": [0.3, 0.3, 0.3],
                "rotation": [(std::f64::consts::FRAC_PI_8).sin(), 0.0, 0.0, (std::f64::consts::FRAC_PI_8).cos()] }),
        json!({ "kind": "cylinder", "centre": [-0.5, 0.0, 0.3], "rotation": [s, 0.0, 0.0, s],
                "radius": 0.3, "half_length": 0.5 }),
    ];
    for shape in &around_base {
        let (status, answer) = server.json("POST", "/v1/plan", &body(json!([shape])));
        assert_eq!(status, 422, "{shape}: {answer}");
        assert_eq!(
            answer["error"]["details"]["field"], "robot.start",
            "{answer}"
        );
        // The same shape 3 m away blocks nothing.
        let mut far = shape.clone();
        far["centre"][0] = json!(2.5);
        let (status, answer) = server.json("POST", "/v1/plan", &body(json!([far])));
        assert_eq!(status, 200, "{far}: {answer}");
    }
    for (shape, field) in [
        (
            json!({ "kind": "box", "centre": [2.0, 0.0, 0.3], "half_extents": [0.1, 0.1, 0.1],
                    "yaw": 0.3, "rotation": [0.0, 0.0, 0.0, 1.0] }),
            "obstacles.rotation",
        ),
        (
            json!({ "kind": "cylinder", "centre": [2.0, 0.0, 0.3], "rotation": [0.0, 0.0, 0.0, 0.0],
                    "radius": 0.1, "half_length": 0.1 }),
            "obstacles.rotation",
        ),
        (
            json!({ "kind": "cylinder", "centre": [2.0, 0.0, 0.3], "radius": 0.1, "half_length": 0.0 }),
            "obstacles.half_length",
        ),
    ] {
        let (status, answer) = server.json("POST", "/v1/plan", &body(json!([shape])));
        assert_eq!(status, 422, "{shape}: {answer}");
        assert_eq!(answer["error"]["details"]["field"], field, "{answer}");
    }
    let (status, scene) = server.json(
        "POST",
        "/v1/robot/link-poses",
        &json!({ "configurations": [[0.0, -1.5, 1.5, 0.0, 0.0, 0.0]] }),
    );
    assert_eq!(status, 200, "{scene}");
    let mut shapes: Vec<Value> = scene["links"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|l| l["shapes"].as_array().unwrap().clone())
        .collect();
    let kinds: std::collections::BTreeSet<&str> =
        shapes.iter().map(|s| s["kind"].as_str().unwrap()).collect();
    assert!(
        kinds.contains("capsule") && kinds.contains("box"),
        "{kinds:?}"
    );
    for shape in &mut shapes {
        for key in ["centre", "a", "b"] {
            if let Some(x) = shape[key][0].as_f64() {
                shape[key][0] = json!(x + 3.0);
            }
        }
    }
    let (status, answer) = server.json("POST", "/v1/plan", &body(json!(shapes)));
    assert_eq!(status, 200, "{answer}");
}

/// Each bad objective or limit gets a 4xx JSON error naming its field, and
/// the server goes on answering.
#[test]
fn bad_objectives_are_named() {
    let server = Server::start(&["--models-dir", MODELS]);
    let (tree, centre) = task();
    let n = tree.len();
    let tree_json = serde_json::to_value(TreeJson::from_tree(&tree)).unwrap();
    let targets: Vec<Value> = tree.positions().iter().map(p).collect();
    let sphere = json!({ "kind": "sphere", "centre": p(&centre), "radius": 0.04 });
    let plan = |extra: Value| {
        let mut body = json!({ "tree": tree_json, "strategy": "physics" });
        for (k, v) in extra.as_object().unwrap() {
            body[k] = v.clone();
        }
        body
    };
    let mut zero_weights = vec![0.0; n];
    zero_weights[0] = 1.0;
    let cases = [
        (json!({}), "objective"),
        (
            json!({ "target_positions": targets, "objective": { "kind": "clear", "regions": [sphere] } }),
            "objective",
        ),
        (
            json!({ "objective": { "kind": "clear", "regions": [] } }),
            "objective.regions",
        ),
        (
            json!({ "objective": { "kind": "clear", "regions": [{ "kind": "sphere", "centre": [0, 0, 0.5], "radius": -0.1 }] } }),
            "objective.regions[0].radius",
        ),
        (
            json!({ "objective": { "kind": "clear", "regions": [{ "kind": "sphere", "centre": [100, 0, 0.5], "radius": 0.1 }] } }),
            "objective.regions[0].centre",
        ),
        (
            json!({ "objective": { "kind": "clear", "regions": [{ "kind": "box", "centre": [0, 0, 0.5], "half_extents": [0.1, 0, 0.1] }] } }),
            "objective.regions[0].half_extents",
        ),
        (
            json!({ "objective": { "kind": "clear", "regions": [sphere], "margin": -0.01 } }),
            "objective.margin",
        ),
        (
            json!({ "objective": { "kind": "shape", "target_positions": targets, "weights": zero_weights } }),
            "objective.weights",
        ),
        (
            json!({ "objective": { "kind": "shape", "target_positions": targets, "weights": [1.0] } }),
            "objective.weights",
        ),
        (
            json!({ "objective": { "kind": "reach", "node": 0, "region": sphere } }),
            "objective.node",
        ),
        (
            json!({ "objective": { "kind": "reach", "node": n, "region": sphere } }),
            "objective.node",
        ),
        (
            json!({ "target_positions": targets, "limits": { "max_stress": 0.0 } }),
            "limits.max_stress",
        ),
        (
            json!({ "target_positions": targets, "limits": { "max_contact_force": -5.0 } }),
            "limits.max_contact_force",
        ),
        // Obstacles are the same shapes, checked by the same validator
        // (sizes up to 5 m where a region's stop at 2 m).
        (
            json!({ "target_positions": targets, "obstacles": [{ "kind": "sphere", "centre": [0, 0, 0.5], "radius": 6.0 }] }),
            "obstacles.radius",
        ),
        (
            json!({ "target_positions": targets, "obstacles": [{ "kind": "box", "centre": [100, 0, 0.5], "half_extents": [0.1, 0.1, 0.1] }] }),
            "obstacles.centre",
        ),
        (
            json!({ "objective": { "kind": "clear", "regions": [{ "kind": "capsule", "a": [0, 0, 0], "b": [0, 0, 1], "radius": 3.0 }] } }),
            "objective.regions[0].radius",
        ),
    ];
    for (extra, field) in cases {
        let body = plan(extra);
        let (status, e) = server.json("POST", "/v1/plan", &body);
        assert!((400..500).contains(&status), "{body}: {status} {e}");
        assert_eq!(
            e["error"]["details"]["field"].as_str(),
            Some(field),
            "{body}: {e}"
        );
    }
    // NaN cannot be written in JSON; a string where a number belongs is a
    // malformed body, also a 4xx.
    let body = plan(
        json!({ "objective": { "kind": "clear", "regions": [{ "kind": "sphere", "centre": [0, 0, "x"], "radius": 0.1 }] } }),
    );
    let (status, _) = server.json("POST", "/v1/plan", &body);
    assert!((400..500).contains(&status));
    let (status, _) = server.json(
        "POST",
        "/v1/plan",
        &plan(json!({ "target_positions": targets })),
    );
    assert_eq!(status, 200);
}
