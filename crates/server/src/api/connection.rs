//! Which answers end their connection.
//!
//! hyper closes a keep-alive connection after an answer when the request's
//! body was not read to its end: it cannot tell where the next request
//! would start. An error answered before the body was read (a 415 for the
//! wrong content type, a 413, a 404 for a POST) therefore ends the
//! connection without saying so, and a pooled client (Python's `requests`,
//! ureq) that sends its next request on it sees the peer disconnect: a
//! valid request fails because of an earlier bad one. Saying
//! `Connection: close` on those answers lets the client open a new
//! connection instead.

use axum::extract::Request;
use axum::http::{HeaderValue, header};
use axum::middleware::Next;
use axum::response::Response;

/// Middleware: an error answer (4xx, 5xx) to a request that carries a body
/// says `Connection: close`. Whether the handler read the body is not
/// known here; closing after an error costs the client one reconnect.
pub async fn close_after_error_with_body(request: Request, next: Next) -> Response {
    let carries_body = request
        .headers()
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim().parse::<u64>().ok())
        .is_some_and(|n| n > 0)
        || request.headers().contains_key(header::TRANSFER_ENCODING);
    let mut response = next.run(request).await;
    let status = response.status();
    if carries_body && (status.is_client_error() || status.is_server_error()) {
        response
            .headers_mut()
            .insert(header::CONNECTION, HeaderValue::from_static("close"));
    }
    response
}
