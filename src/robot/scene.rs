//! The arm among the tree: which configurations and joint-space edges are
//! collision-free, conservatively.
//!
//! An edge is checked at poses spaced so that no point of the robot moves
//! more than `resolution` (δ) between two of them: between poses a point
//! moves at most Σ_i R_i |Δq_i|, where R_i bounds the distance of any robot
//! point from joint i's axis ([`LEVER_ARMS`]). Every robot shape is grown by
//! δ/2 in these checks, so each pose between two samples is covered by a
//! checked, inflated pose: a path accepted here is free at any finer
//! resolution.

use super::collision::{Allowed, CollisionModel, Hit, TreeObstacles};
use super::rrt::{Config, MotionValidator};
use super::ur5::{DH_A, DH_D, FINGER_LENGTH, TOOL_OFFSET};

/// Largest capsule radius plus the gripper's half width, added to the
/// kinematic reach to bound every collision shape (m).
const SHAPE_SLACK: f64 = 0.1;

/// R_i: an upper bound on the distance from joint i's axis to any point of
/// the robot's collision shapes (m), from the chain of DH lengths beyond it.
pub const LEVER_ARMS: [f64; 6] = {
    let tool = TOOL_OFFSET + FINGER_LENGTH + SHAPE_SLACK;
    let wrist = DH_D[4] + DH_D[5] + tool;
    let forearm = -DH_A[2] + DH_D[3] + wrist;
    let arm = -DH_A[1] + forearm;
    [arm, arm, forearm, wrist, DH_D[5] + tool, tool]
};

/// Default edge-check resolution δ (m): no robot point moves more than this
/// between checked poses; shapes are grown by δ/2.
pub const DEFAULT_RESOLUTION: f64 = 0.01;

#[derive(Debug, Clone)]
pub struct PlanningScene<'a> {
    pub model: &'a CollisionModel,
    pub obstacles: &'a TreeObstacles,
    pub allowed: Allowed,
    pub resolution: f64,
}

impl<'a> PlanningScene<'a> {
    pub fn new(model: &'a CollisionModel, obstacles: &'a TreeObstacles, allowed: Allowed) -> Self {
        Self {
            model,
            obstacles,
            allowed,
            resolution: DEFAULT_RESOLUTION,
        }
    }

    /// What `q` hits with the planning margin, if anything.
    pub fn hit(&self, q: &Config) -> Option<Hit> {
        self.model
            .check_with_margin(q, self.obstacles, &self.allowed, self.resolution / 2.0)
    }

    /// Number of intervals an edge is checked in: the sweep Σ_i R_i |Δq_i|
    /// over the resolution, with R_i joint i's reach at `a`
    /// ([`CollisionModel::axis_reach`]) plus how far the joints beyond it
    /// can carry a point away from its axis during the edge
    /// (Σ_{j>i} R_j^max |Δq_j|, with [`LEVER_ARMS`] as R^max), never more
    /// than the configuration-free bound. Joints before i move a point and
    /// joint i's axis together, so they do not change that distance.
    pub fn edge_intervals(&self, a: &Config, b: &Config) -> usize {
        let dq: [f64; 6] = std::array::from_fn(|i| (b[i] - a[i]).abs());
        let reach = self.model.axis_reach(a, self.resolution / 2.0);
        let sweep: f64 = (0..6)
            .map(|i| {
                let drift: f64 = (i + 1..6).map(|j| LEVER_ARMS[j] * dq[j]).sum();
                (reach[i] + drift).min(LEVER_ARMS[i]) * dq[i]
            })
            .sum();
        (sweep / self.resolution).ceil().max(1.0) as usize
    }
}

impl MotionValidator for PlanningScene<'_> {
    fn config_valid(&self, q: &Config) -> bool {
        self.hit(q).is_none()
    }

    /// Checks the same poses as a sweep from `a` to `b`, but coarse to fine
    /// (the end, the middle, the quarters, …), so an edge through an
    /// obstacle is usually rejected after a few checks.
    fn edge_valid(&self, a: &Config, b: &Config) -> bool {
        let steps = self.edge_intervals(a, b);
        let at = |k: usize| -> Config {
            let t = k as f64 / steps as f64;
            std::array::from_fn(|i| a[i] + (b[i] - a[i]) * t)
        };
        if !self.config_valid(&at(steps)) {
            return false;
        }
        let mut stride = steps.next_power_of_two();
        while stride > 1 {
            let half = stride / 2;
            let mut k = half;
            while k < steps {
                if !self.config_valid(&at(k)) {
                    return false;
                }
                k += stride;
            }
            stride = half;
        }
        true
    }
}
