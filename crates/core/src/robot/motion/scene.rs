//! The arm among the tree: which configurations and joint-space edges are
//! collision-free, conservatively.
//!
//! A configuration is free when every robot shape, grown by δ/2
//! (`resolution / 2`), touches nothing. An edge is free when conservative
//! advancement ([`PlanningScene::edge_check`]) proves it: each checked pose's
//! clearances, with a bound on how fast every shape can move along the edge,
//! clear a stretch of it, so an edge far from everything needs a few poses
//! and an edge that grazes something is refined where it grazes. Every pose
//! of an accepted edge is free with no margin.

use crate::robot::collision::{Allowed, CollisionModel, Hit, TreeObstacles};
use crate::robot::motion::rrt::{Config, MotionValidator};

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
    /// (Σ_{j>i} R_j^max |Δq_j|, with [`CollisionModel::lever_arms`] as R^max), never more
    /// than the configuration-free bound. Joints before i move a point and
    /// joint i's axis together, so they do not change that distance.
    pub fn edge_intervals(&self, a: &Config, b: &Config) -> usize {
        let dof = a.len();
        let dq = Config::from_fn(dof, |i| (b[i] - a[i]).abs());
        let reach = self.model.axis_reach(a, self.resolution / 2.0);
        let lever = self.model.lever_arms();
        let sweep: f64 = (0..dof)
            .map(|i| {
                let drift: f64 = (i + 1..dof).map(|j| lever[j] * dq[j]).sum();
                (reach[i] + drift).min(lever[i]) * dq[i]
            })
            .sum();
        (sweep / self.resolution).ceil().max(1.0) as usize
    }
}

impl PlanningScene<'_> {
    /// The straight edge `a` → `b` by conservative advancement: from each
    /// end in turn, the pose's clearances and the shapes' sweep rates
    /// ([`CollisionModel::free_span`]) prove a stretch of the edge free, and
    /// the next pose is checked where that stretch ends, until the stretches
    /// from both ends meet. A pose closer than δ/2 to anything rejects the
    /// edge, as [`Self::hit`] rejects a configuration; so every stretch is
    /// at least δ/(2 × the fastest shape's rate) long and the walk ends.
    /// Every pose of an accepted edge is free with no margin.
    pub fn edge_check(&self, a: &Config, b: &Config) -> EdgeCheck {
        let rates = self.model.sweep_rates(a, b);
        let mut poses = 0;
        if rates.max() <= 0.0 {
            return EdgeCheck { free: true, poses };
        }
        let at = |t: f64| -> Config { a.lerp(b, t) };
        // Most blocked edges are blocked in the middle: a plain check there
        // rejects them before the walk from the ends.
        poses += 1;
        if !self.config_valid(&at(0.5)) {
            return EdgeCheck { free: false, poses };
        }
        let (mut lo, mut hi) = (0.0, 1.0);
        let min_clearance = self.resolution / 2.0;
        let mut from_start = true;
        while lo < hi {
            let t = if from_start { lo } else { hi };
            poses += 1;
            let Some(span) = self.model.free_span(
                &at(t),
                self.obstacles,
                &self.allowed,
                &rates,
                hi - lo,
                min_clearance,
            ) else {
                return EdgeCheck { free: false, poses };
            };
            if from_start {
                lo += span;
            } else {
                hi -= span;
            }
            from_start = !from_start;
        }
        EdgeCheck { free: true, poses }
    }

    /// The straight edge checked the textbook way: poses spaced by
    /// [`Self::edge_intervals`], coarse to fine, each with margin δ/2
    /// (kept for comparison; [`Self::edge_check`] is the one used).
    pub fn edge_valid_fixed_step(&self, a: &Config, b: &Config) -> bool {
        let steps = self.edge_intervals(a, b);
        let at = |k: usize| -> Config {
            let t = k as f64 / steps as f64;
            a.lerp(b, t)
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

/// The outcome of one edge check, with its cost.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EdgeCheck {
    pub free: bool,
    /// Poses whose clearance was measured.
    pub poses: usize,
}

impl MotionValidator for PlanningScene<'_> {
    fn config_valid(&self, q: &Config) -> bool {
        self.hit(q).is_none()
    }

    /// [`PlanningScene::edge_check`]: `a` must be valid (as RRT* ensures).
    fn edge_valid(&self, a: &Config, b: &Config) -> bool {
        self.edge_check(a, b).free
    }

    fn joint_limits(&self) -> Vec<(f64, f64)> {
        self.model.robot.limits()
    }
}
