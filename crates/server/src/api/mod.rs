//! The HTTP layer: routes, request/response types, error mapping, limits
//! and metrics. It owns no computation; CPU work (inference, simulation,
//! planning) runs on tokio's blocking pool behind an admission limit, so
//! the async executor only moves bytes.
//!
//! Routes (23, and `POST /debug/panic` and `/debug/panic-worker` with fault
//! injection on; [`router`] is the list that serves them, [`openapi`]
//! derives their document from the handlers and [`types`]):
//! - service: `GET /healthz`, `GET /readyz`, `GET /metrics`,
//!   `GET /v1/models` ([`service`]), `GET /openapi.yaml` ([`openapi`]);
//! - models and physics: `POST /v1/forward`, `POST /v1/policy`,
//!   `POST /v1/simulate` ([`predict`], [`simulate`]);
//! - planning: `POST /v1/plan` ([`plan`], [`objective`]), `GET /v1/robots`
//!   ([`robots`]), `POST /v1/robot/link-poses` ([`scene`]);
//! - stiffness: `POST /v1/identify`, `POST /v1/identify/probes`
//!   ([`identify`], [`observations`]);
//! - trees: `POST /v1/trees/urdf`, `GET /v1/trees/example` ([`scene`]);
//! - the viewer: `GET /viewer`, `GET /viewer/{file}` ([`viewer`]);
//! - the KServe/Triton open inference protocol: `GET /v2`,
//!   `GET /v2/health/live`, `GET /v2/health/ready`, `GET /v2/models/{name}`,
//!   `GET /v2/models/{name}/ready`, `POST /v2/models/{name}/infer` ([`v2`]).
//!
//! Every request and response type is in [`types`], one file per endpoint
//! group. Around the handlers: [`state`] (shared state, admission, the
//! blocking pool),
//! [`error`] (the JSON error and its codes), [`json`] and [`validate`]
//! (request parsing and checks), [`metrics`], [`request_log`], [`shutdown`]
//! and [`drain`] (graceful shutdown), [`connection`] (which answers end
//! their connection), [`robot_planners`] (one planner per
//! arm), [`server`] (the binary's flags and start-up), [`health_check`]
//! (the container's health check).

pub mod connection;
pub mod domain;
pub mod drain;
pub mod error;
pub mod from_points;
pub mod health_check;
pub mod identify;
pub mod json;
pub mod metrics;
pub mod objective;
pub mod observations;
pub mod openapi;
pub mod plan;
pub mod predict;
pub mod request_log;
pub mod robot_planners;
pub mod robots;
pub mod scene;
pub mod server;
pub mod service;
pub mod shape;
pub mod shutdown;
pub mod simulate;
pub mod state;
pub mod tree_json;
pub mod types;
pub mod v2;
pub mod validate;
pub mod viewer;

use axum::Router;
use axum::body::Bytes;
use axum::extract::{DefaultBodyLimit, State};
use axum::response::IntoResponse;
use axum::routing::{get, post};

use error::{ApiError, ErrorCode};
pub use state::{AppState, Limits, ModelRef, REQUIRED_MODELS};

pub fn router(state: AppState) -> Router {
    let body_limit = state.limits.max_body_bytes;
    let cloud_limit = state.limits.max_cloud_bytes;
    let mut routes = Router::new();
    if state.limits.fault_injection {
        // For tests of what a bug does to the server: a handler that
        // panics, and one whose blocking job panics. Both read the body
        // first, as every real handler does: hyper closes a keep-alive
        // connection whose request body was left unread, and a client
        // reusing it would see the peer disconnect, not the 500.
        routes = routes.route("/debug/panic", post(injected_panic)).route(
            "/debug/panic-worker",
            post(|State(state): State<AppState>, _body: Bytes| async move {
                state
                    .run_blocking("/debug/panic-worker", || -> Result<(), ApiError> {
                        panic!("injected fault in a worker")
                    })
                    .await
            }),
        );
    }
    routes
        .route("/healthz", get(service::healthz))
        .route("/readyz", get(service::readyz))
        .route("/metrics", get(service::render_metrics))
        .route("/openapi.yaml", get(openapi::serve))
        .route("/v1/models", get(service::list_models))
        .route("/v1/forward", post(predict::forward))
        .route("/v1/policy", post(predict::policy))
        .route("/v1/plan", post(plan::plan))
        .route("/v1/simulate", post(simulate::simulate))
        .route("/v1/identify", post(identify::identify))
        .route("/v1/identify/probes", post(identify::propose))
        .route("/v1/trees/urdf", post(scene::tree_from_urdf))
        .route("/v1/trees/example", get(scene::example_tree))
        // Clouds are larger than every other body: their own limit.
        .route(
            "/v1/trees/from-points",
            post(from_points::from_points).layer(DefaultBodyLimit::max(cloud_limit)),
        )
        .route("/v1/robots", get(robots::robots))
        .route("/v1/robot/link-poses", post(scene::link_poses))
        .route("/viewer", get(viewer::index))
        .route("/viewer/{*file}", get(viewer::asset))
        .route("/v2", get(v2::server_metadata))
        .route("/v2/health/live", get(v2::live))
        .route("/v2/health/ready", get(v2::ready))
        .route("/v2/models/{name}", get(v2::model_metadata))
        .route("/v2/models/{name}/ready", get(v2::model_ready))
        .route("/v2/models/{name}/infer", post(v2::infer))
        .fallback(not_found)
        .method_not_allowed_fallback(method_not_allowed)
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            shutdown::guard,
        ))
        .layer(axum::middleware::from_fn(metrics::track))
        .layer(axum::middleware::from_fn(request_log::headers))
        // A bug in one handler is that request's 500, in the error shape;
        // the server keeps serving.
        .layer(tower_http::catch_panic::CatchPanicLayer::custom(
            panic_response,
        ))
        .layer(DefaultBodyLimit::max(body_limit))
        // After the panic layer, so that a panic's 500 says it too.
        .layer(axum::middleware::from_fn(
            connection::close_after_error_with_body,
        ))
        // Every request gets an id (a client's own `x-request-id` is kept),
        // echoed in the answer and named in its log lines.
        .layer(tower_http::request_id::PropagateRequestIdLayer::x_request_id())
        .layer(request_log::RequestSpanLayer::new())
        .layer(tower_http::request_id::SetRequestIdLayer::x_request_id(
            tower_http::request_id::MakeRequestUuid,
        ))
        .with_state(state)
}

async fn injected_panic(_body: Bytes) -> ApiError {
    panic!("injected fault")
}

fn panic_response(panic: Box<dyn std::any::Any + Send + 'static>) -> axum::response::Response {
    let what = panic
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown".to_owned());
    tracing::error!(panic = %what, "a request handler panicked");
    ::metrics::counter!("treemanip_panics_total").increment(1);
    ApiError::internal("the server hit a bug while answering this request (it keeps serving)")
        .into_response()
}

async fn not_found(uri: axum::http::Uri) -> ApiError {
    ApiError::not_found(format!("no route for {}", uri.path()))
}

async fn method_not_allowed(method: axum::http::Method, uri: axum::http::Uri) -> ApiError {
    ApiError::new(
        ErrorCode::MethodNotAllowed,
        format!("{method} is not allowed on {}", uri.path()),
    )
}
