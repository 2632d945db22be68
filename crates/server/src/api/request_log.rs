//! Per-request observability: an id in every log line, one access-log line
//! per answer, and `x-queue-time` / `x-compute-time` headers (ms) on answers
//! that ran model or planner work.

use std::cell::Cell;
use std::time::Duration;

use axum::body::Body;
use axum::extract::Request;
use axum::http::{HeaderValue, Response};
use axum::middleware::Next;
use tower_http::classify::{ServerErrorsAsFailures, SharedClassifier};
use tower_http::trace::{DefaultOnRequest, TraceLayer};
use tracing::Span;

tokio::task_local! {
    /// (waiting, computing) of the request running in this task, set by
    /// [`super::AppState::run_model_work`].
    pub static TIMING: Cell<Option<(Duration, Duration)>>;
}

/// Middleware: adds the timing headers when the handler recorded them.
pub async fn headers(request: Request, next: Next) -> axum::response::Response {
    TIMING
        .scope(Cell::new(None), async move {
            let mut response = next.run(request).await;
            if let Some((queued, computed)) = TIMING.with(Cell::get) {
                for (name, d) in [("x-queue-time", queued), ("x-compute-time", computed)] {
                    if let Ok(v) = HeaderValue::from_str(&format!("{:.3}", d.as_secs_f64() * 1e3)) {
                        response.headers_mut().insert(name, v);
                    }
                }
            }
            response
        })
        .await
}

fn request_span(request: &Request<Body>) -> Span {
    let id = request
        .headers()
        .get("x-request-id")
        .and_then(|v| v.to_str().ok())
        .unwrap_or("-");
    tracing::info_span!("request", request_id = %id, method = %request.method(), uri = %request.uri())
}

fn access_log(response: &Response<Body>, latency: Duration, _span: &Span) {
    tracing::info!(
        status = response.status().as_u16(),
        latency_ms = latency.as_secs_f64() * 1e3,
        "answered"
    );
}

type SpanFn = fn(&Request<Body>) -> Span;
type LogFn = fn(&Response<Body>, Duration, &Span);

/// Tracing of every request in a span carrying its `x-request-id`, with one
/// info-level line per answer (status and latency).
pub struct RequestSpanLayer;

impl RequestSpanLayer {
    #[allow(clippy::new_ret_no_self)]
    pub fn new()
    -> TraceLayer<SharedClassifier<ServerErrorsAsFailures>, SpanFn, DefaultOnRequest, LogFn> {
        TraceLayer::new_for_http()
            .make_span_with(request_span as SpanFn)
            .on_response(access_log as LogFn)
    }
}
