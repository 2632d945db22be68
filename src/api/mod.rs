//! The HTTP layer: request/response types, routing and error mapping. It
//! owns no computation; it calls into the other modules.
//!
//! So far only the process endpoints exist (`/healthz`, `/readyz`); the
//! model and planner endpoints arrive with the models and the planner.

pub mod error;

use axum::Router;
use axum::routing::get;
use serde_json::json;

use error::ApiError;

/// What the server knows about itself.
#[derive(Clone, Debug, Default)]
pub struct AppState {
    /// Names of the models that are loaded and can answer requests.
    pub loaded_models: Vec<String>,
}

pub fn router(state: AppState) -> Router {
    Router::new()
        .route("/healthz", get(healthz))
        .route("/readyz", get(readyz))
        .fallback(not_found)
        .with_state(state)
}

/// The process is up and answering.
async fn healthz() -> axum::Json<serde_json::Value> {
    axum::Json(json!({ "status": "ok" }))
}

/// Ready means: every model the endpoints need is loaded.
async fn readyz(
    axum::extract::State(state): axum::extract::State<AppState>,
) -> Result<axum::Json<serde_json::Value>, ApiError> {
    if state.loaded_models.is_empty() {
        return Err(ApiError::not_ready(
            "no models are loaded: this build ships no trained models yet",
        ));
    }
    Ok(axum::Json(
        json!({ "status": "ready", "models": state.loaded_models }),
    ))
}

async fn not_found(uri: axum::http::Uri) -> ApiError {
    ApiError::not_found(format!("no route for {}", uri.path()))
}
