//! `treemanip-server`: the HTTP service.

use std::net::SocketAddr;

use clap::{Parser, ValueEnum};
use tokio::net::TcpListener;
use treemanip::api::{self, AppState};

#[derive(Parser)]
#[command(
    name = "treemanip-server",
    version,
    about = "HTTP service for tree manipulation models"
)]
struct Args {
    /// Address to listen on (port 0 picks a free port).
    #[arg(long, env = "TREEMANIP_BIND", default_value = "127.0.0.1:8080")]
    bind: SocketAddr,
    /// Log format.
    #[arg(long, env = "TREEMANIP_LOG_FORMAT", value_enum, default_value_t = LogFormat::Text)]
    log_format: LogFormat,
}

#[derive(Clone, Copy, ValueEnum)]
enum LogFormat {
    Text,
    Json,
}

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    let logs = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr);
    match args.log_format {
        LogFormat::Text => logs.init(),
        LogFormat::Json => logs.json().init(),
    }

    let listener = TcpListener::bind(args.bind)
        .await
        .map_err(|e| anyhow::anyhow!("cannot listen on {}: {e}", args.bind))?;
    let addr = listener.local_addr()?;
    tracing::warn!("no trained models are shipped yet: /readyz answers 503");
    tracing::info!(%addr, "listening");
    // One machine-readable line on stdout for scripts and tests.
    println!("listening on http://{addr}");

    axum::serve(listener, api::router(AppState::default()))
        .with_graceful_shutdown(shutdown_signal())
        .await?;
    tracing::info!("shut down cleanly");
    Ok(())
}

/// Resolves on SIGINT or SIGTERM; in-flight requests then finish.
async fn shutdown_signal() {
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
