//! The service's own endpoints: liveness, readiness, the loaded models and
//! the Prometheus metrics.

use axum::extract::State;
use axum::http::header;
use axum::response::IntoResponse;
use serde_json::json;

use crate::api::error::ApiError;
use crate::api::state::{AppState, REQUIRED_MODELS};
use crate::api::types::models::{ModelEntry, ModelsResponse};
use crate::api::types::service::{HealthResponse, ReadyResponse};

/// The process is up.
#[utoipa::path(get, path = "/healthz", tag = "service",
    responses((status = 200, description = "Up.", body = HealthResponse)))]
pub async fn healthz() -> axum::Json<HealthResponse> {
    axum::Json(HealthResponse { status: "ok" })
}

/// The models are loaded.
///
/// Ready means: every model the endpoints need is loaded.
#[utoipa::path(get, path = "/readyz", tag = "service", responses(
    (status = 200, description = "Ready.", body = ReadyResponse),
    (status = 503, response = crate::api::types::error::ErrorReply),
))]
pub async fn readyz(State(state): State<AppState>) -> Result<axum::Json<ReadyResponse>, ApiError> {
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
    let broken: std::collections::BTreeMap<String, String> = state
        .models
        .as_ref()
        .map(|m| m.broken.iter().cloned().collect())
        .unwrap_or_default();
    if !missing.is_empty() {
        return Err(ApiError::not_ready(format!(
            "models not loaded: {} (POST /v1/simulate works without them)",
            missing.join(", ")
        ))
        .with_details(json!({ "missing": missing, "loaded": loaded, "broken": broken })));
    }
    Ok(axum::Json(ReadyResponse {
        status: "ready",
        models: loaded,
        broken,
        backend: state.backend_name(),
    }))
}

/// The loaded models and their metadata.
#[utoipa::path(get, path = "/v1/models", tag = "service",
    responses((status = 200, description = "Models.", body = ModelsResponse)))]
pub async fn list_models(State(state): State<AppState>) -> axum::Json<ModelsResponse> {
    let models = state
        .models
        .as_ref()
        .map(|set| {
            set.models
                .iter()
                .map(|m| ModelEntry {
                    name: m.name.clone(),
                    task: m.task.name(),
                    file: m.file.file_name().map(|f| f.to_string_lossy().into_owned()),
                    metadata: serde_json::to_value(&m.card).unwrap_or_default(),
                })
                .collect()
        })
        .unwrap_or_default();
    axum::Json(ModelsResponse {
        backend: state.backend_name(),
        models,
    })
}

/// Prometheus metrics (text exposition format).
#[utoipa::path(get, path = "/metrics", tag = "service",
    responses((status = 200, description = "Metrics.", body = String, content_type = "text/plain")))]
pub async fn render_metrics(State(state): State<AppState>) -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "text/plain; version=0.0.4")],
        state.metrics.render(),
    )
}
