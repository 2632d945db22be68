//! What the handlers share ([`AppState`]): the limits, the served models,
//! the admission limit and the blocking pool every CPU job runs on, with
//! its deadline, queue and compute timing.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;

use tokio::sync::Semaphore;
use treemanip_core::graph::Task;
use treemanip_infer::Backend;
use treemanip_infer::batcher::JobControl;
use treemanip_infer::models::{ModelSet, ServedModel};

use super::drain::Drain;
use super::error::ApiError;
use super::robot_planners::RobotPlanners;
use super::{metrics, request_log};

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
    /// Largest tree accepted (≤ [`treemanip_core::tree::MAX_NODES`]).
    pub max_nodes: usize,
    /// Largest request body (bytes).
    pub max_body_bytes: usize,
    /// Largest point cloud of `/v1/trees/from-points` (points).
    pub max_cloud_points: usize,
    /// Largest `/v1/trees/from-points` body (bytes).
    pub max_cloud_bytes: usize,
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
            max_nodes: treemanip_core::tree::MAX_NODES,
            max_body_bytes: 1 << 20,
            max_cloud_points: treemanip_core::scan::extract::DEFAULT_MAX_POINTS,
            max_cloud_bytes: 128 << 20,
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
    pub(crate) admission: Arc<Semaphore>,
    pub(crate) metrics: metrics_exporter_prometheus::PrometheusHandle,
    /// Graceful shutdown's state ([`crate::api::shutdown`]).
    pub drain: Arc<Drain>,
    /// A planner per arm served, each built once.
    pub robots: Arc<RobotPlanners>,
}

impl AppState {
    pub fn new(limits: Limits) -> Self {
        Self {
            admission: Arc::new(Semaphore::new(limits.max_in_flight)),
            limits,
            models: None,
            metrics: metrics::recorder(),
            drain: Arc::default(),
            robots: Arc::default(),
        }
    }

    pub fn with_robots(mut self, robots: RobotPlanners) -> Self {
        self.robots = Arc::new(robots);
        self
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
        let names = treemanip_infer::models::default_name(task);
        names
            .iter()
            .find_map(|name| self.model_by_name(name).ok())
            .map_or_else(|| self.model_by_name(names[names.len() - 1]), Ok)
    }

    /// The forward model for a tree of `nodes` nodes
    /// ([`treemanip_infer::models::ModelSet::forward_for`]).
    pub fn forward_model_for(&self, nodes: usize) -> Result<ModelRef, ApiError> {
        let name = self
            .models
            .as_ref()
            .and_then(|set| set.forward_for(nodes))
            .map(|m| m.name.clone());
        match name {
            Some(name) => self.model_by_name(&name),
            None => self.model_for(Task::Forward),
        }
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
                let _ = request_log::TIMING.try_with(|t| t.set(Some((queued, computed))));
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

pub use crate::api::types::ModelInfo;

impl ModelInfo {
    pub fn of(model: &ServedModel, state: &AppState) -> Self {
        Self {
            name: model.name.clone(),
            version: model.card.git_commit.clone(),
            backend: state.backend_name(),
        }
    }
}
