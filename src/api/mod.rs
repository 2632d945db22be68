//! The HTTP layer: routes, request/response types, error mapping, limits
//! and metrics. It owns no computation; CPU work (inference, simulation,
//! planning) runs on tokio's blocking pool behind an admission limit, so
//! the async executor only moves bytes.
//!
//! Routes: `GET /healthz`, `GET /readyz`, `GET /metrics`, `GET /openapi.yaml`,
//! `GET /v1/models`, `POST /v1/forward`, `POST /v1/policy`, `POST /v1/plan`,
//! `POST /v1/simulate`, `POST /v1/trees/urdf`, `GET /v1/trees/example`,
//! `POST /v1/robot/link-poses`, and the viewer page `GET /viewer`.
//! Described in `openapi.yaml`.

pub mod domain;
pub mod error;
pub mod json;
pub mod metrics;
pub mod plan;
pub mod predict;
pub mod probe;
pub mod scene;
pub mod server;
pub mod shutdown;
pub mod simulate;
pub mod timing;
pub mod tree_json;
pub mod v2;
pub mod viewer;

use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::extract::{DefaultBodyLimit, State};
use axum::http::header;
use axum::response::IntoResponse;
use axum::routing::{get, post};
use serde_json::json;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use tokio::sync::Semaphore;

use error::ApiError;

use crate::graph::Task;
use crate::infer::Backend;
use crate::infer::batcher::JobControl;
use crate::infer::models::{ModelSet, ServedModel};

/// A served model that can move into a blocking job.
#[derive(Clone)]
pub struct ModelRef {
    set: Arc<ModelSet>,
    index: usize,
}

impl std::ops::Deref for ModelRef {
    type Target = ServedModel;
    fn deref(&self) -> &ServedModel {
        &self.set.models[self.index]
    }
}

/// Models both model endpoints need before the server calls itself ready.
pub const REQUIRED_MODELS: [&str; 2] = ["forward_gnn", "policy_gnn"];

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
    /// Actions one `/v1/forward` call may evaluate.
    pub max_actions: usize,
    /// Largest planning budget a `/v1/plan` call may ask for.
    pub max_plan_budget: Duration,
    /// Push predictions one `/v1/plan` call may ask for.
    pub max_plan_evaluations: usize,
    /// Serve `POST /debug/panic` and `/debug/panic-worker` (tests only).
    pub fault_injection: bool,
}

impl Default for Limits {
    fn default() -> Self {
        let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
        Self {
            max_nodes: crate::tree::MAX_NODES,
            max_body_bytes: 1 << 20,
            // Queued model jobs cost a waiting thread, not CPU: admit enough
            // that dynamic batching has work (16 per core) and shed the rest.
            max_in_flight: 16 * cores,
            request_timeout: Duration::from_secs(10),
            max_actions: 256,
            max_plan_budget: Duration::from_secs(5),
            max_plan_evaluations: 512,
            fault_injection: false,
        }
    }
}

/// What the handlers share.
#[derive(Clone)]
pub struct AppState {
    pub limits: Limits,
    /// The served models (none: only `/v1/simulate` works, `/readyz` is 503).
    pub models: Option<Arc<ModelSet>>,
    admission: Arc<Semaphore>,
    metrics: metrics_exporter_prometheus::PrometheusHandle,
    /// Graceful shutdown's state ([`shutdown`]).
    pub drain: Arc<shutdown::Drain>,
    /// The arm's collision geometry, built once.
    pub planner: Arc<crate::planner::Planner>,
}

impl AppState {
    pub fn new(limits: Limits) -> Self {
        Self {
            admission: Arc::new(Semaphore::new(limits.max_in_flight)),
            limits,
            models: None,
            metrics: metrics::recorder(),
            drain: Arc::default(),
            planner: Arc::default(),
        }
    }

    pub fn with_models(mut self, models: Arc<ModelSet>) -> Self {
        self.models = Some(models);
        self
    }

    /// `tract` or `onnxruntime`.
    pub fn backend_name(&self) -> String {
        match self.models.as_ref().map(|m| &m.backend) {
            Some(Backend::OnnxRuntime { .. }) => "onnxruntime".to_owned(),
            _ => "tract".to_owned(),
        }
    }

    /// The model serving `task`, or 503 naming what is missing.
    pub fn model_for(&self, task: Task) -> Result<ModelRef, ApiError> {
        self.model_by_name(&format!("{}_gnn", task.name()))
    }

    /// A loaded model by name, or 503 naming what is missing.
    pub fn model_by_name(&self, name: &str) -> Result<ModelRef, ApiError> {
        let set = self.models.clone().ok_or_else(|| {
            ApiError::not_ready("no models are loaded (start the server with --models-dir)")
        })?;
        let index = set
            .models
            .iter()
            .position(|m| m.name == name)
            .ok_or_else(|| {
                ApiError::not_ready(format!(
                    "the {name} model is not loaded (looked in {})",
                    set.dir.display()
                ))
            })?;
        Ok(ModelRef { set, index })
    }

    /// Runs CPU work on the blocking pool, within the admission limit and
    /// the time budget. The work itself is not cancelled by a timeout (it
    /// is bounded by the request limits); its answer is dropped.
    pub async fn run_blocking<T, F>(&self, route: &'static str, work: F) -> Result<T, ApiError>
    where
        T: Send + 'static,
        F: FnOnce() -> Result<T, ApiError> + Send + 'static,
    {
        self.run_model_work(route, None, move |_| work()).await
    }

    /// [`Self::run_blocking`] for work that queues model jobs: the work gets
    /// a [`JobControl`] with the request's deadline (`timeout`, capped by
    /// the server's limit) and a flag set when the client goes away, so
    /// the model's queue drops jobs nobody waits for.
    pub async fn run_model_work<T, F>(
        &self,
        route: &'static str,
        timeout: Option<Duration>,
        work: F,
    ) -> Result<T, ApiError>
    where
        T: Send + 'static,
        F: FnOnce(JobControl) -> Result<T, ApiError> + Send + 'static,
    {
        let Ok(permit) = self.admission.clone().try_acquire_owned() else {
            ::metrics::counter!("treemanip_rejected_total", "route" => route, "reason" => "overloaded").increment(1);
            return Err(ApiError::overloaded());
        };
        let budget = timeout.map_or(self.limits.request_timeout, |t| {
            t.min(self.limits.request_timeout)
        });
        let started = std::time::Instant::now();
        let cancel = CancelOnDrop(Arc::new(AtomicBool::new(false)));
        let waited_ns = Arc::new(AtomicU64::new(0));
        let control = JobControl {
            deadline: Some(started + budget),
            cancelled: Some(cancel.0.clone()),
            waited_ns: Some(waited_ns.clone()),
        };
        let job = tokio::task::spawn_blocking(move || {
            let _permit = permit;
            let began = std::time::Instant::now();
            let result = work(control);
            (began, began.elapsed(), result)
        });
        let result = match tokio::time::timeout(budget, job).await {
            Err(_) => Err(ApiError::timeout(budget.as_secs_f64())),
            Ok(Err(join)) => Err(ApiError::internal(format!("the worker failed: {join}"))),
            Ok(Ok((began, worked, result))) => {
                // Waiting: for a blocking thread, then in the model queues;
                // computing: the rest of the work.
                let in_queues = Duration::from_nanos(waited_ns.load(Ordering::SeqCst));
                let queued = began.duration_since(started) + in_queues;
                let computed = worked.saturating_sub(in_queues);
                ::metrics::histogram!("treemanip_queue_seconds", "route" => route)
                    .record(queued.as_secs_f64());
                let _ = timing::TIMING.try_with(|t| t.set(Some((queued, computed))));
                result
            }
        };
        drop(cancel);
        ::metrics::histogram!("treemanip_compute_seconds", "route" => route)
            .record(started.elapsed().as_secs_f64());
        result
    }
}

/// Marks a request's model jobs as unwanted when its handler is dropped (the
/// client closed the connection) or finishes.
struct CancelOnDrop(Arc<AtomicBool>);

impl Drop for CancelOnDrop {
    fn drop(&mut self) {
        self.0.store(true, Ordering::SeqCst);
    }
}

pub fn router(state: AppState) -> Router {
    let body_limit = state.limits.max_body_bytes;
    let mut routes = Router::new();
    if state.limits.fault_injection {
        // For tests of what a bug does to the server: a handler that
        // panics, and one whose blocking job panics.
        routes = routes.route("/debug/panic", post(injected_panic)).route(
            "/debug/panic-worker",
            post(|State(state): State<AppState>| async move {
                state
                    .run_blocking("/debug/panic-worker", || -> Result<(), ApiError> {
                        panic!("injected fault in a worker")
                    })
                    .await
            }),
        );
    }
    routes
        .route("/healthz", get(healthz))
        .route("/readyz", get(readyz))
        .route("/metrics", get(render_metrics))
        .route("/openapi.yaml", get(openapi))
        .route("/v1/models", get(list_models))
        .route("/v1/forward", post(predict::forward))
        .route("/v1/policy", post(predict::policy))
        .route("/v1/plan", post(plan::plan))
        .route("/v1/simulate", post(simulate::simulate))
        .route("/v1/trees/urdf", post(scene::tree_from_urdf))
        .route("/v1/trees/example", get(scene::example_tree))
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
        .layer(axum::middleware::from_fn(timing::headers))
        // A bug in one handler is that request's 500, in the error shape;
        // the server keeps serving.
        .layer(tower_http::catch_panic::CatchPanicLayer::custom(
            panic_response,
        ))
        .layer(DefaultBodyLimit::max(body_limit))
        // Every request gets an id (a client's own `x-request-id` is kept),
        // echoed in the answer and named in its log lines.
        .layer(tower_http::request_id::PropagateRequestIdLayer::x_request_id())
        .layer(timing::RequestSpanLayer::new())
        .layer(tower_http::request_id::SetRequestIdLayer::x_request_id(
            tower_http::request_id::MakeRequestUuid,
        ))
        .with_state(state)
}

async fn injected_panic() -> ApiError {
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

/// The process is up and answering.
async fn healthz() -> axum::Json<serde_json::Value> {
    axum::Json(json!({ "status": "ok" }))
}

/// Ready means: every model the endpoints need is loaded.
async fn readyz(State(state): State<AppState>) -> Result<axum::Json<serde_json::Value>, ApiError> {
    let loaded: Vec<String> = state
        .models
        .as_ref()
        .map(|m| m.models.iter().map(|m| m.name.clone()).collect())
        .unwrap_or_default();
    let missing: Vec<&str> = REQUIRED_MODELS
        .iter()
        .copied()
        .filter(|r| !loaded.iter().any(|l| l == r))
        .collect();
    let broken: serde_json::Map<String, serde_json::Value> = state
        .models
        .as_ref()
        .map(|m| {
            m.broken
                .iter()
                .map(|(name, why)| (name.clone(), json!(why)))
                .collect()
        })
        .unwrap_or_default();
    if !missing.is_empty() {
        return Err(ApiError::not_ready(format!(
            "models not loaded: {} (POST /v1/simulate works without them)",
            missing.join(", ")
        ))
        .with_details(json!({ "missing": missing, "loaded": loaded, "broken": broken })));
    }
    Ok(axum::Json(json!({
        "status": "ready",
        "models": loaded,
        "broken": broken,
        "backend": state.backend_name(),
    })))
}

/// Every loaded model with its metadata.
async fn list_models(State(state): State<AppState>) -> axum::Json<serde_json::Value> {
    let models: Vec<serde_json::Value> = state
        .models
        .as_ref()
        .map(|set| {
            set.models
                .iter()
                .map(|m| {
                    let metadata: serde_json::Map<String, serde_json::Value> = m
                        .metadata
                        .iter()
                        .map(|(k, v)| {
                            // Values that are JSON documents are returned as JSON.
                            let value = serde_json::from_str::<serde_json::Value>(v)
                                .ok()
                                .filter(|v| v.is_object() || v.is_array())
                                .unwrap_or_else(|| serde_json::Value::String(v.clone()));
                            (k.clone(), value)
                        })
                        .collect();
                    json!({
                        "name": m.name,
                        "task": m.task.name(),
                        "file": m.file.file_name().map(|f| f.to_string_lossy().into_owned()),
                        "metadata": metadata,
                    })
                })
                .collect()
        })
        .unwrap_or_default();
    axum::Json(json!({ "backend": state.backend_name(), "models": models }))
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
