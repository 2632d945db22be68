//! The arms: `GET /v1/robots`' answer, and the `robot` block of `/v1/plan`
//! and `/v1/identify/probes` requests (which arm, where it stands).

use serde::{Deserialize, Serialize};

/// One joint's limits (rad, or m for a prismatic joint; per s, per s²).
#[derive(Debug, Serialize)]
pub struct JointLimitsJson {
    pub name: String,
    pub kind: &'static str,
    pub lower: Option<f64>,
    pub upper: Option<f64>,
    pub velocity: f64,
    pub acceleration: f64,
    pub jerk: Option<f64>,
}

#[derive(Debug, Serialize)]
pub struct RobotJsonInfo {
    pub name: String,
    pub dof: usize,
    pub joint_names: Vec<String>,
    pub limits: Vec<JointLimitsJson>,
    /// The link the tool frame hangs from (the chain's tip).
    pub tool_link: String,
    /// The tool frame in `tool_link`'s frame: [x, y, z] (m) and
    /// [roll, pitch, yaw] (rad).
    pub tool_frame: ToolFrameJson,
    pub base_link: String,
    /// The home configuration (the default start).
    pub home: Vec<f64>,
    /// Whether inverse kinematics is the UR closed form.
    pub closed_form_ik: bool,
    pub default: bool,
}

#[derive(Debug, Serialize)]
pub struct ToolFrameJson {
    pub xyz: [f64; 3],
    pub rpy: [f64; 3],
}

#[derive(Debug, Serialize)]
pub struct RobotsResponse {
    pub robots: Vec<RobotJsonInfo>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BaseRegionJson {
    pub min: Vec<f64>,
    pub max: Vec<f64>,
    #[serde(default)]
    pub yaw: Option<Vec<f64>>,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotJson {
    /// Which arm plans (`GET /v1/robots`); default the server's default
    /// robot (the built-in `ur5` unless `--robot` was given).
    #[serde(default)]
    pub name: Option<String>,
    /// Arm base position (m); default (−0.5, 0, 0.1).
    #[serde(default)]
    pub base: Option<Vec<f64>>,
    /// The fixed base's orientation [roll, pitch, yaw] (rad, the URDF's
    /// convention); default upright, facing +x. Roll π hangs the arm.
    #[serde(default)]
    pub base_rpy: Option<Vec<f64>>,
    /// A box the planner may place the base in (instead of `base`).
    #[serde(default)]
    pub base_region: Option<BaseRegionJson>,
    /// Start joint configuration (rad, or m for prismatic joints), one
    /// value per joint of the arm; default the arm's home.
    #[serde(default)]
    pub start: Option<Vec<f64>>,
}
