//! Graceful shutdown in two phases, so that no admitted request is lost and
//! no client is left without an answer:
//!
//! 1. **Drain**: on SIGTERM (or SIGINT) the server keeps its listener and
//!    connections open but answers every *new* request 503 `not_ready`
//!    ("shutting down"; a load balancer retries it elsewhere, and readiness
//!    already fails), while the requests already admitted run to the end.
//! 2. **Close**: once none is in flight (or the grace period is over), the
//!    listener closes and open connections finish (axum's graceful
//!    shutdown), and the process exits 0.

use std::sync::atomic::Ordering;

use axum::extract::{Request, State};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use super::error::ApiError;
use crate::api::drain::InFlight;
use crate::api::state::AppState;

/// Middleware: refuses new requests while draining, counts the others.
/// Health checks pass through so that an orchestrator can still see the
/// process live while it drains.
///
/// While draining, every answer carries `Connection: close`: a load
/// balancer (or client) then stops sending requests on this connection
/// instead of racing the final close, when a request written onto an idle
/// connection just as the server closes it would get no answer at all.
pub async fn guard(State(state): State<AppState>, request: Request, next: Next) -> Response {
    let mut response = if request.uri().path() == "/healthz" {
        next.run(request).await
    } else {
        state.drain.in_flight.fetch_add(1, Ordering::SeqCst);
        let _counted = InFlight(state.drain.clone());
        if state.drain.is_draining() {
            ApiError::not_ready("the server is shutting down; retry on another instance")
                .into_response()
        } else {
            next.run(request).await
        }
    };
    if state.drain.is_draining() {
        response.headers_mut().insert(
            axum::http::header::CONNECTION,
            axum::http::HeaderValue::from_static("close"),
        );
    }
    response
}

/// SIGINT or SIGTERM.
pub async fn signal() {
    let interrupt = async {
        tokio::signal::ctrl_c().await.ok();
    };
    #[cfg(unix)]
    let terminate = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let terminate = std::future::pending::<()>();
    tokio::select! {
        _ = interrupt => {},
        _ = terminate => {},
    }
}
