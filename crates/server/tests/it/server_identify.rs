//! `/v1/identify`, `/v1/identify/probes` and `/v1/plan`'s `observations`
//! over HTTP: probes simulated on a tree with hidden stiffness, the
//! estimate checked against the truth, bad probes named.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde_json::{Value, json};
use treemanip_core::identify::{Noise, Probe, observe};
use treemanip_core::sim::{ContactModel, Push};
use treemanip_core::tree::{ScaParams, StiffnessVariation, Tree, generate};
use treemanip_server::api::types::TreeJson;

use crate::common::server::Server;

const MODELS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../models");

fn trees() -> (Tree, Tree) {
    let nominal = generate(13, 21, &ScaParams::default()).unwrap();
    let variation = StiffnessVariation {
        branch_log_sigma: 0.3,
        global_factor: 1.0,
    };
    let truth = variation.apply(&nominal, &mut ChaCha8Rng::seed_from_u64(2));
    (nominal, truth)
}

fn probe_json(p: &Probe) -> Value {
    let mut v = json!({
        "contact_node": p.push.node,
        "push": [p.push.vector.x, p.push.vector.y, p.push.vector.z],
        "observed_positions": p.observed.iter().map(|o| o.map(|o| [o.x, o.y, o.z])).collect::<Vec<_>>(),
    });
    if let Some(f) = p.contact_force {
        v["contact_force"] = json!([f.x, f.y, f.z]);
    }
    v
}

fn tree_value(tree: &Tree) -> Value {
    serde_json::to_value(TreeJson::from_tree(tree)).unwrap()
}

/// The prior tree as a client sends it: radius only (the formula).
fn prior_tree(tree: &Tree) -> Value {
    let mut v = tree_value(tree);
    v.as_object_mut().unwrap().remove("stiffness");
    v
}

#[test]
fn identify_and_probes_over_http() {
    let server = Server::start(&[
        "--models-dir",
        crate::common::temp_dir("id-none").to_str().unwrap(),
    ]);
    let (nominal, truth) = trees();
    // Proposed probes, then observed on the hidden truth.
    let (status, proposed) = server.json(
        "POST",
        "/v1/identify/probes",
        &json!({"tree": prior_tree(&nominal), "count": 4}),
    );
    assert_eq!(status, 200, "{proposed}");
    let list = proposed["probes"].as_array().unwrap();
    assert_eq!(list.len(), 4);
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let probes: Vec<Probe> = list
        .iter()
        .map(|p| {
            let v: Vec<f64> = serde_json::from_value(p["push"].clone()).unwrap();
            let push = Push {
                node: p["contact_node"].as_u64().unwrap() as usize,
                vector: nalgebra::Vector3::new(v[0], v[1], v[2]),
            };
            observe(
                &truth,
                push,
                ContactModel::Slot,
                &Noise::default(),
                true,
                &mut rng,
            )
            .unwrap()
        })
        .collect();
    let body = json!({
        "tree": prior_tree(&nominal),
        "probes": probes.iter().map(probe_json).collect::<Vec<_>>(),
    });
    let (status, answer) = server.json("POST", "/v1/identify", &body);
    assert_eq!(status, 200, "{answer}");
    assert_eq!(answer["scale"], "absolute");
    assert_eq!(answer["stiffness"][0], Value::Null);
    let n = nominal.len();
    assert_eq!(answer["stiffness"].as_array().unwrap().len(), n);
    let mut checked = 0;
    for j in 1..n {
        if answer["status"][j] == "identified" {
            let k = answer["stiffness"][j].as_f64().unwrap();
            let truth_k = truth.branch(j).unwrap().stiffness;
            assert!((k / truth_k).ln().abs() < 0.3, "node {j}: {k} vs {truth_k}");
            let lo = answer["interval"][j][0].as_f64().unwrap();
            let hi = answer["interval"][j][1].as_f64().unwrap();
            assert!(lo < k && k < hi);
            checked += 1;
        }
    }
    assert!(checked >= 2, "{answer}");
    assert!(
        answer["fit"]["position_rms"].as_f64().unwrap()
            < answer["fit"]["prior_position_rms"].as_f64().unwrap()
    );
    // The returned tree is ready for the other endpoints.
    let simulate = json!({"tree": answer["tree"], "contact_node": 1, "push": [0.02, 0.0, 0.0]});
    let (status, _) = server.json("POST", "/v1/simulate", &simulate);
    assert_eq!(status, 200);

    // Bad probes: 422 naming the probe and the field.
    let bad = |edit: &dyn Fn(&mut Value)| {
        let mut b = body.clone();
        edit(&mut b);
        let (status, e) = server.json("POST", "/v1/identify", &b);
        assert_eq!(status, 422, "{e}");
        e["error"]["details"]["field"]
            .as_str()
            .unwrap_or_default()
            .to_owned()
    };
    assert_eq!(
        bad(&|b| b["probes"][1]["contact_node"] = json!(0)),
        "probes[1].contact_node"
    );
    assert_eq!(
        bad(&|b| {
            b["probes"][2]["observed_positions"]
                .as_array_mut()
                .unwrap()
                .pop();
        }),
        "probes[2].observed_positions"
    );
    assert_eq!(
        bad(&|b| b["probes"][0]["contact_force"] = json!([0.0, 0.0, 0.0])),
        "probes[0].contact_force"
    );
    assert_eq!(
        bad(&|b| b["probes"][0]["push"] = json!([0.1, 0.0])),
        "probes[0].push"
    );
    assert_eq!(
        bad(&|b| b["probes"][3]["observed_positions"][n - 1] = json!([5.0, 5.0, 5.0])),
        "probes[3].observed_positions"
    );
    assert_eq!(bad(&|b| b["probes"] = json!([])), "probes");
    assert_eq!(
        bad(&|b| b["noise"] = json!({"position": -1.0})),
        "noise.position"
    );
    // Non-finite numbers are not JSON: a 400, not a panic.
    let text = serde_json::to_string(&body)
        .unwrap()
        .replacen("\"push\":[", "\"push\":[NaN,", 1);
    let (status, _) = server.send("POST", "/v1/identify", "application/json", text.as_bytes());
    assert_eq!(status, 400);
}

#[test]
fn plan_with_observations_identifies_first() {
    let server = Server::start(&["--models-dir", MODELS]);
    let (nominal, truth) = trees();
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let exact = Noise {
        position: 1e-9,
        force: 0.05,
    };
    // Two pushes across a leaf's branch: one seen, one making the target.
    let (leaf, seen, target) = (1..nominal.len())
        .filter(|&j| nominal.is_leaf(j))
        .find_map(|leaf| {
            let d = nominal.branch_direction(leaf).unwrap();
            let u = d.cross(&nalgebra::Vector3::z()).normalize();
            let w = d.cross(&u);
            let push = |v| Push {
                node: leaf,
                vector: v,
            };
            let seen = observe(
                &truth,
                push(u * 0.08),
                ContactModel::Slot,
                &Noise::default(),
                false,
                &mut rng,
            )?;
            let target = observe(
                &truth,
                push(w * 0.06),
                ContactModel::Slot,
                &exact,
                false,
                &mut rng,
            )?;
            Some((leaf, seen, target))
        })
        .unwrap();
    let targets: Vec<[f64; 3]> = target
        .observed
        .iter()
        .map(|o| {
            let o = o.unwrap();
            [o.x, o.y, o.z]
        })
        .collect();
    let body = json!({
        "tree": prior_tree(&nominal),
        "target_positions": targets,
        "strategy": "physics",
        "observations": [probe_json(&seen)],
    });
    let (status, answer) = server.json("POST", "/v1/plan", &body);
    assert_eq!(status, 200, "{answer}");
    let id = &answer["identification"];
    assert_eq!(id["scale"], "relative");
    assert!(id["status"][leaf] != "unobserved");
    // Without observations there is no identification.
    let mut plain = body.clone();
    plain.as_object_mut().unwrap().remove("observations");
    let (status, answer) = server.json("POST", "/v1/plan", &plain);
    assert_eq!(status, 200);
    assert!(answer.get("identification").is_none());
    // A bad observation is named with its field.
    let mut bad = body.clone();
    bad["observations"][0]["contact_node"] = json!(99);
    let (status, e) = server.json("POST", "/v1/plan", &bad);
    assert_eq!(status, 422, "{e}");
    assert_eq!(
        e["error"]["details"]["field"],
        "observations[0].contact_node"
    );
}

/// A global factor on every K_s is physics-invariant: the served forward
/// model neither refuses it nor moves its prediction.
#[test]
fn a_global_stiffness_factor_is_neither_refused_nor_seen() {
    let server = Server::start(&["--models-dir", MODELS]);
    let (nominal, _) = trees();
    let mut answers = Vec::new();
    for factor in [1.0, 1000.0, 1e-3] {
        let mut tree = tree_value(&nominal);
        let k: Vec<Value> = nominal
            .branches()
            .iter()
            .map(|b| b.map_or(Value::Null, |b| json!(b.stiffness * factor)))
            .collect();
        tree["stiffness"] = json!(k);
        let body = json!({"tree": tree, "contact_node": 5, "push": [0.0, 0.06, 0.0]});
        let (status, answer) = server.json("POST", "/v1/forward", &body);
        assert_eq!(status, 200, "factor {factor}: {answer}");
        answers.push(answer["displacements"].clone());
    }
    fn flat(v: &Value, out: &mut Vec<f64>) {
        match v {
            Value::Array(items) => items.iter().for_each(|i| flat(i, out)),
            Value::Number(x) => out.push(x.as_f64().unwrap()),
            _ => {}
        }
    }
    let values = |v: &Value| {
        let mut out = Vec::new();
        flat(v, &mut out);
        out
    };
    let first = values(&answers[0]);
    assert!(first.len() >= 3 * nominal.len());
    for other in &answers[1..] {
        let other = values(other);
        assert_eq!(first.len(), other.len());
        for (p, q) in first.iter().zip(&other) {
            assert!((p - q).abs() < 1e-6, "{p} vs {q}");
        }
    }
}

/// With `robot`, only pushes the arm can make are proposed: each passes
/// the planner's reach test from that base, and an arm standing 3 m away
/// gets none.
#[test]
fn probes_respect_the_arms_reach() {
    use treemanip_core::planner::{Planner, Stance};
    let server = Server::start(&[
        "--models-dir",
        crate::common::temp_dir("id-reach").to_str().unwrap(),
    ]);
    let (nominal, _) = trees();
    let ask = |robot: Value| {
        let (status, answer) = server.json(
            "POST",
            "/v1/identify/probes",
            &json!({ "tree": prior_tree(&nominal), "count": 4, "robot": robot }),
        );
        assert_eq!(status, 200, "{answer}");
        answer["probes"].as_array().unwrap().clone()
    };
    let near = ask(json!({ "base": [-0.5, 0.0, 0.1] }));
    assert!(!near.is_empty());
    let planner = Planner::default();
    let stance = Stance::Fixed(nalgebra::Isometry3::translation(-0.5, 0.0, 0.1));
    let reachable = planner.reach_test(&nominal, &[], &stance, None);
    for p in &near {
        let v = &p["push"];
        let push = Push {
            node: p["contact_node"].as_u64().unwrap() as usize,
            vector: nalgebra::Vector3::new(
                v[0].as_f64().unwrap(),
                v[1].as_f64().unwrap(),
                v[2].as_f64().unwrap(),
            ),
        };
        assert!(reachable(&push), "{p}");
    }
    assert!(ask(json!({ "base": [3.0, 3.0, 0.1] })).is_empty());
    let (status, e) = server.json(
        "POST",
        "/v1/identify/probes",
        &json!({ "tree": prior_tree(&nominal), "robot": { "base": [0.0, 0.0, 99.0] } }),
    );
    assert_eq!(
        (status, e["error"]["details"]["field"].as_str()),
        (422, Some("robot.base"))
    );
}
