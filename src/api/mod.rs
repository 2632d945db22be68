//! The HTTP layer: routes, request/response types, error mapping, limits
//! and metrics. It owns no computation; CPU work (simulation now; inference
//! and planning later) runs on tokio's blocking pool behind an admission
//! limit, so the async executor only moves bytes.
//!
//! Routes so far: `GET /healthz`, `GET /readyz`, `GET /metrics`,
//! `GET /openapi.yaml`, `POST /v1/simulate`. The model endpoints
//! (`/v1/forward`, `/v1/policy`, `/v1/plan`) arrive with the trained models.

pub mod error;
pub mod json;
pub mod metrics;
pub mod simulate;
pub mod tree_json;

use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::extract::{DefaultBodyLimit, State};
use axum::http::header;
use axum::response::IntoResponse;
use axum::routing::{get, post};
use serde_json::json;
use tokio::sync::Semaphore;

use error::ApiError;

/// Limits a deployment can tune (flags / environment of the server).
#[derive(Debug, Clone)]
pub struct Limits {
    /// Largest tree accepted (≤ [`crate::tree::MAX_NODES`]).
    pub max_nodes: usize,
    /// Largest request body (bytes).
    pub max_body_bytes: usize,
    /// CPU jobs admitted at once (running or queued); more get 503.
    pub max_in_flight: usize,
    /// Time budget of one request's CPU work.
    pub request_timeout: Duration,
}

impl Default for Limits {
    fn default() -> Self {
        let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
        Self {
            max_nodes: crate::tree::MAX_NODES,
            max_body_bytes: 1 << 20,
            max_in_flight: 4 * cores,
            request_timeout: Duration::from_secs(10),
        }
    }
}

/// What the handlers share.
#[derive(Clone)]
pub struct AppState {
    pub limits: Limits,
    /// Names of the models that are loaded and can answer requests.
    pub loaded_models: Vec<String>,
    admission: Arc<Semaphore>,
    metrics: metrics_exporter_prometheus::PrometheusHandle,
}

impl AppState {
    pub fn new(limits: Limits) -> Self {
        Self {
            admission: Arc::new(Semaphore::new(limits.max_in_flight)),
            limits,
            loaded_models: Vec::new(),
            metrics: metrics::recorder(),
        }
    }

    /// Runs CPU work on the blocking pool, within the admission limit and
    /// the time budget. The work itself is not cancelled by a timeout (it
    /// is bounded by the request limits); its answer is dropped.
    pub async fn run_blocking<T, F>(&self, route: &'static str, work: F) -> Result<T, ApiError>
    where
        T: Send + 'static,
        F: FnOnce() -> Result<T, ApiError> + Send + 'static,
    {
        let Ok(permit) = self.admission.clone().try_acquire_owned() else {
            ::metrics::counter!("treemanip_rejected_total", "route" => route, "reason" => "overloaded").increment(1);
            return Err(ApiError::overloaded());
        };
        let started = std::time::Instant::now();
        let job = tokio::task::spawn_blocking(move || {
            let _permit = permit;
            work()
        });
        let budget = self.limits.request_timeout;
        let result = match tokio::time::timeout(budget, job).await {
            Err(_) => Err(ApiError::timeout(budget.as_secs_f64())),
            Ok(Err(join)) => Err(ApiError::internal(format!("the worker failed: {join}"))),
            Ok(Ok(result)) => result,
        };
        ::metrics::histogram!("treemanip_compute_seconds", "route" => route)
            .record(started.elapsed().as_secs_f64());
        result
    }
}

pub fn router(state: AppState) -> Router {
    let body_limit = state.limits.max_body_bytes;
    Router::new()
        .route("/healthz", get(healthz))
        .route("/readyz", get(readyz))
        .route("/metrics", get(render_metrics))
        .route("/openapi.yaml", get(openapi))
        .route("/v1/simulate", post(simulate::simulate))
        .fallback(not_found)
        .method_not_allowed_fallback(method_not_allowed)
        .layer(axum::middleware::from_fn(metrics::track))
        .layer(DefaultBodyLimit::max(body_limit))
        .with_state(state)
}

/// The process is up and answering.
async fn healthz() -> axum::Json<serde_json::Value> {
    axum::Json(json!({ "status": "ok" }))
}

/// Ready means: every model the endpoints need is loaded.
async fn readyz(State(state): State<AppState>) -> Result<axum::Json<serde_json::Value>, ApiError> {
    if state.loaded_models.is_empty() {
        return Err(ApiError::not_ready(
            "no models are loaded: this build ships no trained models yet (POST /v1/simulate works without them)",
        ));
    }
    Ok(axum::Json(
        json!({ "status": "ready", "models": state.loaded_models }),
    ))
}

async fn render_metrics(State(state): State<AppState>) -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "text/plain; version=0.0.4")],
        state.metrics.render(),
    )
}

/// The API description, embedded at build time.
pub const OPENAPI_YAML: &str = include_str!("../../openapi.yaml");

async fn openapi() -> impl IntoResponse {
    ([(header::CONTENT_TYPE, "application/yaml")], OPENAPI_YAML)
}

async fn not_found(uri: axum::http::Uri) -> ApiError {
    ApiError::not_found(format!("no route for {}", uri.path()))
}

async fn method_not_allowed(method: axum::http::Method, uri: axum::http::Uri) -> ApiError {
    ApiError::new(
        axum::http::StatusCode::METHOD_NOT_ALLOWED,
        "method_not_allowed",
        format!("{method} is not allowed on {}", uri.path()),
    )
}
