//! Entry points of the fuzz targets (`fuzz/`, cargo fuzz with libFuzzer),
//! also replayed over the committed seed corpora by the test suite. Each
//! takes arbitrary bytes and must return, without panicking, in bounded time
//! and memory, whatever the bytes are: that is the property fuzzed.

use std::sync::{Arc, OnceLock};
use std::time::Duration;

use crate::api::types::TreeJson;
use crate::api::{AppState, Limits, router};
use treemanip_core::dataset::Split;
use treemanip_infer::models::ModelSet;

/// Tree JSON → validated tree.
pub fn tree_json(data: &[u8]) {
    if let Ok(json) = serde_json::from_slice::<TreeJson>(data) {
        let _ = json.to_tree(treemanip_core::tree::MAX_NODES);
    }
}

/// URDF text → tree.
pub fn urdf(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = treemanip_core::tree::urdf::from_urdf_str(text);
    }
}

/// PLY bytes → point cloud (at most 100,000 points) → a tree, when the
/// cloud holds one.
pub fn ply(data: &[u8]) {
    if let Ok(cloud) = treemanip_core::scan::io::ply::read(data, 100_000) {
        let _ = treemanip_core::scan::extract(&cloud, &Default::default());
    }
}

/// `.npz` dataset file → validated episodes.
pub fn npz(data: &[u8]) {
    let _ = treemanip_core::dataset::npz::read_size(
        std::io::Cursor::new(data),
        "fuzz input",
        Split::Train,
    );
}

/// The routes a request body is sent to: the first input byte picks one.
pub const ROUTES: [&str; 6] = [
    "/v1/forward",
    "/v1/policy",
    "/v1/plan",
    "/v1/simulate",
    "/v1/trees/urdf",
    "/v1/robot/link-poses",
];

/// A request body through the whole router (validation, limits, models on
/// the embedded backend, the planner with its budget capped at 100 ms). The
/// first byte picks the route; the answer must be a response, never a
/// panic, and never a 5xx.
pub fn request(data: &[u8]) {
    let Some((&selector, body)) = data.split_first() else {
        return;
    };
    let route = ROUTES[selector as usize % ROUTES.len()];
    let (runtime, app) = harness();
    let request = axum::http::Request::post(route)
        .header("content-type", "application/json")
        .body(axum::body::Body::from(body.to_vec()))
        .expect("a valid request");
    let response = runtime
        .block_on(tower::ServiceExt::oneshot(app.clone(), request))
        .expect("the router is infallible");
    assert!(
        !response.status().is_server_error(),
        "{route} answered {} to {:?}",
        response.status(),
        String::from_utf8_lossy(body)
    );
}

/// Loads the models and builds the router once, before fuzzing starts
/// (loading takes seconds under the sanitizers, which is not a request's
/// time).
pub fn init_request_harness() {
    harness();
}

fn harness() -> &'static (tokio::runtime::Runtime, axum::Router) {
    static HARNESS: OnceLock<(tokio::runtime::Runtime, axum::Router)> = OnceLock::new();
    HARNESS.get_or_init(|| {
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .enable_all()
            .build()
            .expect("a runtime");
        let models = ModelSet::load_dir(
            std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../models")),
            None,
            1,
            false,
        )
        .expect("the committed models load");
        let limits = Limits {
            max_plan_budget: Duration::from_millis(100),
            max_plan_evaluations: 64,
            max_in_flight: 64,
            ..Limits::default()
        };
        let app = router(AppState::new(limits).with_models(Arc::new(models)));
        (runtime, app)
    })
}
