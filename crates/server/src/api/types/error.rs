//! The one error shape every endpoint answers with: `{"error": {"code",
//! "message", "details"}}` ([`crate::api::error::ApiError`] builds it).

use axum::http::StatusCode;
use serde::Serialize;
use utoipa::openapi::schema::{ObjectBuilder, Schema, Type};
use utoipa::openapi::{Ref, RefOr, ResponseBuilder, content::ContentBuilder};
use utoipa::{IntoResponses, PartialSchema, ToResponse, ToSchema};

use crate::api::types::schema::AnyJson;

/// The API's error codes: each has one HTTP status. Clients branch on the
/// code; `openapi.yaml`'s `Error.code` enum is derived from [`ErrorCode::ALL`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ErrorCode {
    MalformedJson,
    NotFound,
    MethodNotAllowed,
    TooLarge,
    UnsupportedMediaType,
    InvalidTree,
    InvalidArgument,
    PushInfeasible,
    OutOfDomain,
    NotReady,
    Overloaded,
    Timeout,
    Internal,
}

impl ErrorCode {
    pub const ALL: [ErrorCode; 13] = [
        ErrorCode::MalformedJson,
        ErrorCode::NotFound,
        ErrorCode::MethodNotAllowed,
        ErrorCode::TooLarge,
        ErrorCode::UnsupportedMediaType,
        ErrorCode::InvalidTree,
        ErrorCode::InvalidArgument,
        ErrorCode::PushInfeasible,
        ErrorCode::OutOfDomain,
        ErrorCode::NotReady,
        ErrorCode::Overloaded,
        ErrorCode::Timeout,
        ErrorCode::Internal,
    ];

    /// The code as clients see it.
    pub const fn as_str(self) -> &'static str {
        match self {
            ErrorCode::MalformedJson => "malformed_json",
            ErrorCode::NotFound => "not_found",
            ErrorCode::MethodNotAllowed => "method_not_allowed",
            ErrorCode::TooLarge => "too_large",
            ErrorCode::UnsupportedMediaType => "unsupported_media_type",
            ErrorCode::InvalidTree => "invalid_tree",
            ErrorCode::InvalidArgument => "invalid_argument",
            ErrorCode::PushInfeasible => "push_infeasible",
            ErrorCode::OutOfDomain => "out_of_domain",
            ErrorCode::NotReady => "not_ready",
            ErrorCode::Overloaded => "overloaded",
            ErrorCode::Timeout => "timeout",
            ErrorCode::Internal => "internal",
        }
    }

    /// The HTTP status every answer with this code has.
    pub const fn status(self) -> StatusCode {
        match self {
            ErrorCode::MalformedJson => StatusCode::BAD_REQUEST,
            ErrorCode::NotFound => StatusCode::NOT_FOUND,
            ErrorCode::MethodNotAllowed => StatusCode::METHOD_NOT_ALLOWED,
            ErrorCode::TooLarge => StatusCode::PAYLOAD_TOO_LARGE,
            ErrorCode::UnsupportedMediaType => StatusCode::UNSUPPORTED_MEDIA_TYPE,
            ErrorCode::InvalidTree
            | ErrorCode::InvalidArgument
            | ErrorCode::PushInfeasible
            | ErrorCode::OutOfDomain => StatusCode::UNPROCESSABLE_ENTITY,
            ErrorCode::NotReady | ErrorCode::Overloaded => StatusCode::SERVICE_UNAVAILABLE,
            ErrorCode::Timeout => StatusCode::GATEWAY_TIMEOUT,
            ErrorCode::Internal => StatusCode::INTERNAL_SERVER_ERROR,
        }
    }
}

impl PartialEq<&str> for ErrorCode {
    fn eq(&self, other: &&str) -> bool {
        self.as_str() == *other
    }
}

/// An error, in the one shape every endpoint uses.
#[derive(Debug, Serialize, ToSchema)]
#[schema(as = Error)]
pub struct ErrorResponse {
    pub error: ErrorBody,
}

/// What went wrong: a stable `code` (clients branch on it), a `message`
/// for people, and `details` (which field, which limit) for programs.
#[derive(Debug, Serialize, ToSchema)]
pub struct ErrorBody {
    pub code: ErrorCode,
    pub message: String,
    #[schema(value_type = AnyJson)]
    pub details: serde_json::Value,
}

impl PartialSchema for ErrorCode {
    fn schema() -> RefOr<Schema> {
        ObjectBuilder::new()
            .schema_type(Type::String)
            .enum_values(Some(ErrorCode::ALL.iter().map(|c| c.as_str())))
            .description(Some(
                "Each code has one HTTP status (`crates/server/src/api/error.rs`).",
            ))
            .into()
    }
}
impl ToSchema for ErrorCode {}

impl Serialize for ErrorCode {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

impl ToSchema for AnyJson {}

/// The error response every endpoint may answer with (4xx, 5xx).
pub struct ErrorReply;

impl<'r> ToResponse<'r> for ErrorReply {
    fn response() -> (&'r str, RefOr<utoipa::openapi::Response>) {
        (
            "Error",
            ResponseBuilder::new()
                .description("An error, in the one shape every endpoint uses.")
                .content(
                    "application/json",
                    ContentBuilder::new()
                        .schema(Some(RefOr::Ref(Ref::from_schema_name("Error"))))
                        .build(),
                )
                .into(),
        )
    }
}

/// The statuses at which an endpoint answers [`ErrorReply`], as a set a
/// handler's `#[utoipa::path(responses(...))]` names once.
fn errors(
    statuses: &[u16],
) -> std::collections::BTreeMap<String, RefOr<utoipa::openapi::Response>> {
    statuses
        .iter()
        .map(|s| (s.to_string(), RefOr::Ref(Ref::from_response_name("Error"))))
        .collect()
}

/// A JSON POST endpoint's errors: malformed (400), too large (413), not
/// JSON (415), unusable (422), not ready or overloaded (503), out of time
/// (504).
pub struct PostErrors;

impl IntoResponses for PostErrors {
    fn responses() -> std::collections::BTreeMap<String, RefOr<utoipa::openapi::Response>> {
        errors(&[400, 413, 415, 422, 503, 504])
    }
}

/// An Open Inference Protocol model endpoint's errors: no such model
/// (404), not loaded (503).
pub struct ModelErrors;

impl IntoResponses for ModelErrors {
    fn responses() -> std::collections::BTreeMap<String, RefOr<utoipa::openapi::Response>> {
        errors(&[404, 503])
    }
}
