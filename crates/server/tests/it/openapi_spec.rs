//! openapi.yaml is the document the server derives from its wire types
//! (so a change of a type that is not carried into the committed file
//! fails here), a valid OpenAPI 3.1 document (checked by
//! openapi-spec-validator from PyPI; skipped, with the reason printed, when
//! it is not installed, except in CI), and lists every route the server
//! serves.

use std::process::Command;

/// The committed `openapi.yaml` is exactly what the types generate.
#[test]
fn the_committed_spec_is_the_generated_one() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../openapi.yaml");
    let committed = std::fs::read_to_string(path).expect("openapi.yaml");
    let generated = treemanip_server::api::openapi::yaml();
    if committed != generated {
        let line = committed
            .lines()
            .zip(generated.lines())
            .position(|(a, b)| a != b)
            .unwrap_or_else(|| committed.lines().count().min(generated.lines().count()));
        panic!(
            "openapi.yaml differs from the document the wire types generate, first at line {}:\n  committed: {:?}\n  generated: {:?}\nrefresh it with `cargo run -p treemanip-server -- --print-openapi > openapi.yaml`",
            line + 1,
            committed.lines().nth(line),
            generated.lines().nth(line)
        );
    }
}

#[test]
fn the_spec_validates() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../openapi.yaml");
    let script = format!(
        "import yaml\nfrom openapi_spec_validator import validate\nvalidate(yaml.safe_load(open({path:?})))\nprint('valid')"
    );
    match Command::new("python3").args(["-c", &script]).output() {
        Ok(out) if out.status.success() => {
            assert_eq!(String::from_utf8_lossy(&out.stdout).trim(), "valid");
        }
        Ok(out) if String::from_utf8_lossy(&out.stderr).contains("ModuleNotFoundError") => {
            assert!(
                std::env::var_os("TREEMANIP_REQUIRE_PYTHON").is_none(),
                "openapi-spec-validator is required here: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            println!(
                "skipped: openapi-spec-validator not installed (pip install -r requirements-dev.txt)"
            );
        }
        Ok(out) => panic!(
            "openapi.yaml is invalid:\n{}",
            String::from_utf8_lossy(&out.stderr)
        ),
        Err(e) => {
            assert!(
                std::env::var_os("TREEMANIP_REQUIRE_PYTHON").is_none(),
                "python3: {e}"
            );
            println!("skipped: python3 not runnable: {e}");
        }
    }
}

#[test]
fn every_served_route_is_described() {
    let spec = treemanip_server::api::openapi::yaml();
    for route in [
        "/healthz:",
        "/readyz:",
        "/metrics:",
        "/openapi.yaml:",
        "/v1/simulate:",
        "/v1/forward:",
        "/v1/policy:",
        "/v1/plan:",
        "/v1/robots:",
        "/v1/identify:",
        "/v1/identify/probes:",
        "/v1/models:",
        "/v1/trees/urdf:",
        "/v1/trees/example:",
        "/v1/robot/link-poses:",
        "/viewer:",
        "/v2:",
        "/v2/health/live:",
        "/v2/health/ready:",
        "/v2/models/{name}:",
        "/v2/models/{name}/ready:",
        "/v2/models/{name}/infer:",
    ] {
        assert!(
            spec.contains(&format!("  {route}")),
            "openapi.yaml lacks {route}"
        );
    }
    // And the error codes the server can answer with are in the schema.
    for code in [
        "malformed_json",
        "not_found",
        "method_not_allowed",
        "too_large",
        "unsupported_media_type",
        "invalid_tree",
        "invalid_argument",
        "push_infeasible",
        "out_of_domain",
        "not_ready",
        "overloaded",
        "timeout",
    ] {
        assert!(
            spec.contains(code),
            "error code {code} missing from openapi.yaml"
        );
    }
}

/// The limits a derive attribute states as a literal are the server's:
/// a tree's node cap, and the models the repository ships.
#[test]
fn literal_limits_match_the_code() {
    let doc = treemanip_server::api::openapi::document();
    let tree = &doc["components"]["schemas"]["Tree"]["properties"];
    let cap = treemanip_core::tree::MAX_NODES as u64;
    for field in ["positions", "parents", "radius", "stiffness"] {
        assert_eq!(tree[field]["maxItems"].as_u64(), Some(cap), "Tree.{field}");
    }
    assert_eq!(tree["parents"]["items"]["maximum"].as_u64(), Some(cap - 1));
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../models");
    let mut shipped: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| {
            let p = e.unwrap().path();
            (p.extension()? == "onnx")
                .then(|| p.file_stem().unwrap().to_string_lossy().into_owned())
        })
        .collect();
    shipped.sort();
    let mut listed: Vec<&str> = treemanip_server::api::types::schema::SHIPPED_MODELS.to_vec();
    listed.sort();
    assert_eq!(shipped, listed);
}
