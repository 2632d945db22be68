//! The arms: `GET /v1/robots`' answer, and the `robot` block of `/v1/plan`
//! and `/v1/identify/probes` requests (which arm, where it stands).

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::types::schema::{Joints, Vec3, base_rpy, string_enum};

/// One joint's limits (rad, or m for a prismatic joint; per s, per s²).
#[derive(Debug, Serialize, ToSchema)]
#[schema(as = JointLimits)]
pub struct JointLimitsJson {
    pub name: String,
    #[schema(schema_with = joint_kind)]
    pub kind: &'static str,
    /// Null: unbounded (continuous).
    #[schema(required = true)]
    pub lower: Option<f64>,
    #[schema(required = true)]
    pub upper: Option<f64>,
    pub velocity: f64,
    pub acceleration: f64,
    #[schema(required = true)]
    pub jerk: Option<f64>,
}

fn joint_kind() -> utoipa::openapi::schema::Schema {
    string_enum(&["revolute", "continuous", "prismatic"], None)
}

/// An arm this server plans for.
#[derive(Debug, Serialize, ToSchema)]
#[schema(as = RobotInfo)]
pub struct RobotJsonInfo {
    pub name: String,
    #[schema(minimum = 1, maximum = 8)]
    pub dof: usize,
    pub joint_names: Vec<String>,
    pub limits: Vec<JointLimitsJson>,
    /// The link the tool frame hangs from (the chain's tip).
    pub tool_link: String,
    /// The tool frame in `tool_link`'s frame: [x, y, z] (m) and
    /// [roll, pitch, yaw] (rad).
    pub tool_frame: ToolFrameJson,
    /// How the tool frame was chosen: `flange axis: joint J, D m past it,
    /// along|against its axis` (a bare URDF's default: the last revolute
    /// joint's axis pointing out of the wrist, past what it carries),
    /// `frame NAME` (`tool=NAME`), `configured` (a robot configuration's
    /// `[tool]`), `built in: ...` (the built-in UR5); `, adjusted by
    /// tool_xyz/tool_rpy` when those moved it.
    pub tool_chosen: String,
    pub base_link: String,
    /// The home configuration (the default start).
    #[schema(value_type = Joints)]
    pub home: Vec<f64>,
    /// Whether inverse kinematics is the UR closed form.
    pub closed_form_ik: bool,
    /// The arm a request without `robot.name` gets.
    pub default: bool,
}

/// A frame relative to a link: [x, y, z] (m) and [roll, pitch, yaw] (rad).
#[derive(Debug, Serialize, ToSchema)]
#[schema(as = ToolFrame)]
pub struct ToolFrameJson {
    #[schema(value_type = Vec3)]
    pub xyz: [f64; 3],
    #[schema(value_type = Vec3)]
    pub rpy: [f64; 3],
}

/// The built-in `ur5` and every arm the server was started with
/// (`--robot NAME=PATH`, `TREEMANIP_ROBOTS`); `default` marks the one a
/// request without `robot.name` gets. Limits are rad (m for a prismatic
/// joint), per s, per s²; `tool_frame` is the pusher's tool frame in
/// `tool_link`'s frame.
#[derive(Debug, Serialize, ToSchema)]
pub struct RobotsResponse {
    pub robots: Vec<RobotJsonInfo>,
}

/// A box (m, within 5 m of the root, min ≤ max) the planner may place the
/// base in, and optionally a range of headings about the vertical axis
/// (rad, within ±2π).
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BaseRegion)]
pub struct BaseRegionJson {
    #[schema(value_type = Vec3)]
    pub min: Vec<f64>,
    #[schema(value_type = Vec3)]
    pub max: Vec<f64>,
    /// The range of headings [from, to] (rad).
    #[serde(default)]
    #[schema(min_items = 2, max_items = 2)]
    pub yaw: Option<Vec<f64>>,
}

/// Which arm, and where it stands. Give `base` or `base_region`, not both
/// (422).
#[derive(Debug, Clone, Default, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = Robot)]
pub struct RobotJson {
    /// Which arm plans (`GET /v1/robots`); default the server's default
    /// robot (the built-in `ur5` unless the server was started with
    /// `--robot`). An unknown name is a 422 listing the robots.
    #[serde(default)]
    pub name: Option<String>,
    /// Arm base position (m, within 5 m of the root); default
    /// [-0.5, 0, 0.1].
    #[serde(default)]
    #[schema(value_type = Option<Vec3>)]
    pub base: Option<Vec<f64>>,
    /// The fixed base's orientation (described in the schema).
    #[serde(default)]
    #[schema(schema_with = base_rpy)]
    pub base_rpy: Option<Vec<f64>>,
    /// A box the planner may place the base in (instead of `base`).
    #[serde(default)]
    pub base_region: Option<BaseRegionJson>,
    /// Start joints of the named robot; default its home (the UR5's is
    /// the paper's), or the first collision-free tucked pose.
    #[serde(default)]
    #[schema(value_type = Option<Joints>)]
    pub start: Option<Vec<f64>>,
}
