//! Every request and response type of the HTTP API, in one place, one file
//! per endpoint group (as text-embeddings-inference keeps its router's in
//! `http/types.rs`). Handlers in [`crate::api`] turn them into core types
//! and back; `openapi.yaml` describes them.
//!
//! Still core types on the wire (to be mirrored here): `Strategy`,
//! `Attempt`, `BasePose`, `TimedPoint`, `Candidate`, `Noise`, `Prior`,
//! `ContactModel`, the identification report (`Status`, `Scale`,
//! `FitReport`, `Rejected`), `LoadMargin`, `PeakStress`, `SolverReport`.

pub mod domain;
pub mod identify;
pub mod models;
pub mod objective;
pub mod plan;
pub mod predict;
pub mod robots;
pub mod scene;
pub mod shape;
pub mod simulate;
pub mod tree;
pub mod v2;

pub use domain::Warning;
pub use identify::{
    IdentifyRequest, IdentifyResponse, ProbeJson, ProbesRequest, ProbesResponse, ProposedProbeJson,
};
pub use models::ModelInfo;
pub use objective::{LimitsJson, LoadsJson, ObjectiveJson};
pub use plan::{PlanRequest, PlanResponse};
pub use predict::{ForwardRequest, ForwardResponse, PolicyRequest, PolicyResponse};
pub use robots::{
    BaseRegionJson, JointLimitsJson, RobotJson, RobotJsonInfo, RobotsResponse, ToolFrameJson,
};
pub use scene::{
    BaseJson, LinkJson, LinkPosesRequest, LinkPosesResponse, LinkShapeJson, TreeResponse,
    UrdfRequest,
};
pub use shape::ShapeJson;
pub use simulate::{SimulateRequest, SimulateResponse};
pub use tree::TreeJson;
