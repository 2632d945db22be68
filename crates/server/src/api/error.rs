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

use axum::response::{IntoResponse, Response};
use serde_json::{Value, json};

pub use crate::api::types::error::ErrorCode;
use crate::api::types::error::{ErrorBody, ErrorResponse};
use treemanip_core::planner::PlanError;
use treemanip_infer::InferError;

#[derive(Debug, Clone)]
pub struct ApiError {
    /// Stable, machine-readable: clients branch on this, not on `message`.
    pub code: ErrorCode,
    /// For people: says what is wrong and, where possible, how to fix it.
    pub message: String,
    pub details: Value,
}

impl ApiError {
    pub fn new(code: ErrorCode, message: impl Into<String>) -> Self {
        Self {
            code,
            message: message.into(),
            details: Value::Null,
        }
    }

    pub fn not_found(message: impl Into<String>) -> Self {
        Self::new(ErrorCode::NotFound, message)
    }

    pub fn not_ready(message: impl Into<String>) -> Self {
        Self::new(ErrorCode::NotReady, message)
    }

    pub fn malformed(message: impl Into<String>) -> Self {
        Self::new(ErrorCode::MalformedJson, message)
    }

    pub fn invalid_tree(message: impl Into<String>) -> Self {
        Self::new(ErrorCode::InvalidTree, message)
    }

    pub fn invalid_argument(message: impl Into<String>) -> Self {
        Self::new(ErrorCode::InvalidArgument, message)
    }

    /// `invalid_argument` naming the request field at fault.
    pub fn invalid_field(field: &str, message: impl Into<String>) -> Self {
        Self::invalid_argument(message).with_details(json!({ "field": field }))
    }

    pub fn out_of_domain(message: impl Into<String>) -> Self {
        Self::new(ErrorCode::OutOfDomain, message)
    }

    pub fn too_large(message: impl Into<String>) -> Self {
        Self::new(ErrorCode::TooLarge, message)
    }

    pub fn overloaded() -> Self {
        Self::new(
            ErrorCode::Overloaded,
            "the server is busy with other requests; retry shortly",
        )
    }

    pub fn timeout(seconds: f64) -> Self {
        Self::new(
            ErrorCode::Timeout,
            format!("the request did not finish within its {seconds:.1} s budget"),
        )
    }

    /// A request whose deadline passed while its model job was queued.
    pub fn deadline(message: impl Into<String>) -> Self {
        Self::new(ErrorCode::Timeout, message)
    }

    pub fn internal(message: impl Into<String>) -> Self {
        Self::new(ErrorCode::Internal, message)
    }

    pub fn with_details(mut self, details: Value) -> Self {
        self.details = details;
        self
    }
}

/// A failed model job: a deadline that passed or a client that went away is
/// a timeout (nobody reads a cancelled job's answer); an input the model
/// cannot read is the request's; anything else is ours.
impl From<InferError> for ApiError {
    fn from(e: InferError) -> Self {
        match e {
            InferError::DeadlineExceeded | InferError::Cancelled => {
                ApiError::deadline(e.to_string())
            }
            // What the request asked the model to read (a push deeper than
            // a path graph holds, when the domain check is overridden).
            InferError::Encode(_) => ApiError::invalid_argument(e.to_string()),
            _ => ApiError::internal(format!("inference failed: {e}")),
        }
    }
}

impl From<PlanError> for ApiError {
    fn from(e: PlanError) -> Self {
        match e {
            PlanError::StartInCollision => ApiError::invalid_field("robot.start", e.to_string()),
            PlanError::NoForwardModel => ApiError::not_ready(e.to_string()),
            PlanError::PaperNeedsShape(_) => ApiError::invalid_field("strategy", e.to_string()),
            PlanError::Predict(p) => match p.source_as::<InferError>() {
                Some(e) => e.clone().into(),
                None => ApiError::internal(format!("inference failed: {p}")),
            },
        }
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let body = ErrorResponse {
            error: ErrorBody {
                code: self.code,
                message: self.message,
                details: self.details,
            },
        };
        (self.code.status(), axum::Json(body)).into_response()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every code is an error status, and the document's `ErrorCode` enum
    /// (derived from [`ErrorCode::ALL`]) lists each code once.
    #[test]
    fn every_code_is_an_error_status_and_documented() {
        let doc = crate::api::openapi::document();
        let schema = &doc["components"]["schemas"]["ErrorCode"]["enum"];
        let listed: Vec<&str> = schema
            .as_array()
            .expect("an ErrorCode enum")
            .iter()
            .map(|v| v.as_str().unwrap())
            .collect();
        let ours: Vec<&str> = ErrorCode::ALL.iter().map(|c| c.as_str()).collect();
        assert_eq!(listed, ours);
        for code in ErrorCode::ALL {
            assert!(code.status().is_client_error() || code.status().is_server_error());
        }
    }
}
