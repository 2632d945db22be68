//! The planner's answer: the plan, every push looked at and what became
//! of it, and why planning could not start.

use serde::Serialize;

use crate::identify::Identification;
use crate::planner::base::BasePose;
use crate::planner::objective::Limits;
use crate::planner::predict::PredictError;
use crate::planner::query::Strategy;
use crate::robot::motion::push_motion::{Outcome, PushPlan};
use crate::robot::motion::rrt::Config;
use crate::sim::loads::PushLoads;

/// One push the planner looked at, and what became of it.
#[derive(Debug, Clone, Serialize)]
pub struct Attempt {
    pub node: usize,
    /// The node's rank in the policy's ranking (1 = best).
    pub rank: usize,
    pub push: [f64; 3],
    pub outcome: Outcome,
    /// The objective's predicted residual after it (m).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub predicted_error: Option<f64>,
    /// Loads the search predicted for it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub predicted_loads: Option<PushLoads>,
    /// Loads the simulation of its execution gave (when it got that far).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub simulated_loads: Option<PushLoads>,
    pub ms: f64,
}

/// The planner's answer.
#[derive(Debug, Clone, Serialize)]
pub struct Plan {
    pub strategy: Strategy,
    /// The objective's kind (`shape`, `clear`, `reach`).
    pub objective: &'static str,
    /// The chosen push, its approach and push trajectory.
    pub plan: Option<PushPlan>,
    /// Where the arm stands (the given base, or the one chosen).
    pub base: BasePose,
    /// The start configuration the trajectory begins at.
    pub start: Config,
    /// Whether the planner chose `start` (no start given, base region).
    pub start_chosen: bool,
    /// The objective's predicted residual after the chosen push (m);
    /// `None` for `paper`, which does not predict.
    pub predicted_error: Option<f64>,
    /// The objective's residual if nothing is done (m).
    pub no_action_error: f64,
    /// The chosen push's predicted loads (`None` for `paper`).
    pub predicted_loads: Option<PushLoads>,
    /// The chosen push's loads as the simulator gives them (the
    /// simulation its push line was checked with).
    pub simulated_loads: Option<PushLoads>,
    /// The limits enforced (`None` for `paper` or without limits).
    pub limits: Option<Limits>,
    /// The wrist force (N) at which the arm should stop the chosen push
    /// ([`Limits::guard_force`]): `None` without a plan or without limits.
    pub guard_contact_force: Option<f64>,
    /// For `clear`, the clearance the chosen push reaches between branches
    /// and regions (m, negative: overlapping): predicted, and simulated.
    pub clearance: Option<Clearance>,
    /// Pushes predicted by the search.
    pub evaluations: usize,
    pub attempts: Vec<Attempt>,
    pub total_ms: f64,
    /// With observations: the stiffness identified from them, which the
    /// plan was made with.
    #[serde(skip)]
    pub identification: Option<Identification>,
}

#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    #[error("the start configuration collides with the tree, an obstacle, the ground or itself")]
    StartInCollision,
    #[error("the forward model is needed for the `model` strategy and is not loaded")]
    NoForwardModel,
    #[error("inference failed: {0}")]
    Predict(#[from] PredictError),
    #[error(
        "the `paper` strategy plans only `shape` objectives (the contact policy was trained for target shapes); use `model` or `physics` for `{0}`"
    )]
    PaperNeedsShape(&'static str),
}

/// The clearance a `clear` plan reaches (m; negative: overlapping).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Clearance {
    pub predicted: Option<f64>,
    pub simulated: Option<f64>,
}
