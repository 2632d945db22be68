//! The Open Inference Protocol v2 endpoints, through the unmodified
//! `tritonclient[http]` from PyPI: liveness, readiness, model metadata with
//! the real tensor names and shapes, and an inference whose output equals
//! `/v1/forward`'s for the same tree and push. The input tensors are written
//! by this project's encoder (as .npy files the Python client sends), so
//! the encoding exists once.

use std::process::Command;

use nalgebra::Vector3;
use ndarray::{Array2, Array3, Array4};
use serde_json::{Value, json};
use treemanip_core::graph::{EDGE_DIM, batch, encode_forward};
use treemanip_core::tree::{ScaParams, generate};
use treemanip_server::api::types::TreeJson;

use crate::common::server::Server;
use crate::common::temp_dir;

const MODELS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../models");

const CLIENT: &str = r#"
import json, sys
import numpy as np
import tritonclient.http as http

url, folder = sys.argv[1], sys.argv[2]
client = http.InferenceServerClient(url=url)
out = {
    "live": client.is_server_live(),
    "ready": client.is_server_ready(),
    "model_ready": client.is_model_ready("forward_gnn"),
    "server": client.get_server_metadata(),
    "forward": client.get_model_metadata("forward_gnn"),
    "policy": client.get_model_metadata("policy_gnn"),
}
inputs = []
for k, name in enumerate(["nodes", "edges", "global", "mask"]):
    value = np.load(f"{folder}/{name}.npy").astype(np.float32)
    tensor = http.InferInput(name, list(value.shape), "FP32")
    # Half the tensors as JSON, half with the binary extension.
    tensor.set_data_from_numpy(value, binary_data=(k % 2 == 0))
    inputs.append(tensor)
result = client.infer("forward_gnn", inputs, outputs=[http.InferRequestedOutput("displacement", binary_data=False)])
out["displacement"] = result.as_numpy("displacement").tolist()
print(json.dumps(out))
"#;

#[test]
fn tritonclient_sees_the_models_and_gets_the_same_answers() {
    let available = Command::new("python3")
        .args(["-c", "import tritonclient.http"])
        .output();
    if !available.as_ref().is_ok_and(|o| o.status.success()) {
        assert!(
            std::env::var_os("TREEMANIP_REQUIRE_PYTHON").is_none(),
            "tritonclient[http] is required here"
        );
        println!("skipped: tritonclient not installed (pip install -r requirements-dev.txt)");
        return;
    }
    let server = Server::start(&["--models-dir", MODELS]);
    let tree = generate(15, 4, &ScaParams::default()).unwrap();
    let push = Vector3::new(0.05, 0.02, 0.0);
    let graph = encode_forward(&tree, 5, &push).unwrap();
    let b = batch(&[graph]).unwrap();
    let n = b.n;
    let dir = temp_dir("oip");
    let write = |name: &str, shape: &[usize], values: &[f32]| match shape.len() {
        2 => ndarray_npy::write_npy(
            dir.join(format!("{name}.npy")),
            &Array2::from_shape_vec((shape[0], shape[1]), values.to_vec()).unwrap(),
        )
        .unwrap(),
        3 => ndarray_npy::write_npy(
            dir.join(format!("{name}.npy")),
            &Array3::from_shape_vec((shape[0], shape[1], shape[2]), values.to_vec()).unwrap(),
        )
        .unwrap(),
        _ => ndarray_npy::write_npy(
            dir.join(format!("{name}.npy")),
            &Array4::from_shape_vec((shape[0], shape[1], shape[2], shape[3]), values.to_vec())
                .unwrap(),
        )
        .unwrap(),
    };
    write("nodes", &[1, n, 1], &b.nodes);
    write("edges", &[1, n, n, EDGE_DIM], &b.edges);
    write("global", &[1, 3], &b.global);
    write("mask", &[1, n], &b.mask);
    let out = Command::new("python3")
        .args(["-c", CLIENT, &server.addr, dir.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let seen: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        (&seen["live"], &seen["ready"], &seen["model_ready"]),
        (&json!(true), &json!(true), &json!(true))
    );
    assert_eq!(seen["server"]["name"], "treemanip");
    let names = |m: &Value, key: &str| -> Vec<String> {
        m[key]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| t["name"].as_str().unwrap().to_owned())
            .collect()
    };
    assert_eq!(
        names(&seen["forward"], "inputs"),
        ["nodes", "edges", "global", "mask"]
    );
    assert_eq!(names(&seen["forward"], "outputs"), ["displacement"]);
    assert_eq!(names(&seen["policy"], "outputs"), ["action", "affordance"]);
    assert_eq!(
        seen["forward"]["inputs"][1]["shape"],
        json!([-1, -1, -1, 6])
    );
    // The same answer as the domain API.
    let (status, answer) = server.json(
        "POST",
        "/v1/forward",
        &json!({"tree": TreeJson::from_tree(&tree), "contact_node": 5, "push": [push.x, push.y, push.z]}),
    );
    assert_eq!(status, 200, "{answer}");
    let expected = answer["displacements"][0].as_array().unwrap();
    let got = seen["displacement"][0].as_array().unwrap();
    assert_eq!(got.len(), expected.len());
    for (g, e) in got.iter().zip(expected) {
        for c in 0..3 {
            let (g, e) = (g[c].as_f64().unwrap(), e[c].as_f64().unwrap());
            assert!((g - e).abs() < 1e-6, "{g} vs {e}");
        }
    }
}

#[test]
fn v2_errors_use_the_error_shape() {
    let server = Server::start(&["--models-dir", MODELS]);
    let (status, answer) = server.get("/v2/models/nope");
    assert_eq!(
        (status, answer["error"]["code"].as_str()),
        (404, Some("not_found"))
    );
    let body =
        json!({"inputs": [{"name": "mask", "shape": [1, 2], "datatype": "FP32", "data": [1, 1]}]});
    let (status, answer) = server.json("POST", "/v2/models/forward_gnn/infer", &body);
    assert_eq!(status, 422, "{answer}");
    assert!(
        answer["error"]["message"]
            .as_str()
            .unwrap()
            .contains("nodes"),
        "{answer}"
    );
    let body =
        json!({"inputs": [{"name": "mask", "shape": [1, 2], "datatype": "INT64", "data": [1, 1]}]});
    let (status, _) = server.json("POST", "/v2/models/forward_gnn/infer", &body);
    assert_eq!(status, 422);
}
