//! The arms this server plans for ([`RobotPlanners`], one planner each:
//! the built-in `ur5` and every `--robot`), and `GET /v1/robots`.

use std::sync::Arc;

use axum::extract::State;
use serde::Serialize;
use serde_json::json;
use treemanip_core::planner::Planner;
use treemanip_core::robot::catalog::BUILT_IN;
use treemanip_core::robot::collision::CollisionModel;
use treemanip_core::robot::{Arm, ur5};

use super::error::ApiError;
use super::state::AppState;

/// The planners by robot name, with the default one.
#[derive(Clone)]
pub struct RobotPlanners {
    entries: Vec<(String, Arc<Planner>)>,
    default: usize,
}

impl Default for RobotPlanners {
    /// The built-in UR5 alone.
    fn default() -> Self {
        Self {
            entries: vec![(BUILT_IN.to_owned(), Arc::default())],
            default: 0,
        }
    }
}

impl RobotPlanners {
    /// The built-in UR5 and `arms` (each at the default mount); the first
    /// of `arms` becomes the default. An arm named `ur5` replaces the
    /// built-in one.
    pub fn new(arms: Vec<Arm>) -> Self {
        let mut out = Self::default();
        for (k, arm) in arms.into_iter().enumerate() {
            let name = arm.name().to_owned();
            let planner = Arc::new(Planner::new(CollisionModel::new(
                arm.with_base(ur5::default_base()),
            )));
            let at = match out.entries.iter().position(|(n, _)| *n == name) {
                Some(i) => {
                    out.entries[i].1 = planner;
                    i
                }
                None => {
                    out.entries.push((name, planner));
                    out.entries.len() - 1
                }
            };
            if k == 0 {
                out.default = at;
            }
        }
        out
    }

    /// The planner of robot `name` (default: the default robot), or 422
    /// naming the robots there are.
    pub fn get(&self, name: Option<&str>, field: &str) -> Result<Arc<Planner>, ApiError> {
        let Some(name) = name else {
            return Ok(self.entries[self.default].1.clone());
        };
        self.entries
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, p)| p.clone())
            .ok_or_else(|| {
                let names: Vec<&str> = self.entries.iter().map(|(n, _)| n.as_str()).collect();
                ApiError::invalid_argument(format!(
                    "unknown robot `{name}`; this server plans for: {}",
                    names.join(", ")
                ))
                .with_details(json!({ "field": field, "robots": names }))
            })
    }

    /// The default robot's name.
    pub fn default_name(&self) -> &str {
        &self.entries[self.default].0
    }

    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.entries.iter().map(|(n, _)| n.as_str())
    }
}

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
            .entries
            .iter()
            .enumerate()
            .map(|(k, (_, p))| RobotJsonInfo::of(p.robot(), k == set.default))
            .collect(),
    })
}
