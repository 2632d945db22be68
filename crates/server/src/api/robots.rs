//! `GET /v1/robots`: the arms this server plans for
//! ([`crate::api::robot_planners::RobotPlanners`]).

use axum::extract::State;
use treemanip_core::robot::Arm;

use super::state::AppState;
use crate::api::types::{JointLimitsJson, RobotJsonInfo, RobotsResponse, ToolFrameJson};

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
            tool_chosen: arm.tool_chosen().to_owned(),
            base_link: arm.base_link().to_owned(),
            home: arm.home().to_vec(),
            closed_form_ik: arm.has_closed_form_ik(),
            default,
        }
    }
}

/// The arms this server plans for.
///
/// The built-in `ur5` and every arm the server was started with (`--robot
/// NAME=PATH`, `TREEMANIP_ROBOTS`); `default` marks the one a request without
/// `robot.name` gets. Limits are rad (m for a prismatic joint), per s, per
/// s²; `tool_frame` is the pusher's tool frame in `tool_link`'s frame.
#[utoipa::path(get, path = "/v1/robots", tag = "planning",
    responses(
    (status = 200, description = "Robots.", body = RobotsResponse),
))]
pub async fn robots(State(state): State<AppState>) -> axum::Json<RobotsResponse> {
    let set = &state.robots;
    axum::Json(RobotsResponse {
        robots: set
            .planners()
            .map(|(name, p)| RobotJsonInfo::of(p.robot(), name == set.default_name()))
            .collect(),
    })
}
