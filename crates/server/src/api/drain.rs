//! The drain state of graceful shutdown ([`crate::api::shutdown`]): whether
//! the server is draining and how many requests are in flight.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Duration;

/// Whether the server is draining, and how many requests are in flight.
#[derive(Debug, Default)]
pub struct Drain {
    pub(crate) draining: AtomicBool,
    pub(crate) in_flight: AtomicUsize,
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
pub(crate) struct InFlight(pub(crate) Arc<Drain>);

impl Drop for InFlight {
    fn drop(&mut self) {
        self.0.in_flight.fetch_sub(1, Ordering::SeqCst);
    }
}
