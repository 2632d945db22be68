//! `/v1/trees/urdf`, `/v1/trees/example` and `/v1/robot/link-poses`.

use crate::api::types::motion::BasePoseJson;
use serde::{Deserialize, Serialize};

use crate::api::types::tree::TreeJson;

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UrdfRequest {
    /// A tree URDF document as `treemanip` writes it.
    pub urdf: String,
}

#[derive(Debug, Clone, Serialize)]
pub struct TreeResponse {
    pub tree: TreeJson,
    pub nodes: usize,
    /// The generator's seed (examples only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BaseJson {
    /// m, tree frame.
    pub position: Vec<f64>,
    /// Rotation about the vertical axis (rad).
    #[serde(default)]
    pub yaw: f64,
    /// Tilt of a tilted or hanging mount (rad; see `robot.base_rpy`).
    #[serde(default)]
    pub roll: f64,
    #[serde(default)]
    pub pitch: f64,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinkPosesRequest {
    /// Which arm (`GET /v1/robots`); default the server's default robot.
    #[serde(default)]
    pub robot: Option<String>,
    /// Where the arm stands (`/v1/plan`'s `base`); default the paper's mount.
    #[serde(default)]
    pub base: Option<BaseJson>,
    /// Joint configurations (rad), e.g. a plan's trajectory.
    pub configurations: Vec<Vec<f64>>,
}

/// A collision shape in its link's frame (m).
#[derive(Debug, Clone, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum LinkShapeJson {
    /// The capsule around segment a–b.
    Capsule {
        a: [f64; 3],
        b: [f64; 3],
        radius: f64,
    },
    /// A box: its centre's pose `[x, y, z, qx, qy, qz, qw]` and half extents.
    Box {
        pose: [f64; 7],
        half_extents: [f64; 3],
    },
    /// A cylinder along the local z axis of its centre's pose.
    Cylinder {
        pose: [f64; 7],
        radius: f64,
        half_length: f64,
    },
}

#[derive(Debug, Clone, Serialize)]
pub struct LinkJson {
    pub name: String,
    /// Index of the parent link (`null` for the root).
    pub parent: Option<usize>,
    pub shapes: Vec<LinkShapeJson>,
}

#[derive(Debug, Clone, Serialize)]
pub struct LinkPosesResponse {
    pub base: BasePoseJson,
    /// The arm these are the links of.
    pub robot: String,
    pub joint_names: Vec<String>,
    pub links: Vec<LinkJson>,
    /// Per configuration, per link: world pose `[x, y, z, qx, qy, qz, qw]`.
    pub poses: Vec<Vec<[f64; 7]>>,
}
