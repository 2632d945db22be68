//! Running exported ONNX models through `ort`.
//!
//! [`init_backend`] is called once per process and picks the engine:
//! 1. a path to ONNX Runtime's shared library (`--ort-dylib` /
//!    `ORT_DYLIB_PATH`): native ONNX Runtime from it, or tract (with a
//!    logged warning) when it does not load;
//! 2. otherwise the ONNX Runtime library embedded in this binary at build
//!    time (`build.rs`), written once to a cache file and loaded from there:
//!    native speed with nothing to install;
//! 3. otherwise (`TREEMANIP_BACKEND=tract`, or a build without the embedded
//!    library) tract, pure Rust, when the `tract` feature compiled it in;
//!    without it, an error that says how to get an engine.
//!
//! ort is never left to load a library on its own, which would panic when
//! none is installed.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use ort::session::Session;
use ort::session::builder::GraphOptimizationLevel;
use ort::value::TensorRef;
use serde::Serialize;

pub mod batcher;
/// The model I/O contract lives with the graph encoding (the exporter in
/// `nn` uses it too); re-exported here for the runner's users.
pub use treemanip_core::graph::contract;
mod embedded;
pub use embedded::EMBEDDED;

pub mod models;
mod planning;

use treemanip_core::graph::contract::ModelOutput;
use treemanip_core::graph::{Batch, EDGE_DIM};

/// Which ONNX engine this process runs on.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Backend {
    /// Native ONNX Runtime, loaded from this library (`embedded`: the copy
    /// carried in this binary).
    OnnxRuntime { library: PathBuf, embedded: bool },
    /// tract, compiled in.
    Tract,
}

/// Why a model could not be loaded or could not answer. Each layer's
/// error keeps its source: the file's path, the graph encoder's or batcher's
/// error, the model card's.
#[derive(Debug, Clone, thiserror::Error)]
pub enum InferError {
    /// No ONNX engine could be set up.
    #[error("ONNX backend: {0}")]
    Backend(String),
    /// A model file or directory could not be read.
    #[error("reading {}: {reason}", path.display())]
    Read { path: PathBuf, reason: String },
    /// A model file this build cannot serve.
    #[error("{}: {problem}", path.display())]
    Load { path: PathBuf, problem: LoadProblem },
    /// ONNX Runtime refused a model's bytes (a session could not be made).
    #[error("ONNX Runtime cannot open the model: {0}")]
    Session(String),
    /// The request is not a graph the model reads.
    #[error("cannot encode the request: {0}")]
    Encode(#[from] treemanip_core::graph::EncodeError),
    #[error("cannot batch the request: {0}")]
    Batch(#[from] treemanip_core::graph::BatchError),
    /// The engine failed while running a batch.
    #[error("inference failed: {0}")]
    Run(String),
    /// The model answered in a shape the contract does not allow.
    #[error("the model answered {got} values where the contract has {expected}")]
    OutputShape { expected: usize, got: usize },
    #[error("{model} is not a policy model (it has no affordance output)")]
    NotAPolicy { model: String },
    /// The batching worker is gone (the server is shutting down).
    #[error("the model's worker stopped")]
    WorkerStopped,
    #[error("the request's deadline passed before the model ran it")]
    DeadlineExceeded,
    #[error("the caller went away before the model ran its request")]
    Cancelled,
}

/// What is wrong with a model file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LoadProblem {
    #[error("not an ONNX model: {0}")]
    NotOnnx(String),
    #[error("feature layout version {found:?}, this build encodes version {expected}")]
    FeatureLayout {
        found: Option<String>,
        expected: u32,
    },
    #[error(transparent)]
    Card(#[from] treemanip_core::model::card::CardError),
    #[error("ONNX Runtime cannot open it: {0}")]
    Session(String),
    #[error("start-up canary inference: {0}")]
    Canary(String),
}

struct Engine {
    backend: Backend,
    environment: ort::environment::Environment,
}

static ENGINE: OnceLock<Engine> = OnceLock::new();

/// Sets up the ONNX engine once; later calls return the first choice.
/// `library` (or else `ORT_DYLIB_PATH`) names ONNX Runtime's shared library.
pub fn init_backend(library: Option<&Path>) -> Result<Backend, InferError> {
    if let Some(engine) = ENGINE.get() {
        return Ok(engine.backend.clone());
    }
    let requested = library
        .map(Path::to_path_buf)
        .or_else(|| std::env::var_os("ORT_DYLIB_PATH").map(PathBuf::from));
    let tract_forced = std::env::var("TREEMANIP_BACKEND").is_ok_and(|b| b == "tract");
    let embedded = match (&requested, tract_forced) {
        (None, false) => embedded::library(),
        _ => None,
    };
    let native = requested.as_ref().or(embedded.as_ref()).and_then(|path| {
        if !path.is_file() {
            tracing::warn!(library = %path.display(), "ONNX Runtime library not found");
            return None;
        }
        match ort::init_from(path) {
            Ok(builder) => builder.build().ok().map(|env| (path.clone(), env)),
            Err(e) => {
                tracing::warn!(library = %path.display(), error = %e, "cannot load ONNX Runtime");
                None
            }
        }
    });
    let engine = match native {
        Some((library, environment)) => Engine {
            backend: Backend::OnnxRuntime {
                library,
                embedded: requested.is_none(),
            },
            environment,
        },
        None => fallback_engine(requested.as_deref(), tract_forced)?,
    };
    Ok(ENGINE.get_or_init(|| engine).backend.clone())
}

/// No native ONNX Runtime: tract, compiled in with the `tract` feature.
#[cfg(feature = "tract")]
fn fallback_engine(requested: Option<&Path>, _tract_forced: bool) -> Result<Engine, InferError> {
    match requested {
        None => {
            tracing::info!("no ONNX Runtime library given or embedded; running models on tract")
        }
        Some(_) => tracing::warn!("running models on tract"),
    }
    // tract runs its matrix products on one thread unless given an
    // executor. Measured on the GNNs (2 cores, batch 1), its
    // multithreaded executor is slower (N = 30: 14.6 vs 9.3 ms), so it
    // is opt-in: `TREEMANIP_TRACT_THREADS=n`.
    let threads = std::env::var("TREEMANIP_TRACT_THREADS")
        .ok()
        .and_then(|t| t.parse::<usize>().ok())
        .unwrap_or(1);
    if threads > 1 {
        tract_linalg::multithread::set_default_executor(
            tract_linalg::multithread::Executor::multithread(threads),
        );
    }
    ort::set_api(ort_tract::api());
    let environment = ort::init()
        .build()
        .map_err(|e| InferError::Backend(e.to_string()))?;
    Ok(Engine {
        backend: Backend::Tract,
        environment,
    })
}

/// No native ONNX Runtime and no tract in this build: say how to get one.
#[cfg(not(feature = "tract"))]
fn fallback_engine(requested: Option<&Path>, tract_forced: bool) -> Result<Engine, InferError> {
    Err(InferError::Backend(no_engine_message(
        requested,
        tract_forced,
    )))
}

/// Why no engine could be had, and the three ways out.
#[cfg_attr(feature = "tract", allow(dead_code))]
fn no_engine_message(requested: Option<&Path>, tract_forced: bool) -> String {
    let why = match (requested, tract_forced) {
        (_, true) => "TREEMANIP_BACKEND=tract asks for tract, which this build does not include".to_owned(),
        (Some(path), false) => format!("the ONNX Runtime library {} could not be loaded", path.display()),
        (None, false) => "this build embeds no ONNX Runtime library (built offline or with TREEMANIP_EMBED_ORT=0)".to_owned(),
    };
    format!(
        "no ONNX engine: {why}. Give a working ONNX Runtime {ORT_VERSION} library with --ort-dylib or ORT_DYLIB_PATH \
         (scripts/fetch-onnxruntime downloads one from PyPI's onnxruntime wheel), rebuild with network access so that \
         the build embeds one, or build the pure-Rust fallback: cargo build --release -p treemanip-server --features tract"
    )
}

/// The ONNX Runtime version the build embeds and `scripts/fetch-onnxruntime`
/// fetches (`build.rs` is where it is set).
pub const ORT_VERSION: &str = env!("TREEMANIP_ORT_VERSION");

/// One loaded model.
pub struct OnnxModel {
    session: Session,
    has_global: bool,
    has_affordance: bool,
    /// The model's `metadata_props`.
    pub metadata: Vec<(String, String)>,
}

impl OnnxModel {
    /// Loads a model from ONNX bytes (initialising the backend with its
    /// defaults first if needed).
    pub fn from_bytes(bytes: &[u8], metadata: Vec<(String, String)>) -> Result<Self, InferError> {
        Self::with_threads(bytes, metadata, None)
    }

    /// Like [`from_bytes`](Self::from_bytes); on native ONNX Runtime,
    /// `intra_threads` caps the threads one inference uses (a server runs
    /// one session per core instead).
    pub fn with_threads(
        bytes: &[u8],
        metadata: Vec<(String, String)>,
        intra_threads: Option<usize>,
    ) -> Result<Self, InferError> {
        init_backend(None)?;
        let engine = ENGINE.get().expect("initialised above");
        let load = |e: String| InferError::Session(e);
        // Level 3 on both backends: native ONNX Runtime optimises by default,
        // but `ort-tract` runs tract's optimiser (operator fusion, constant
        // folding, shape specialisation) only when a level is set, and
        // without it the GNN graphs ran 7-8x slower.
        let mut builder = Session::builder(&engine.environment)
            .map_err(|e| load(e.to_string()))?
            .with_optimization_level(GraphOptimizationLevel::Level3)
            .map_err(|e| load(e.to_string()))?;
        if let (Some(threads), Backend::OnnxRuntime { .. }) = (intra_threads, &engine.backend) {
            builder = builder
                .with_intra_threads(threads)
                .map_err(|e| load(e.to_string()))?;
            // Idle pool threads would otherwise spin after every run,
            // taking the cores the planner's collision checks and
            // simulations need between two inferences.
            if threads > 1 {
                builder = builder
                    .with_intra_op_spinning(false)
                    .map_err(|e| load(e.to_string()))?;
            }
        }
        let session = builder
            .commit_from_memory(bytes)
            .map_err(|e| load(e.to_string()))?;
        let names: Vec<String> = session
            .inputs()
            .iter()
            .map(|i| i.name().to_owned())
            .collect();
        let outputs: Vec<String> = session
            .outputs()
            .iter()
            .map(|o| o.name().to_owned())
            .collect();
        Ok(Self {
            has_global: names.iter().any(|n| n == contract::GLOBAL),
            has_affordance: outputs.iter().any(|n| n == contract::AFFORDANCE),
            session,
            metadata,
        })
    }

    /// Runs the model on a batch.
    pub fn run(&mut self, batch: &Batch) -> Result<ModelOutput, InferError> {
        let (b, n) = (batch.batch, batch.n);
        let nd = batch.task.node_dim();
        let run = |e: ort::Error| InferError::Run(e.to_string());
        let nodes =
            TensorRef::from_array_view(([b, n, nd], batch.nodes.as_slice())).map_err(run)?;
        let edges = TensorRef::from_array_view(([b, n, n, EDGE_DIM], batch.edges.as_slice()))
            .map_err(run)?;
        let mask = TensorRef::from_array_view(([b, n], batch.mask.as_slice())).map_err(run)?;
        let outputs = if self.has_global {
            let global =
                TensorRef::from_array_view(([b, 3], batch.global.as_slice())).map_err(run)?;
            self.session
                .run(ort::inputs![contract::NODES => nodes, contract::EDGES => edges, contract::GLOBAL => global, contract::MASK => mask])
                .map_err(run)?
        } else {
            self.session
                .run(ort::inputs![contract::NODES => nodes, contract::EDGES => edges, contract::MASK => mask])
                .map_err(run)?
        };
        let vector_name = if self.has_affordance {
            contract::ACTION
        } else {
            contract::DISPLACEMENT
        };
        let (_, vectors) = outputs[vector_name]
            .try_extract_tensor::<f32>()
            .map_err(run)?;
        let affordance = if self.has_affordance {
            let (_, a) = outputs[contract::AFFORDANCE]
                .try_extract_tensor::<f32>()
                .map_err(run)?;
            Some(a.to_vec())
        } else {
            None
        };
        Ok(ModelOutput {
            vectors: vectors.to_vec(),
            affordance,
        })
    }
}

impl OnnxModel {
    /// Loads a model file, reading its `metadata_props`.
    pub fn load(path: &std::path::Path) -> Result<Self, InferError> {
        let bytes = std::fs::read(path).map_err(|e| InferError::Read {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        let metadata = read_metadata(&bytes).map_err(|e| InferError::Load {
            path: path.to_path_buf(),
            problem: LoadProblem::NotOnnx(e),
        })?;
        Self::from_bytes(&bytes, metadata)
    }

    /// The task the model's signature implies.
    pub fn task(&self) -> treemanip_core::graph::Task {
        if self.has_affordance {
            treemanip_core::graph::Task::Policy
        } else {
            treemanip_core::graph::Task::Forward
        }
    }
}

/// The `metadata_props` of an ONNX model.
pub fn read_metadata(bytes: &[u8]) -> Result<Vec<(String, String)>, String> {
    use prost::Message;
    let model = onnx_metadata::ModelMetadata::decode(bytes).map_err(|e| e.to_string())?;
    Ok(model
        .metadata_props
        .into_iter()
        .map(|p| (p.key, p.value))
        .collect())
}

/// The part of ONNX's `ModelProto` (onnx.proto3) that holds the metadata:
/// field 14, `repeated StringStringEntryProto metadata_props`. prost skips
/// every other field, so the graph's weights are not decoded.
mod onnx_metadata {
    #[derive(Clone, PartialEq, prost::Message)]
    pub struct ModelMetadata {
        #[prost(message, repeated, tag = "14")]
        pub metadata_props: Vec<StringStringEntry>,
    }

    #[derive(Clone, PartialEq, prost::Message)]
    pub struct StringStringEntry {
        #[prost(string, tag = "1")]
        pub key: String,
        #[prost(string, tag = "2")]
        pub value: String,
    }
}
