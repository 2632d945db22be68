//! `GET /v1/robots`: the arms this server plans for
//! ([`crate::api::robot_planners::RobotPlanners`]).

use axum::extract::State;
use serde::Serialize;
use treemanip_core::robot::Arm;

use super::state::AppState;

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

impl RobotJsonInfo {
    fn of(arm: &Arm, default: bool) -> Self {
        let tool = arm.tool_in_tip();
        let t = tool.translation.vector;
        let (r, p, y) = tool.rotation.euler_angles();
        let finite = |x: f64| x.is_finite().then_some(x);
        Self {
            name: arm.name().to_owned(),
            dof: arm.dof(),
            joint_names: arm.joint_names().map(str::to_owned).collect(),
            limits: arm
                .joints()
                .iter()
                .map(|j| JointLimitsJson {
                    name: j.name.clone(),
                    kind: j.kind.name(),
                    lower: finite(j.lower),
                    upper: finite(j.upper),
                    velocity: j.velocity,
                    acceleration: j.acceleration,
                    jerk: j.jerk,
                })
                .collect(),
            tool_link: arm.tip_link().to_owned(),
            tool_frame: ToolFrameJson {
                xyz: [t.x, t.y, t.z],
                rpy: [r, p, y],
            },
            base_link: arm.base_link().to_owned(),
            home: arm.home().to_vec(),
            closed_form_ik: arm.has_closed_form_ik(),
            default,
        }
    }
}

/// `GET /v1/robots`: every arm this server plans for.
pub async fn robots(State(state): State<AppState>) -> axum::Json<RobotsResponse> {
    let set = &state.robots;
    axum::Json(RobotsResponse {
        robots: set
            .planners()
            .map(|(name, p)| RobotJsonInfo::of(p.robot(), name == set.default_name()))
            .collect(),
    })
}
