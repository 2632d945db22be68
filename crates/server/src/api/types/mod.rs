//! Every request and response type of the HTTP API, in one place, one file
//! per endpoint group (as text-embeddings-inference keeps its router's in
//! `http/types.rs`). Handlers in [`crate::api`] turn them into core types
//! and back; the OpenAPI document is derived from them
//! ([`crate::api::openapi`]), with [`schema`] for what a derive cannot
//! state.
//!
//! No core type is serialized as an answer or read as a request: each
//! has a mirror here (`StrategyJson`, `AttemptJson`, `ContactJson`, ...),
//! converted with `From` at the edge, so a change in the library never
//! changes the wire by itself.

pub mod domain;
pub mod error;
pub mod identify;
pub mod models;
pub mod motion;
pub mod objective;
pub mod plan;
pub mod predict;
pub mod robots;
pub mod scan;
pub mod scene;
pub mod schema;
pub mod service;
pub mod shape;
pub mod simulate;
pub mod tree;
pub mod v2;

pub use domain::Warning;
pub use identify::{
    IdentifyRequest, IdentifyResponse, NoiseJson, PriorJson, ProbeJson, ProbesRequest,
    ProbesResponse, ProposedProbeJson,
};
pub use models::ModelInfo;
pub use motion::{
    AttemptJson, BasePoseJson, ClearanceJson, JointTrajectoryJson, LimitsAnswer, OutcomeJson,
    StrategyJson, TimedPointJson,
};
pub use objective::{LimitsJson, LoadsJson, ObjectiveJson};
pub use plan::{PlanRequest, PlanResponse};
pub use predict::{ForwardRequest, ForwardResponse, PolicyRequest, PolicyResponse};
pub use robots::{
    BaseRegionJson, JointLimitsJson, RobotJson, RobotJsonInfo, RobotsResponse, ToolFrameJson,
};
pub use scan::{
    CropJson, DroppedJson, FoliageJson, FromPointsQuery, FromPointsRequest, FromPointsResponse,
    SensorJson,
};
pub use scene::{
    BaseJson, LinkJson, LinkPosesRequest, LinkPosesResponse, TreeResponse, UrdfRequest,
};
pub use shape::ShapeJson;
pub use simulate::{ContactJson, GuardedJson, SimulateRequest, SimulateResponse};
pub use tree::TreeJson;
