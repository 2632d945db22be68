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

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Duration;

use axum::extract::{Request, State};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use super::AppState;
use super::error::ApiError;

/// Whether the server is draining, and how many requests are in flight.
#[derive(Debug, Default)]
pub struct Drain {
    draining: AtomicBool,
    in_flight: AtomicUsize,
}

impl Drain {
    pub fn is_draining(&self) -> bool {
        self.draining.load(Ordering::SeqCst)
    }

    pub fn in_flight(&self) -> usize {
        self.in_flight.load(Ordering::SeqCst)
    }

    /// Starts draining and resolves when no request is in flight, or after
    /// `grace`, whichever comes first.
    pub async fn drain(&self, grace: Duration) {
        self.draining.store(true, Ordering::SeqCst);
        tracing::info!(
            in_flight = self.in_flight(),
            "draining: new requests get 503"
        );
        let deadline = tokio::time::Instant::now() + grace;
        while self.in_flight() > 0 && tokio::time::Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
        tracing::info!(left = self.in_flight(), "drained");
    }
}

/// Decrements the in-flight count however the request ends (a dropped
/// future included: the client went away).
struct InFlight(Arc<Drain>);

impl Drop for InFlight {
    fn drop(&mut self) {
        self.0.in_flight.fetch_sub(1, Ordering::SeqCst);
    }
}

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
