//! RRT* in joint space (Karaman & Frazzoli 2011), with several goal
//! configurations at once, then shortcut smoothing.
//!
//! - Samples uniformly inside a box around the start and the goals (each
//!   joint's range widened by `sampling_margin`, within the joint limits),
//!   or (with probability `goal_bias`) one of the goals. Sampling all of
//!   ±2π on six joints wastes nearly every sample on wrapped-around arm
//!   poses far from both ends.
//! - Steers at most `max_step` (rad, Euclidean in joint space) from the
//!   nearest node.
//! - Chooses the cheapest collision-free parent among the nodes within
//!   r_n = min(γ (ln n / n)^{1/6}, `max_step`), then rewires those
//!   neighbours through the new node when that is cheaper. Cost is joint-
//!   space path length, so the best cost never increases with iterations.
//! - Tries the direct edge to each goal first, nearest goal first, and
//!   stops at the iteration or time budget, `refine_iterations` after the
//!   first solution, or at once when a path is as short as the straight
//!   line to the nearest goal (nothing can beat it).
//!
//! - By default edges are evaluated lazily (`lazy`): checked only when a
//!   path through them is about to be used (`lazy: false` keeps the
//!   textbook algorithm, which checks every edge as it is added).
//!
//! The validity of configurations and edges is the caller's
//! [`MotionValidator`]; [`crate::robot::motion::scene::PlanningScene`] is the one used for
//! the arm. The random stream is ChaCha8 from `seed`, so a plan with the
//! same inputs and seed (and no time budget hit) is reproduced exactly.

mod lazy;
mod problem;
mod shortcut;
mod star;

pub use problem::{
    Config, MotionValidator, RrtError, RrtPath, RrtStarOptions, RrtStats, distance, path_cost,
};
pub use shortcut::shortcut;
pub use star::rrt_star;
