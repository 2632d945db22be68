//! A JSON body extractor whose failures are [`ApiError`]s in our shape,
//! with messages that say what is wrong (axum's own rejections are plain
//! text).

use axum::body::Bytes;
use axum::extract::{FromRequest, Request};
use axum::http::{StatusCode, header};
use serde::de::DeserializeOwned;

use super::error::ApiError;

pub struct ApiJson<T>(pub T);

impl<S, T> FromRequest<S> for ApiJson<T>
where
    T: DeserializeOwned,
    S: Send + Sync,
{
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &S) -> Result<Self, Self::Rejection> {
        let is_json = req
            .headers()
            .get(header::CONTENT_TYPE)
            .and_then(|v| v.to_str().ok())
            .is_some_and(|v| {
                let mime = v
                    .split(';')
                    .next()
                    .unwrap_or("")
                    .trim()
                    .to_ascii_lowercase();
                mime == "application/json" || mime.ends_with("+json")
            });
        if !is_json {
            return Err(ApiError::new(
                StatusCode::UNSUPPORTED_MEDIA_TYPE,
                "unsupported_media_type",
                "send the body as JSON with `Content-Type: application/json`",
            ));
        }
        let bytes = Bytes::from_request(req, state).await.map_err(|rejection| {
            if rejection.status() == StatusCode::PAYLOAD_TOO_LARGE {
                ApiError::too_large("the request body is larger than the server accepts")
            } else {
                ApiError::malformed(format!(
                    "cannot read the request body: {}",
                    rejection.body_text()
                ))
            }
        })?;
        serde_json::from_slice(&bytes).map(Self).map_err(|e| {
            let text = String::from_utf8_lossy(&bytes);
            if e.is_syntax() && (text.contains("NaN") || text.contains("Infinity")) {
                ApiError::malformed(format!(
                    "not valid JSON ({e}): JSON has no NaN or Infinity, every number must be finite"
                ))
            } else if e.is_syntax() || e.is_eof() {
                ApiError::malformed(format!("not valid JSON: {e}"))
            } else {
                // Valid JSON of the wrong shape: a missing or mistyped field.
                ApiError::malformed(format!("the request does not match the schema: {e}"))
            }
        })
    }
}
