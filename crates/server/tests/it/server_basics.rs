//! `treemanip-server` as a process: it binds, answers the process endpoints
//! with the documented JSON shapes, and exits cleanly on SIGTERM.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

use crate::common::server::Server;
use serde_json::{Value, json};

/// Without models: only the simulator answers.
fn start() -> Server {
    let empty = crate::common::temp_dir("no-models");
    Server::start(&["--models-dir", empty.to_str().unwrap()])
}

#[test]
fn process_endpoints_and_error_shape() {
    let server = start();
    let (status, body) = server.get("/healthz");
    assert_eq!(status, 200);
    assert_eq!(body["status"], "ok");

    let (status, body) = server.get("/readyz");
    assert_eq!(status, 503, "this server has no models");
    assert_eq!(body["error"]["code"], "not_ready");
    assert_eq!(
        body["error"]["details"]["missing"],
        json!(["forward_gnn", "policy_gnn"])
    );
    let (status, body) = server.json("POST", "/v1/forward", &simulate_body(tree_json()));
    assert_eq!(
        (status, body["error"]["code"].as_str()),
        (503, Some("not_ready"))
    );

    let (status, body) = server.get("/no/such/route");
    assert_eq!(status, 404);
    assert_eq!(body["error"]["code"], "not_found");
    assert!(
        body["error"]["message"]
            .as_str()
            .unwrap()
            .contains("/no/such/route")
    );
}

#[test]
fn sigterm_shuts_down_cleanly() {
    let mut server = start();
    assert_eq!(server.get("/healthz").0, 200);
    server.terminate();
    server.wait_for_clean_exit("server ignored SIGTERM");
}

/// A 4-node tree: trunk 0 → 1 → 2 and a side branch 1 → 3.
fn tree_json() -> Value {
    json!({
        "positions": [[0.0, 0.0, 0.0], [0.0, 0.0, 0.4], [0.02, 0.0, 0.8], [0.25, 0.05, 0.55]],
        "parents": [null, 0, 1, 1],
        "radius": [null, 0.015, 0.008, 0.006]
    })
}

fn simulate_body(tree: Value) -> Value {
    json!({ "tree": tree, "contact_node": 3, "push": [0.0, 0.03, 0.0] })
}

#[test]
fn simulate_answers_with_the_simulators_ground_truth() {
    let server = start();
    let (status, body) = server.json("POST", "/v1/simulate", &simulate_body(tree_json()));
    assert_eq!(status, 200, "{body}");
    let finals = body["final_positions"].as_array().unwrap();
    assert_eq!(finals.len(), 4);
    assert_eq!(finals[0], json!([0.0, 0.0, 0.0]), "the root stays");
    assert!(body["solver"]["kkt_residual"].as_f64().unwrap() < 1e-8);
    assert_eq!(body["contact"], "slot");
    // The same push through the library gives the same numbers.
    let tree = serde_json::from_value::<treemanip_server::api::types::TreeJson>(tree_json())
        .unwrap()
        .to_tree(64)
        .unwrap();
    let out = treemanip_core::sim::simulate(
        &tree,
        &treemanip_core::sim::Push {
            node: 3,
            vector: nalgebra::Vector3::new(0.0, 0.03, 0.0),
        },
        &treemanip_core::sim::SimConfig::default(),
    )
    .unwrap();
    for (j, p) in out.final_positions.iter().enumerate() {
        for k in 0..3 {
            assert_eq!(finals[j][k].as_f64().unwrap(), p[k]);
        }
        let d = body["displacements"][j][0].as_f64().unwrap();
        assert_eq!(d, p.x - tree.position(j).x);
    }
    // Branch loads: the library's, null at the root; the path 0 → 1 → 3
    // bends, branch 2 (off the path) carries nothing; the default stiffness
    // implies 5 GPa.
    let loads = treemanip_core::sim::loads::branch_loads(&tree, &out.joint_rotations);
    assert_eq!(body["branch_moment"][0], Value::Null);
    assert_eq!(body["branch_stress"][0], Value::Null);
    for j in 1..4 {
        assert_eq!(body["branch_moment"][j].as_f64(), loads.bending_moment[j]);
        assert_eq!(body["branch_stress"][j].as_f64(), loads.bending_stress[j]);
        let e = body["wood_modulus"][j].as_f64().unwrap();
        assert!((e - 5e9).abs() < 1e-3 * 5e9, "{e}");
    }
    assert_eq!(body["branch_moment"][2], json!(0.0));
    assert!(body["branch_moment"][3].as_f64().unwrap() > 0.0);
    let peak = &body["peak_stress"];
    assert_eq!(
        peak["node"].as_u64(),
        loads.peak_stress.map(|p| p.node as u64)
    );
    assert_eq!(body["contact_force"], body["solver"]["contact_force"]);
    // Pinned contact on request.
    let mut pinned = simulate_body(tree_json());
    pinned["contact"] = json!("pinned");
    let (status, body) = server.json("POST", "/v1/simulate", &pinned);
    assert_eq!(status, 200, "{body}");
    assert_eq!(body["solver"]["hold"], "at_node");
    // Pushed back along its branch past the base, the slot catches on the
    // fork at node 2 and carries it to the gripper's point.
    let chain = json!({
        "positions": [[0.0, 0.0, 0.0], [0.0, 0.0, 0.4], [0.0, 0.0, 0.8], [0.0, 0.0, 1.2]],
        "parents": [null, 0, 1, 2],
        "radius": [null, 0.02, 0.012, 0.006]
    });
    let back = json!({ "tree": chain, "contact_node": 3, "push": [0.02, 0.0, -0.42] });
    let (status, body) = server.json("POST", "/v1/simulate", &back);
    assert_eq!(status, 200, "{body}");
    assert_eq!(body["solver"]["hold"], "at_base");
    for (k, g) in [0.02, 0.0, 1.19 - 0.42].iter().enumerate() {
        let at = body["final_positions"][2][k].as_f64().unwrap();
        assert!((at - g).abs() < 1e-9, "{body}");
    }
}

fn expect_error(server: &Server, body: &Value, status: u16, code: &str) -> Value {
    let (got, answer) = server.json("POST", "/v1/simulate", body);
    assert_eq!(got, status, "{answer}");
    assert_eq!(answer["error"]["code"], code, "{answer}");
    assert!(!answer["error"]["message"].as_str().unwrap().is_empty());
    answer["error"].clone()
}

#[test]
fn every_error_class_has_its_status_and_shape() {
    let server = start();
    // 400: not JSON, NaN, wrong shape, unknown field.
    let (status, body) = server.send("POST", "/v1/simulate", "application/json", b"{\"tree\": ");
    assert_eq!(
        (status, body["error"]["code"].as_str()),
        (400, Some("malformed_json"))
    );
    let nan = br#"{"tree": {"positions": [[0,0,NaN]], "parents": [null], "radius": [null]}, "contact_node": 1, "push": [0,0,0]}"#;
    let (status, body) = server.send("POST", "/v1/simulate", "application/json", nan);
    assert_eq!(status, 400);
    assert!(
        body["error"]["message"].as_str().unwrap().contains("NaN"),
        "{body}"
    );
    let mut wrong = simulate_body(tree_json());
    wrong["contact_node"] = json!("three");
    expect_error(&server, &wrong, 400, "malformed_json");
    let mut extra = simulate_body(tree_json());
    extra["tree"]["colour"] = json!("green");
    let error = expect_error(&server, &extra, 400, "malformed_json");
    assert!(
        error["message"].as_str().unwrap().contains("colour"),
        "{error}"
    );
    // 415: not JSON. Answered before the body is read, so the answer says
    // the connection ends (hyper closes it): a pooled client reconnects
    // instead of sending its next request into a closed socket.
    let (status, head, body) = server.request("POST", "/v1/simulate", "text/plain", b"{}");
    assert_eq!(status, 415, "{body}");
    assert!(body.contains("unsupported_media_type"), "{body}");
    assert!(head.contains("connection: close"), "{head}");
    let (status, head, _) = server.request(
        "POST",
        "/v1/simulate",
        "application/json",
        &serde_json::to_vec(&simulate_body(tree_json())).unwrap(),
    );
    assert_eq!(status, 200);
    assert!(
        !head.contains("connection: close"),
        "a good answer keeps it: {head}"
    );
    // 413: a body over 1 MiB, a tree over 512 nodes.
    let (status, _, body) = server.raw(
        "POST",
        "/v1/simulate",
        "application/json",
        &vec![b' '; 2 << 20],
    );
    let body: serde_json::Value = serde_json::from_str(&body).unwrap();
    assert_eq!(
        (status, body["error"]["code"].as_str()),
        (413, Some("too_large")),
        "{body}"
    );
    let big = json!({
        "positions": (0..513).map(|k| [0.0, 0.0, k as f64 * 0.1]).collect::<Vec<_>>(),
        "parents": (0..513).map(|k: usize| k.checked_sub(1)).collect::<Vec<_>>(),
        "radius": (0..513).map(|k| if k == 0 { None } else { Some(0.01) }).collect::<Vec<_>>(),
    });
    let error = expect_error(&server, &simulate_body(big), 413, "too_large");
    assert_eq!(error["details"]["max_nodes"], 512);
    // 422: a guard that is no force.
    for bad in [json!(0.0), json!(-3.0)] {
        let mut guarded = simulate_body(tree_json());
        guarded["stop_at_contact_force"] = bad;
        let error = expect_error(&server, &guarded, 422, "invalid_argument");
        assert_eq!(
            error["details"]["field"], "stop_at_contact_force",
            "{error}"
        );
    }
    // 422: invalid trees, each naming field and node.
    let mut cycle = tree_json();
    cycle["parents"] = json!([null, 2, 1, 1]);
    let error = expect_error(&server, &simulate_body(cycle), 422, "invalid_tree");
    assert_eq!(error["details"]["field"], "parents");
    assert!(error["message"].as_str().unwrap().contains("cycle"));
    let mut two_roots = tree_json();
    two_roots["parents"] = json!([null, 0, null, 1]);
    let error = expect_error(&server, &simulate_body(two_roots), 422, "invalid_tree");
    assert_eq!(error["details"]["nodes"], json!([0, 2]));
    let mut out_of_range = tree_json();
    out_of_range["parents"] = json!([null, 0, 7, 1]);
    let error = expect_error(&server, &simulate_body(out_of_range), 422, "invalid_tree");
    assert_eq!(error["details"]["node"], 2);
    let mut short = tree_json();
    short["radius"] = json!([null, 0.01, 0.01]);
    let error = expect_error(&server, &simulate_body(short), 422, "invalid_tree");
    assert_eq!(error["details"]["field"], "radius");
    let mut negative = tree_json();
    negative["radius"][2] = json!(-0.01);
    let error = expect_error(&server, &simulate_body(negative), 422, "invalid_tree");
    assert_eq!(
        (
            error["details"]["field"].as_str(),
            error["details"]["node"].as_u64()
        ),
        (Some("radius"), Some(2))
    );
    let mut two_d = tree_json();
    two_d["positions"][1] = json!([0.0, 0.4]);
    let error = expect_error(&server, &simulate_body(two_d), 422, "invalid_tree");
    assert_eq!(error["details"]["node"], 1);
    let mut huge = tree_json();
    huge["positions"][3] = json!([1e308, 1e308, 1e308]);
    let error = expect_error(&server, &simulate_body(huge), 422, "invalid_tree");
    assert_eq!(error["details"]["node"], 3, "{error}");
    // 422: bad arguments, and pushes the physics rejects.
    let mut root = simulate_body(tree_json());
    root["contact_node"] = json!(0);
    let error = expect_error(&server, &root, 422, "invalid_argument");
    assert_eq!(error["details"]["field"], "contact_node");
    let mut two = simulate_body(tree_json());
    two["push"] = json!([0.0, 0.1]);
    expect_error(&server, &two, 422, "invalid_argument");
    let mut far = simulate_body(tree_json());
    far["push"] = json!([0.0, 0.2, 0.0]);
    let error = expect_error(&server, &far, 422, "push_infeasible");
    assert_eq!(error["details"]["kind"], "lost_branch");
    // 405 and 404.
    let (status, body) = server.get("/v1/simulate");
    assert_eq!(
        (status, body["error"]["code"].as_str()),
        (405, Some("method_not_allowed"))
    );
    // The process survived all of it.
    assert_eq!(server.get("/healthz").0, 200);
}

#[test]
fn metrics_count_requests_and_the_spec_is_served() {
    let server = start();
    let count = |text: &str| -> f64 {
        text.lines()
            .filter(|l| {
                l.starts_with("treemanip_http_requests_total")
                    && l.contains("route=\"/v1/simulate\"")
                    && l.contains("status=\"200\"")
            })
            .filter_map(|l| l.rsplit(' ').next()?.parse::<f64>().ok())
            .sum()
    };
    let metrics = || server.request("GET", "/metrics", "text/plain", b"").2;
    let before = count(&metrics());
    for _ in 0..3 {
        assert_eq!(
            server
                .json("POST", "/v1/simulate", &simulate_body(tree_json()))
                .0,
            200
        );
    }
    let after = metrics();
    assert_eq!(count(&after) - before, 3.0, "{after}");
    assert!(after.contains("treemanip_http_request_duration_seconds_bucket"));
    assert!(after.contains("treemanip_compute_seconds"));
    let (status, head, spec) = server.request("GET", "/openapi.yaml", "text/plain", b"");
    assert_eq!(status, 200);
    assert!(head.contains("application/yaml"));
    assert!(spec.starts_with("openapi: 3.1.0"));
    assert!(spec.contains("/v1/simulate:"));
}

#[test]
fn sigterm_lets_an_in_flight_request_finish() {
    let mut server = start();
    let body = serde_json::to_vec(&simulate_body(tree_json())).unwrap();
    let (first, rest) = body.split_at(body.len() / 2);
    let mut stream = TcpStream::connect(&server.addr).unwrap();
    stream
        .set_read_timeout(Some(Duration::from_secs(30)))
        .unwrap();
    write!(
        stream,
        "POST /v1/simulate HTTP/1.1\r\nHost: test\r\nConnection: close\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n",
        body.len()
    )
    .unwrap();
    stream.write_all(first).unwrap();
    stream.flush().unwrap();
    std::thread::sleep(Duration::from_millis(200));
    // The request is half received when the signal arrives.
    server.terminate();
    std::thread::sleep(Duration::from_millis(200));
    assert!(
        server.child.try_wait().unwrap().is_none(),
        "the server quit with a request in flight"
    );
    stream.write_all(rest).unwrap();
    let mut response = String::new();
    stream.read_to_string(&mut response).unwrap();
    assert!(response.starts_with("HTTP/1.1 200"), "{response}");
    assert!(response.contains("final_positions"));
    // Then it exits cleanly, and takes no new connections.
    server.wait_for_clean_exit("server did not exit after the request");
    assert!(TcpStream::connect(&server.addr).is_err());
}

/// Every request gets an id (a client's own `x-request-id` is kept), which
/// the answer echoes and the JSON log names, with one access line per answer.
#[test]
fn request_ids_are_echoed_and_logged() {
    use std::io::BufRead;
    let mut child = std::process::Command::new(crate::common::server::server_exe())
        .current_dir(crate::common::server::workspace_root())
        .args([
            "--bind",
            "127.0.0.1:0",
            "--log-format",
            "json",
            "--models-dir",
        ])
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/../../models"))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    std::io::BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let addr = line
        .trim()
        .strip_prefix("listening on http://")
        .unwrap()
        .to_owned();
    let mut stream = TcpStream::connect(&addr).unwrap();
    write!(
        stream,
        "GET /healthz HTTP/1.1\r\nHost: x\r\nx-request-id: client-id-4711\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut answer = String::new();
    stream.read_to_string(&mut answer).unwrap();
    assert!(
        answer
            .to_lowercase()
            .contains("x-request-id: client-id-4711"),
        "{answer}"
    );
    // An id is made up when the client sends none.
    let mut stream = TcpStream::connect(&addr).unwrap();
    write!(
        stream,
        "GET /healthz HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut answer = String::new();
    stream.read_to_string(&mut answer).unwrap();
    assert!(answer.to_lowercase().contains("x-request-id: "), "{answer}");
    let _ = child.kill();
    let mut logs = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut logs)
        .unwrap();
    let _ = child.wait();
    let access = logs
        .lines()
        .find(|l| l.contains("client-id-4711") && l.contains("answered"))
        .unwrap_or_else(|| panic!("no access line with the request id in:\n{logs}"));
    let entry: Value = serde_json::from_str(access).unwrap();
    assert_eq!(entry["level"], "INFO");
    assert_eq!(entry["fields"]["status"], 200);
}
