//! Planning a push that serves an objective: the one entry point used by
//! `/v1/plan`, `treemanip plan` and `treemanip eval plan` / `eval tasks`.
//!
//! It composes the contact policy (`treemanip-infer`), a predictor of what a
//! push does (the forward model or the simulator, [`predict`]), and the arm
//! ([`crate::robot`]):
//! 1. for a full target shape the policy ranks the nodes and proposes a
//!    push T_j for each; for other objectives ([`objective`]) the tree's
//!    geometry proposes them ([`seeds`]);
//! 2. `paper` (Algorithm 1 as published) walks the policy's ranking;
//!    `model` and `physics` search the push of the top nodes ([`search`]),
//!    pruned by the cheap reachability test
//!    ([`crate::robot::motion::push_motion::reach`]), scored by the objective's predicted
//!    residual, pushes over the load [`Limits`] refused;
//! 3. the best push is executed: its straight push against the deforming
//!    tree (whose simulated loads are checked against the limits again),
//!    then RRT* for the approach, falling back to the next best;
//! 4. with a base region the arm may stand anywhere in it ([`base`]).
//!
//! The documentation beside the code: `docs/tasks.md` (objectives, limits)
//! and `docs/robot.md` (the planner).

pub mod answer;
pub mod base;
mod eased;
mod execute;
pub mod objective;
mod observed;
pub mod placed;
pub mod predict;
pub mod predictive_policy;
mod query;
pub mod refine;
pub mod search;
pub mod seeds;
mod shorter;
mod stages;

pub use crate::geometry::shape::Shape;
pub use answer::{Attempt, Clearance, Plan, PlanError};
pub use objective::{Limits, Objective};
pub use placed::Planner;
pub use predict::{Candidate, ContactPolicy, PredictError, Predictor};
pub use predictive_policy::PredictivePolicy;
pub use query::{
    DEFAULT_CANDIDATES, FIXED_EVALUATION_EDGES, LARGE_TREE_SEARCH_FACTOR, Query,
    REGION_EVALUATION_EDGES, Stance, Strategy, default_evaluations,
};
pub use stages::{DEFAULT_GEOMETRIC_CANDIDATES, FALLBACK_PREDICTIONS};
