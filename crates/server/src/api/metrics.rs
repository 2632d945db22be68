//! Prometheus metrics: per-route request counts by status and latency
//! histograms, compute time, rejections; per model (from the batcher,
//! `infer::batcher`): queue time, compute time and batch size histograms
//! and a queue-depth gauge. Rendered at `GET /metrics`.

use std::sync::OnceLock;
use std::time::{Duration, Instant};

use axum::extract::{MatchedPath, Request};
use axum::middleware::Next;
use axum::response::Response;
use metrics_exporter_prometheus::{Matcher, PrometheusBuilder, PrometheusHandle};

/// Latency buckets (s): 100 µs to 10 s.
const BUCKETS: [f64; 14] = [
    0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 10.0,
];

/// How often the upkeep thread folds recorded samples into the histograms.
const UPKEEP_INTERVAL: Duration = Duration::from_secs(5);

/// The process-wide recorder (installed on first use; one per process, as
/// the `metrics` facade has one global recorder).
///
/// The Prometheus recorder keeps every histogram sample until a scrape or an
/// explicit upkeep folds it into the buckets, and leaves upkeep to the caller:
/// a server nobody scrapes would grow with every request (the soak bench saw
/// +18-25 % resident memory in 10 minutes). A named thread therefore runs
/// upkeep every few seconds for the life of the process.
pub fn recorder() -> PrometheusHandle {
    static HANDLE: OnceLock<PrometheusHandle> = OnceLock::new();
    HANDLE
        .get_or_init(|| {
            let handle = PrometheusBuilder::new()
                .set_buckets_for_metric(Matcher::Suffix("seconds".to_owned()), &BUCKETS)
                .expect("non-empty buckets")
                .set_buckets_for_metric(
                    Matcher::Full("treemanip_batch_size".to_owned()),
                    &[1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0, 128.0, 256.0],
                )
                .expect("non-empty buckets")
                .install_recorder()
                .expect("no other metrics recorder is installed");
            let upkeep = handle.clone();
            std::thread::Builder::new()
                .name(UPKEEP_THREAD.to_owned())
                .spawn(move || {
                    loop {
                        std::thread::sleep(UPKEEP_INTERVAL);
                        upkeep.run_upkeep();
                    }
                })
                .expect("spawn the metrics upkeep thread");
            handle
        })
        .clone()
}

/// Name of the thread that runs the recorder's upkeep.
pub const UPKEEP_THREAD: &str = "metrics-upkeep";

/// Middleware: counts and times every request by route template.
pub async fn track(request: Request, next: Next) -> Response {
    let route = request
        .extensions()
        .get::<MatchedPath>()
        .map_or_else(|| "unmatched".to_owned(), |p| p.as_str().to_owned());
    let method = request.method().to_string();
    let started = Instant::now();
    let response = next.run(request).await;
    let status = response.status().as_u16().to_string();
    metrics::counter!("treemanip_http_requests_total", "route" => route.clone(), "method" => method, "status" => status)
        .increment(1);
    metrics::histogram!("treemanip_http_request_duration_seconds", "route" => route)
        .record(started.elapsed().as_secs_f64());
    response
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Upkeep runs without any scrape: the thread exists once the recorder
    /// does (a thread sets its name once it starts, hence the wait).
    #[test]
    fn metrics_recorder_runs_upkeep_without_scrapes() {
        let _ = recorder();
        let deadline = Instant::now() + Duration::from_secs(5);
        loop {
            let names: Vec<String> = std::fs::read_dir("/proc/self/task")
                .expect("procfs")
                .filter_map(|t| std::fs::read_to_string(t.ok()?.path().join("comm")).ok())
                .map(|n| n.trim().to_owned())
                .collect();
            if names.iter().any(|n| n == UPKEEP_THREAD) {
                return;
            }
            assert!(
                Instant::now() < deadline,
                "no upkeep thread among {names:?}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}
