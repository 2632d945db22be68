//! Faults: broken model files at start-up, a bug in one request, SIGTERM
//! under load.

use std::path::Path;
use std::process::Command;

use serde_json::json;

use crate::common::server::Server;
use crate::common::temp_dir;

const MODELS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/models");

/// A copy of the committed models with `forward_gnn.onnx` spoilt by `spoil`.
fn models_with_broken_forward(tag: &str, spoil: impl Fn(&[u8]) -> Vec<u8>) -> std::path::PathBuf {
    let dir = temp_dir(tag);
    for name in ["forward_gnn.onnx", "policy_gnn.onnx"] {
        let bytes = std::fs::read(Path::new(MODELS).join(name)).unwrap();
        let bytes = if name == "forward_gnn.onnx" {
            spoil(&bytes)
        } else {
            bytes
        };
        std::fs::write(dir.join(name), bytes).unwrap();
    }
    dir
}

fn truncated(bytes: &[u8]) -> Vec<u8> {
    bytes[..bytes.len() / 3].to_vec()
}

fn other_layout(bytes: &[u8]) -> Vec<u8> {
    treemanip::nn::onnx::with_metadata(
        bytes,
        &[("feature_layout_version".to_owned(), "999".to_owned())],
    )
    .unwrap()
}

/// The model with every float weight NaN (it still loads: only what it
/// computes is wrong).
fn nan_weights(bytes: &[u8]) -> Vec<u8> {
    use prost::Message;
    let mut model = tract_onnx::pb::ModelProto::decode(bytes).unwrap();
    let graph = model.graph.as_mut().unwrap();
    for init in graph.initializer.iter_mut().filter(|t| t.data_type == 1) {
        if init.float_data.is_empty() {
            init.raw_data = f32::NAN.to_le_bytes().repeat(init.raw_data.len() / 4);
        } else {
            init.float_data.iter_mut().for_each(|x| *x = f32::NAN);
        }
    }
    model.encode_to_vec()
}

#[test]
fn a_broken_model_file_stops_start_up_naming_it() {
    for (tag, spoil, says) in [
        ("truncated-model", truncated as fn(&[u8]) -> Vec<u8>, ""),
        ("layout-model", other_layout, "feature layout version"),
        ("nan-model", nan_weights, "canary"),
    ] {
        let dir = models_with_broken_forward(tag, spoil);
        let out = Command::new(crate::common::server::server_exe())
            .args(["--bind", "127.0.0.1:0", "--models-dir"])
            .arg(&dir)
            .output()
            .unwrap();
        assert!(!out.status.success(), "{tag}: started");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains("forward_gnn.onnx"), "{tag}: {stderr}");
        assert!(stderr.contains(says), "{tag}: {stderr}");
        assert!(stderr.contains("--skip-broken-models"), "{tag}: {stderr}");
    }
}

#[test]
fn skip_broken_models_serves_the_others_and_reports_the_broken_one() {
    let dir = models_with_broken_forward("skip-broken", truncated);
    let server = Server::start(&[
        "--models-dir",
        dir.to_str().unwrap(),
        "--skip-broken-models",
    ]);
    let (status, ready) = server.get("/readyz");
    assert_eq!(status, 503, "{ready}");
    assert_eq!(ready["error"]["details"]["missing"], json!(["forward_gnn"]));
    assert!(
        ready["error"]["details"]["broken"]["forward_gnn"]
            .as_str()
            .unwrap()
            .contains("forward_gnn.onnx"),
        "{ready}"
    );
    // The policy still answers; the forward model says it is not there.
    let tree = json!({
        "positions": [[0, 0, 0], [0, 0, 0.4], [0.02, 0, 0.8], [0.25, 0.05, 0.55]],
        "parents": [null, 0, 1, 1],
        "radius": [null, 0.015, 0.008, 0.006],
    });
    let target = json!([
        [0, 0, 0],
        [0, 0.004, 0.4],
        [0.02, 0.01, 0.8],
        [0.25, 0.12, 0.55]
    ]);
    let (status, answer) = server.json(
        "POST",
        "/v1/policy",
        &json!({"tree": tree, "target_positions": target}),
    );
    assert_eq!(status, 200, "{answer}");
    let (status, answer) = server.json(
        "POST",
        "/v1/forward",
        &json!({"tree": tree, "contact_node": 3, "push": [0, 0.08, 0]}),
    );
    assert_eq!(
        (status, answer["error"]["code"].as_str()),
        (503, Some("not_ready"))
    );
}

#[test]
fn a_panicking_request_gets_a_json_500_and_the_server_keeps_serving() {
    let server = Server::start(&["--models-dir", MODELS, "--fault-injection"]);
    for path in ["/debug/panic", "/debug/panic-worker"] {
        let (status, answer) = server.json("POST", path, &json!({}));
        assert_eq!(
            (status, answer["error"]["code"].as_str()),
            (500, Some("internal")),
            "{path}: {answer}"
        );
        let (status, _) = server.get("/readyz");
        assert_eq!(status, 200, "after {path}");
    }
    // The admission permit of the panicked worker was given back.
    for _ in 0..20 {
        let (status, _) = server.json("POST", "/debug/panic-worker", &json!({}));
        assert_eq!(status, 500);
    }
    let (_, _, metrics) = server.request("GET", "/metrics", "text/plain", b"");
    assert!(metrics.contains("treemanip_panics_total 1"), "{metrics}");
}

#[test]
fn sigterm_under_load_finishes_admitted_requests_and_refuses_new_ones() {
    let mut server = Server::start(&["--models-dir", MODELS]);
    let tree = serde_json::to_value(treemanip::api::types::TreeJson::from_tree(
        &treemanip::tree::generate(30, 2, &treemanip::tree::ScaParams::default()).unwrap(),
    ))
    .unwrap();
    // The most work one request may ask for (256 actions at N = 30): about
    // 0.8 s on an idle 2-core AVX-512 machine, so both are still running
    // when the signal comes as soon as both were admitted.
    let heavy = json!({
        "tree": tree,
        "contact_nodes": (0..256).map(|k| 1 + k % 29).collect::<Vec<_>>(),
        "pushes": (0..256).map(|k| [0.05, 0.0002 * k as f64, 0.0]).collect::<Vec<_>>(),
        "allow_out_of_domain": true,
    });
    std::thread::scope(|scope| {
        let admitted: Vec<_> = (0..2)
            .map(|_| scope.spawn(|| server.json("POST", "/v1/forward", &heavy)))
            .collect();
        // Both are admitted (validated, their work queued or running)
        // before the signal: counted by the server, not assumed after a
        // fixed wait, which a loaded machine outruns (the requests were
        // then still being read when the server exited).
        let admitted_so_far = || {
            let (_, _, metrics) = server.request("GET", "/metrics", "text/plain", b"");
            metrics
                .lines()
                .filter(|l| l.starts_with("treemanip_actions_per_request_count"))
                .filter_map(|l| l.rsplit(' ').next()?.parse::<f64>().ok())
                .sum::<f64>()
        };
        let waiting = std::time::Instant::now();
        while admitted_so_far() < 2.0 {
            assert!(
                waiting.elapsed() < std::time::Duration::from_secs(30),
                "the two requests were never admitted"
            );
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        server.terminate();
        std::thread::sleep(std::time::Duration::from_millis(100));
        // While draining: new requests are refused with 503, not dropped.
        let (status, answer) = server.get("/readyz");
        assert_eq!(
            (status, answer["error"]["code"].as_str()),
            (503, Some("not_ready")),
            "{answer}"
        );
        assert!(
            answer["error"]["message"]
                .as_str()
                .unwrap()
                .contains("shutting down")
        );
        // ...and say `Connection: close`, so that a load balancer stops
        // reusing the connection before the server closes it.
        let (status, head, _) = server.request("GET", "/v1/models", "", b"");
        assert_eq!(status, 503);
        assert!(head.contains("connection: close"), "{head}");
        for handle in admitted {
            let (status, answer) = handle.join().unwrap();
            assert_eq!(status, 200, "an admitted request was lost: {answer}");
            assert_eq!(answer["displacements"].as_array().unwrap().len(), 256);
        }
    });
    server.wait_for_clean_exit("server did not exit after draining");
}
