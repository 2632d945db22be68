//! The one error shape every endpoint answers with:
//! `{"error": {"code": "...", "message": "...", "details": ...}}`.
//!
//! | status | code | when |
//! | --- | --- | --- |
//! | 400 | `malformed_json` | the body is not JSON of the right shape |
//! | 404 | `not_found` | no such route |
//! | 405 | `method_not_allowed` | wrong method for the route |
//! | 413 | `too_large` | body or tree over the limits |
//! | 415 | `unsupported_media_type` | not `application/json` |
//! | 422 | `invalid_tree`, `invalid_argument`, `push_infeasible`, `out_of_domain` | the request is well formed but not usable (`out_of_domain`: outside what the model was trained on) |
//! | 503 | `not_ready`, `overloaded` | models not loaded / too much work queued |
//! | 504 | `timeout` | the request's time budget (or its `timeout_ms`) ran out |
//! | 500 | `internal` | a bug: never caused by what a client sent |

use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use serde_json::{Value, json};

#[derive(Debug, Clone)]
pub struct ApiError {
    pub status: StatusCode,
    /// Stable, machine-readable: clients branch on this, not on `message`.
    pub code: &'static str,
    /// For people: says what is wrong and, where possible, how to fix it.
    pub message: String,
    pub details: Value,
}

impl ApiError {
    pub fn new(status: StatusCode, code: &'static str, message: impl Into<String>) -> Self {
        Self {
            status,
            code,
            message: message.into(),
            details: Value::Null,
        }
    }

    pub fn not_found(message: impl Into<String>) -> Self {
        Self::new(StatusCode::NOT_FOUND, "not_found", message)
    }

    pub fn not_ready(message: impl Into<String>) -> Self {
        Self::new(StatusCode::SERVICE_UNAVAILABLE, "not_ready", message)
    }

    pub fn malformed(message: impl Into<String>) -> Self {
        Self::new(StatusCode::BAD_REQUEST, "malformed_json", message)
    }

    pub fn invalid_tree(message: impl Into<String>) -> Self {
        Self::new(StatusCode::UNPROCESSABLE_ENTITY, "invalid_tree", message)
    }

    pub fn invalid_argument(message: impl Into<String>) -> Self {
        Self::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_argument",
            message,
        )
    }

    pub fn out_of_domain(message: impl Into<String>) -> Self {
        Self::new(StatusCode::UNPROCESSABLE_ENTITY, "out_of_domain", message)
    }

    pub fn too_large(message: impl Into<String>) -> Self {
        Self::new(StatusCode::PAYLOAD_TOO_LARGE, "too_large", message)
    }

    pub fn overloaded() -> Self {
        Self::new(
            StatusCode::SERVICE_UNAVAILABLE,
            "overloaded",
            "the server is busy with other requests; retry shortly",
        )
    }

    pub fn timeout(seconds: f64) -> Self {
        Self::new(
            StatusCode::GATEWAY_TIMEOUT,
            "timeout",
            format!("the request did not finish within its {seconds:.1} s budget"),
        )
    }

    /// A request whose deadline passed while its model job was queued.
    pub fn deadline(message: impl Into<String>) -> Self {
        Self::new(StatusCode::GATEWAY_TIMEOUT, "timeout", message)
    }

    pub fn internal(message: impl Into<String>) -> Self {
        Self::new(StatusCode::INTERNAL_SERVER_ERROR, "internal", message)
    }

    pub fn with_details(mut self, details: Value) -> Self {
        self.details = details;
        self
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let body = json!({
            "error": { "code": self.code, "message": self.message, "details": self.details }
        });
        (self.status, axum::Json(body)).into_response()
    }
}
