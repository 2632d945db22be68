//! Running the HTTP service: its command-line flags (each with an
//! environment variable), start-up (logging, models, limits) and serving
//! until SIGTERM/SIGINT drains it. `treemanip-server` and `treemanip serve`
//! both call [`run`], so the container image needs one binary.

use std::net::SocketAddr;

use clap::ValueEnum;
use tokio::net::TcpListener;

use crate::api::{self, AppState, Limits};
use treemanip_infer::models::ModelSet;

/// The server's flags.
#[derive(clap::Args, Debug, Clone)]
pub struct ServeArgs {
    /// Address to listen on (port 0 picks a free port).
    #[arg(long, env = "TREEMANIP_BIND", default_value = "127.0.0.1:8080")]
    bind: SocketAddr,
    /// Largest tree accepted (nodes, at most 512: `treemanip_core::tree::MAX_NODES`).
    #[arg(long, env = "TREEMANIP_MAX_NODES", default_value_t = treemanip_core::tree::MAX_NODES)]
    max_nodes: usize,
    /// Largest request body (bytes).
    #[arg(long, env = "TREEMANIP_MAX_BODY_BYTES", default_value_t = 1 << 20)]
    max_body_bytes: usize,
    /// Requests admitted at once (running or queued; default 16 per core, so
    /// that the model queues have work to batch); more are answered 503.
    #[arg(long, env = "TREEMANIP_MAX_IN_FLIGHT")]
    max_in_flight: Option<usize>,
    /// Time budget of one request (seconds); past it the answer is 504.
    #[arg(long, env = "TREEMANIP_REQUEST_TIMEOUT", default_value_t = 10.0)]
    request_timeout: f64,
    /// Directory with the ONNX models (`forward_gnn.onnx`, `policy_gnn.onnx`, ...).
    #[arg(long, env = "TREEMANIP_MODELS_DIR", default_value = "models")]
    models_dir: std::path::PathBuf,
    /// ONNX Runtime shared library; without it (or if it fails to load) the
    /// models run on the embedded tract backend.
    #[arg(long, env = "ORT_DYLIB_PATH")]
    ort_dylib: Option<std::path::PathBuf>,
    /// Largest point cloud `/v1/trees/from-points` takes (points).
    #[arg(long, env = "TREEMANIP_MAX_CLOUD_POINTS", default_value_t = treemanip_core::scan::extract::DEFAULT_MAX_POINTS)]
    max_cloud_points: usize,
    /// Largest `/v1/trees/from-points` body (bytes): 2 million points as
    /// binary PLY of doubles are 48 MB, as JSON about 120 MB.
    #[arg(long, env = "TREEMANIP_MAX_CLOUD_BYTES", default_value_t = 128 << 20)]
    max_cloud_bytes: usize,
    /// Actions one /v1/forward call may evaluate.
    #[arg(long, env = "TREEMANIP_MAX_ACTIONS", default_value_t = 256)]
    max_actions: usize,
    /// Largest planning budget a /v1/plan call may ask for (milliseconds).
    #[arg(long, env = "TREEMANIP_MAX_PLAN_BUDGET_MS", default_value_t = 5000)]
    max_plan_budget_ms: u64,
    /// Push predictions a /v1/plan call may ask for (`max_evaluations`).
    #[arg(long, env = "TREEMANIP_MAX_PLAN_EVALUATIONS", default_value_t = 512)]
    max_plan_evaluations: usize,
    /// Graphs one model batch may hold: queued requests of the same tree size
    /// are run together up to this many.
    #[arg(long, env = "TREEMANIP_MAX_BATCH", default_value_t = 64)]
    max_batch: usize,
    /// How long (µs) a queued request may wait for others to join its batch.
    #[arg(long, env = "TREEMANIP_MAX_QUEUE_DELAY_US", default_value_t = 200)]
    max_queue_delay_us: u64,
    /// Threads one inference runs on (ONNX Runtime's intra-op pool); each
    /// model gets cores ÷ this many sessions. Default: every core, one
    /// session (the fastest per batch measured on 2 cores; the batcher
    /// merges concurrent requests). `1` gives one single-threaded session
    /// per core.
    #[arg(long, env = "TREEMANIP_SESSION_THREADS")]
    session_threads: Option<usize>,
    /// Serve the models that load and report the others as not ready,
    /// instead of refusing to start when a model file is missing, truncated
    /// or of another feature layout.
    #[arg(long, env = "TREEMANIP_SKIP_BROKEN_MODELS")]
    skip_broken_models: bool,
    /// An arm to plan for besides the built-in `ur5`:
    /// `NAME=PATH[,tip=LINK][,base=LINK][,tool=FRAME][,tool_xyz=[x,y,z]][,tool_rpy=[r,p,y]]`,
    /// PATH an imported description (`robots/panda.toml`) or a URDF
    /// (meshes resolve through `TREEMANIP_PACKAGE_PATH`; the tool goes on
    /// the last joint's axis out of the wrist unless `tool=FRAME` names
    /// its frame). Repeatable; the first is the default robot.
    /// `TREEMANIP_ROBOTS` lists them separated by `;`.
    #[arg(long = "robot", env = "TREEMANIP_ROBOTS", value_delimiter = ';')]
    robots: Vec<treemanip_core::robot::catalog::RobotSpec>,
    /// A folder of imported descriptions (`treemanip robot import`), each
    /// served by its file's name beside the built-in `ur5`, which stays
    /// the default unless `--robot` names one (the repository's `robots/`:
    /// `panda`, `ur10`, `iiwa`). A folder that does not exist serves none.
    #[arg(long, env = "TREEMANIP_ROBOTS_DIR", default_value = "robots")]
    robots_dir: std::path::PathBuf,
    /// Serve the robots that load and log the others, instead of refusing
    /// to start on a broken robot file.
    #[arg(long, env = "TREEMANIP_SKIP_BROKEN_ROBOTS")]
    skip_broken_robots: bool,
    /// Serve `POST /debug/panic` and `/debug/panic-worker`, which panic on
    /// purpose: for testing that a bug in one request costs only that
    /// request. Never in production.
    #[arg(long, hide = true)]
    fault_injection: bool,
    /// Check the health of the server listening on --bind (GET /healthz on
    /// loopback) and exit 0 if it answers 200, 1 otherwise: the container
    /// image's HEALTHCHECK, which needs no curl.
    #[arg(long)]
    health_check: bool,
    /// Print the OpenAPI document (derived from the wire types) and exit:
    /// `treemanip-server --print-openapi > openapi.yaml` refreshes the
    /// repository's copy.
    #[arg(long)]
    print_openapi: bool,
    /// Log format.
    #[arg(long, env = "TREEMANIP_LOG_FORMAT", value_enum, default_value_t = LogFormat::Text)]
    log_format: LogFormat,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum LogFormat {
    Text,
    Json,
}

/// Serves until a shutdown signal has drained the server (or, with
/// `--health-check`, probes a running server and returns).
pub fn run(args: ServeArgs) -> anyhow::Result<()> {
    if args.print_openapi {
        print!("{}", api::openapi::yaml());
        return Ok(());
    }
    if args.health_check {
        let addr = api::health_check::loopback_for(args.bind);
        api::health_check::check(addr, std::time::Duration::from_secs(2))
            .map_err(|why| anyhow::anyhow!("unhealthy: {why}"))?;
        println!("healthy: {addr}");
        return Ok(());
    }
    // The blocking pool runs the CPU work, at most --max-in-flight jobs at
    // once (the admission limit), so it needs no more threads than that
    // (tokio's default allows 512); they are kept, not re-spawned after
    // 10 s idle.
    let defaults = Limits::default();
    let blocking = args.max_in_flight.unwrap_or(defaults.max_in_flight).max(1);
    tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .max_blocking_threads(blocking)
        .thread_keep_alive(std::time::Duration::from_secs(24 * 3600))
        .build()?
        .block_on(serve(args))
}

async fn serve(args: ServeArgs) -> anyhow::Result<()> {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    let logs = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr);
    match args.log_format {
        LogFormat::Text => logs.init(),
        LogFormat::Json => logs.json().init(),
    }

    if !(2..=treemanip_core::tree::MAX_NODES).contains(&args.max_nodes) {
        anyhow::bail!(
            "--max-nodes must be between 2 and {}",
            treemanip_core::tree::MAX_NODES
        );
    }
    if !(args.request_timeout.is_finite() && args.request_timeout > 0.0) {
        anyhow::bail!("--request-timeout must be a positive number of seconds");
    }
    if args.max_actions == 0 {
        anyhow::bail!("--max-actions must be at least 1");
    }
    if args.max_batch == 0 {
        anyhow::bail!("--max-batch must be at least 1");
    }
    let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
    let threads = args.session_threads.unwrap_or(cores);
    if threads == 0 {
        anyhow::bail!("--session-threads must be at least 1");
    }
    let sessions = treemanip_infer::models::SessionLayout {
        count: (cores / threads).max(1),
        threads,
    };
    let batching = treemanip_infer::batcher::BatchLimits {
        max_batch: args.max_batch,
        max_pairs: treemanip_infer::batcher::MAX_PAIRS,
        max_delay: std::time::Duration::from_micros(args.max_queue_delay_us),
    };
    let models = ModelSet::load_dir_with(
        &args.models_dir,
        args.ort_dylib.as_deref(),
        sessions,
        args.skip_broken_models,
        batching,
    )
    .map_err(|e| {
        anyhow::anyhow!(
            "loading models from {}: {e} (--skip-broken-models serves the others)",
            args.models_dir.display()
        )
    })?;
    for (name, error) in &models.broken {
        tracing::error!(model = %name, %error, "model not loaded; serving without it");
    }
    tracing::info!(
        backend = ?models.backend,
        models = ?models.models.iter().map(|m| m.name.as_str()).collect::<Vec<_>>(),
        "models loaded"
    );

    let packages = treemanip_core::robot::model::link_geometry::package_path_from_env();
    let shipped = treemanip_core::robot::catalog::folder(&args.robots_dir)
        .map_err(|e| anyhow::anyhow!("--robots-dir: {e}"))?;
    let (mut catalog, mut arms) = (Vec::new(), Vec::new());
    for (spec, given) in shipped
        .iter()
        .map(|s| (s, false))
        .chain(args.robots.iter().map(|s| (s, true)))
    {
        match treemanip_core::robot::catalog::load(spec, &packages) {
            Ok(arm) => {
                tracing::info!(robot = %spec.name, path = %spec.path.display(), dof = arm.dof(), closed_form_ik = arm.has_closed_form_ik(), tool = %arm.tool_chosen(), "robot loaded");
                if given { &mut arms } else { &mut catalog }.push(arm);
            }
            Err(e) if args.skip_broken_robots => {
                tracing::error!(robot = %spec.name, error = %e, "robot not loaded; serving without it");
            }
            Err(e) => anyhow::bail!(
                "loading robot `{}`: {e} (--skip-broken-robots serves the others)",
                spec.name
            ),
        }
    }
    let robots = api::robot_planners::RobotPlanners::new(catalog, arms);

    let listener = TcpListener::bind(args.bind)
        .await
        .map_err(|e| anyhow::anyhow!("cannot listen on {}: {e}", args.bind))?;
    let addr = listener.local_addr()?;
    tracing::info!(%addr, "listening");
    // One machine-readable line on stdout for scripts and tests.
    println!("listening on http://{addr}");

    let defaults = Limits::default();
    let limits = Limits {
        max_nodes: args.max_nodes,
        max_body_bytes: args.max_body_bytes,
        max_cloud_points: args.max_cloud_points.max(1),
        max_cloud_bytes: args.max_cloud_bytes,
        max_in_flight: args.max_in_flight.unwrap_or(defaults.max_in_flight).max(1),
        request_timeout: std::time::Duration::from_secs_f64(args.request_timeout),
        max_actions: args.max_actions,
        max_plan_budget: std::time::Duration::from_millis(args.max_plan_budget_ms),
        max_plan_evaluations: args.max_plan_evaluations.max(1),
        fault_injection: args.fault_injection,
    };
    let grace = limits.request_timeout + std::time::Duration::from_secs(5);
    let state = AppState::new(limits)
        .with_models(std::sync::Arc::new(models))
        .with_robots(robots);
    let drain = state.drain.clone();
    let app = api::router(state);
    axum::serve(listener, app)
        .with_graceful_shutdown(async move {
            api::shutdown::signal().await;
            drain.drain(grace).await;
        })
        .await?;
    tracing::info!("shut down cleanly");
    Ok(())
}
