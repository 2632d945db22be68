//! openapi.yaml is a valid OpenAPI 3.1 document (checked by
//! openapi-spec-validator from PyPI; skipped, with the reason printed, when
//! it is not installed, except in CI) and lists every route the server
//! serves.

use std::process::Command;

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
    let spec = treemanip_server::api::OPENAPI_YAML;
    for route in [
        "/healthz:",
        "/readyz:",
        "/metrics:",
        "/openapi.yaml:",
        "/v1/simulate:",
        "/v1/forward:",
        "/v1/policy:",
        "/v1/plan:",
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
