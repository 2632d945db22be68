//! `/v1/trees/urdf`, `/v1/trees/example` and `/v1/robot/link-poses`.

use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};

use crate::api::types::motion::BasePoseJson;
use crate::api::types::schema::{Joints, Pose, Vec3, angle};
use crate::api::types::shape::ShapeJson;
use crate::api::types::tree::TreeJson;

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct UrdfRequest {
    /// A tree URDF document as `treemanip` writes it.
    pub urdf: String,
}

/// `GET /v1/trees/example`'s query. The handler reads it as text so that a
/// bad value is a 422 naming the parameter; this type documents it.
#[derive(Debug, Clone, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
pub struct ExampleQuery {
    /// Nodes of the tree (at most the server's `--max-nodes`).
    #[param(minimum = 4, maximum = 512, default = 15)]
    pub nodes: Option<u32>,
    /// The generator's seed: the same `nodes` and `seed` always give the
    /// same tree.
    #[param(schema_with = seed)]
    pub seed: Option<u64>,
}

/// Any u64 (the derive would say `int64`, whose range is half of it).
fn seed() -> utoipa::openapi::schema::Object {
    use utoipa::openapi::schema::{ObjectBuilder, Type};
    ObjectBuilder::new()
        .schema_type(Type::Integer)
        .minimum(Some(0))
        .maximum(Some(u64::MAX))
        .default(Some(0.into()))
        .build()
}

#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct TreeResponse {
    pub tree: TreeJson,
    /// How many nodes the tree has.
    pub nodes: usize,
    /// The generator's seed (examples only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
}

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = Base)]
pub struct BaseJson {
    /// m, tree frame.
    #[schema(value_type = Vec3)]
    pub position: Vec<f64>,
    /// Rotation about the vertical axis (rad).
    #[serde(default)]
    #[schema(schema_with = angle)]
    pub yaw: f64,
    /// Tilt of a tilted or hanging mount (rad; see `robot.base_rpy`).
    #[serde(default)]
    #[schema(schema_with = angle)]
    pub roll: f64,
    #[serde(default)]
    #[schema(schema_with = angle)]
    pub pitch: f64,
}

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct LinkPosesRequest {
    /// Which arm (`GET /v1/robots`); default the server's default robot.
    #[serde(default)]
    pub robot: Option<String>,
    /// Where the arm stands (`/v1/plan`'s `base`); default the paper's mount.
    #[serde(default)]
    pub base: Option<BaseJson>,
    /// Joint configurations (rad), e.g. a plan's trajectory's.
    #[schema(value_type = Vec<Joints>, min_items = 1, max_items = 2048)]
    pub configurations: Vec<Vec<f64>>,
}

#[derive(Debug, Clone, Serialize, ToSchema)]
#[schema(as = Link)]
pub struct LinkJson {
    pub name: String,
    /// Index of the parent link (`null` for the root).
    #[schema(required = true)]
    pub parent: Option<usize>,
    /// Its collision shapes, in its frame.
    pub shapes: Vec<ShapeJson>,
}

#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct LinkPosesResponse {
    pub base: BasePoseJson,
    /// The arm these are the links of.
    pub robot: String,
    pub joint_names: Vec<String>,
    pub links: Vec<LinkJson>,
    /// Per configuration, per link: world pose.
    #[schema(value_type = Vec<Vec<Pose>>)]
    pub poses: Vec<Vec<[f64; 7]>>,
}
