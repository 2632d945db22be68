//! Clearance: how far each arm shape is from everything it may not touch,
//! and how long along a joint-space edge that distance keeps the arm free
//! (conservative advancement).
//!
//! Along an edge q(t) = a + t (b − a), t ∈ [0, 1], a point of shape s moves
//! at most `rate_s` per unit t, where `rate_s` bounds Σ_i R_i^s |b_i − a_i|
//! over the edge (R_i^s: the distance of the shape's points from joint i's
//! axis, summed over the joints that move it). A shape at distance d from
//! an obstacle therefore cannot reach it for |Δt| < d / rate_s; two arm
//! shapes close at most at `rate_s + rate_r`. The smallest such span over
//! every pair is a stretch of the edge proven free with no sampling inside
//! it, so an edge far from everything is cleared by a handful of poses where
//! a fixed-step sweep would check dozens.

use std::cell::Cell;

use crate::geometry::world_shape::{WorldShape, WorldShapes, distance};
use crate::robot::arm::JointAxes;
use crate::robot::collision::bounds::from_axis;
use crate::robot::collision::model::{
    Allowed, CollisionModel, GROUND_Z, SELF_CLEARANCE, TreeObstacles,
};
use crate::robot::model::joint_vector::JointVector;

/// How fast each shape can move along one edge, per unit of t.
#[derive(Debug, Clone)]
pub struct SweepRates {
    /// Per shape and joint: how fast that joint's rotation moves the
    /// shape's points (m per unit t); 0 for joints that do not move it.
    by_joint: Vec<JointVector>,
    /// Per shape: the sum over joints, its speed in the world.
    rates: Vec<f64>,
    /// Per self-collision pair of the model: how fast the two approach.
    self_pairs: Vec<f64>,
    /// The pair of shapes (with its approach rate) that limited the last
    /// span measured along this edge ([`CollisionModel::free_span`]).
    limiting: Cell<Option<(Pair, f64)>>,
}

impl SweepRates {
    /// The largest rate of any shape.
    pub fn max(&self) -> f64 {
        self.rates.iter().copied().fold(0.0, f64::max)
    }

    /// How fast shapes `i` and `j` can approach each other: a joint that
    /// moves both carries them rigidly together, so only the joints that
    /// move exactly one of them count (a variable driving a mimic joint
    /// too may move one relative to the other: both rates count).
    fn relative(&self, model: &CollisionModel, i: usize, j: usize) -> f64 {
        let (mi, mj) = (&model.shapes[i].moved_by, &model.shapes[j].moved_by);
        (0..mi.len().min(self.by_joint[i].len()))
            .map(|k| match (mi[k], mj[k]) {
                (true, false) => self.by_joint[i][k],
                (false, true) => self.by_joint[j][k],
                (true, true) if model.drives_several[k] => {
                    self.by_joint[i][k] + self.by_joint[j][k]
                }
                _ => 0.0,
            })
            .sum()
    }
}

impl CollisionModel {
    /// Sweep rates of every shape along the edge `a` → `b`: for each joint
    /// i moving the shape, its reach from i's axis at `a` plus how far the
    /// joints beyond i can carry it away from that axis during the edge
    /// (never more than the arm's lever arm for i), times |b_i − a_i|; a
    /// prismatic joint moves it exactly |b_i − a_i|. Joints before i move
    /// the point and the axis together, so they do not change that
    /// distance.
    pub fn sweep_rates(&self, a: &[f64], b: &[f64]) -> SweepRates {
        let poses = self.robot.link_poses(a);
        let axes: JointAxes = self.robot.joint_axes(&poses);
        let dof = self.robot.dof();
        let dq = JointVector::from_fn(dof, |i| (b[i] - a[i]).abs());
        let lever = &self.lever_arms;
        let by_joint: Vec<JointVector> = self
            .shapes
            .iter()
            .map(|slot| {
                let (points, pad) = slot.shape.bounding_points(&poses[slot.link], 0.0);
                JointVector::from_fn(dof, |i| {
                    if !slot.moved_by[i] || dq[i] == 0.0 {
                        return 0.0;
                    }
                    if self.drives_several[i] {
                        // Turns about more than one axis: its lever arm
                        // bounds every joint it drives together.
                        return lever[i] * dq[i];
                    }
                    if axes[i].2 {
                        return dq[i];
                    }
                    let reach = points
                        .iter()
                        .map(|p| from_axis(&axes[i], p) + pad)
                        .fold(0.0, f64::max);
                    // Joints below i (later variables, and any variable
                    // that also drives a mimic joint, which may sit below i).
                    let below = |j: usize| j > i || (j != i && self.drives_several[j]);
                    let drift: f64 = (0..dof)
                        .filter(|&j| slot.moved_by[j] && below(j))
                        .map(|j| lever[j] * dq[j])
                        .sum();
                    (reach + drift).min(lever[i]) * dq[i]
                })
            })
            .collect();
        let rates = by_joint.iter().map(|r| r.iter().sum()).collect();
        let mut sweep = SweepRates {
            by_joint,
            rates,
            self_pairs: Vec::new(),
            limiting: Cell::new(None),
        };
        sweep.self_pairs = self
            .self_pairs
            .iter()
            .map(|&(i, j)| sweep.relative(self, i, j))
            .collect();
        sweep
    }

    /// How far (in t, at most `horizon`) the arm can move from `q` along an
    /// edge with these sweep rates before anything could touch, or `None`
    /// when some clearance at `q` is below `min_clearance` (m). Only
    /// distances that could shorten the span are computed exactly; the
    /// rest are settled by their bounding boxes. The pair that limited the
    /// last span of the same edge is measured first (it usually limits
    /// this one too, and a short span from the start lets the boxes rule
    /// out nearly every other pair without a distance).
    pub fn free_span(
        &self,
        q: &[f64],
        tree: &TreeObstacles,
        allowed: &Allowed,
        rates: &SweepRates,
        horizon: f64,
        min_clearance: f64,
    ) -> Option<f64> {
        let world = self.world_shapes(q, 0.0);
        // The ground first: exact and cheap, it bounds the span before any
        // pair is looked at.
        let mut span = horizon;
        for (i, (_, aabb)) in world.iter().enumerate() {
            let rate = rates.rates[i];
            // A shape that does not move along this edge is as free as at
            // the edge's start, which the caller has checked.
            if rate > 0.0 && !self.shapes[i].base {
                // Exact: a box's lowest point is its shape's lowest point.
                let d = aabb.min.z - GROUND_Z;
                if d < min_clearance {
                    return None;
                }
                span = span.min(d / rate);
            }
        }
        let hinted = rates.limiting.get();
        if let Some((pair, rate)) = hinted {
            let d = pair.distance(&world, tree);
            if d < pair.clearance(min_clearance) {
                return None;
            }
            span = span.min(d / rate);
        }
        // Pairs whose bounding boxes are close enough to matter, with the
        // span their boxes' distance allows (a lower bound on the true one;
        // −1 for boxes closer than the clearance asked). Anything a shape
        // could reach within the span overlaps its box grown by that much:
        // six comparisons settle most pairs before any distance.
        // Spans are kept squared here to spare a square root per pair.
        let mut pending: smallvec::SmallVec<[(f64, f64, Pair); 64]> = Default::default();
        let mut consider = |lower_squared: f64, rate: f64, pair: Pair| {
            if hinted.is_some_and(|(h, _)| h == pair) {
                // Measured exactly above; the span already allows it.
                return;
            }
            if lower_squared < pair.clearance(min_clearance).powi(2) {
                pending.push((-1.0, rate, pair));
            } else {
                let lower_span_squared = lower_squared / (rate * rate);
                if lower_span_squared < span * span {
                    pending.push((lower_span_squared, rate, pair));
                }
            }
        };
        for (i, (_, aabb)) in world.iter().enumerate() {
            let rate = rates.rates[i];
            if rate <= 0.0 {
                continue;
            }
            let reach = aabb.grown((rate * span).max(min_clearance));
            if !reach.overlaps(&tree.bounds) {
                continue;
            }
            let gripper = self.shapes[i].gripper;
            for (b, (node, _, branch_box)) in tree.branches.iter().enumerate() {
                if reach.overlaps(branch_box)
                    && !(gripper && allowed.gripper_branches.contains(node))
                {
                    consider(aabb.distance_squared(branch_box), rate, Pair::Branch(i, b));
                }
            }
            for (f, (_, obstacle_box)) in tree.fixed.iter().enumerate() {
                if reach.overlaps(obstacle_box) {
                    consider(aabb.distance_squared(obstacle_box), rate, Pair::Fixed(i, f));
                }
            }
        }
        for (k, &(i, j)) in self.self_pairs.iter().enumerate() {
            let rate = rates.self_pairs[k];
            let (box_i, box_j) = (&world[i].1, &world[j].1);
            if rate > 0.0
                && box_i
                    .grown((rate * span).max(min_clearance))
                    .overlaps(box_j)
            {
                consider(box_i.distance_squared(box_j), rate, Pair::Arm(i, j));
            }
        }
        // The most constraining first: once a pair's lower bound allows the
        // span found so far, so do all the rest. Each exact distance can
        // shorten the span, so every scan for the next pair also drops the
        // pairs the span now allows (cheaper than sorting them all).
        loop {
            let mut next: Option<usize> = None;
            let mut x = 0;
            let span_squared = span * span;
            while x < pending.len() {
                if pending[x].0 >= span_squared {
                    pending.swap_remove(x);
                    continue;
                }
                if next.is_none_or(|k| pending[x].0 < pending[k].0) {
                    next = Some(x);
                }
                x += 1;
            }
            let Some(k) = next else { break };
            let (_, rate, pair) = pending.swap_remove(k);
            let d = pair.distance(&world, tree);
            if d < pair.clearance(min_clearance) {
                return None;
            }
            if d / rate < span {
                span = d / rate;
                rates.limiting.set(Some((pair, rate)));
            }
        }
        Some(span)
    }
}

/// A pair of shapes whose distance may limit the span: an arm shape and a
/// branch or fixed obstacle (by index), or two arm shapes.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Pair {
    Branch(usize, usize),
    Fixed(usize, usize),
    Arm(usize, usize),
}

impl Pair {
    /// The clearance this pair needs: `min_clearance`, or for two arm
    /// shapes no more than [`SELF_CLEARANCE`].
    fn clearance(self, min_clearance: f64) -> f64 {
        match self {
            Pair::Arm(..) => min_clearance.min(SELF_CLEARANCE),
            _ => min_clearance,
        }
    }

    fn distance(self, world: &WorldShapes, tree: &TreeObstacles) -> f64 {
        match self {
            Pair::Branch(i, b) => distance(&world[i].0, &WorldShape::Capsule(tree.branches[b].1)),
            Pair::Fixed(i, f) => distance(&world[i].0, &tree.fixed[f].0),
            Pair::Arm(i, j) => distance(&world[i].0, &world[j].0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::shape::Shape;
    use crate::robot::arm::Arm;
    use crate::robot::ur5::JOINT_LIMITS;
    use crate::tree::{ScaParams, generate};
    use nalgebra::Point3;
    use nalgebra::Vector3;
    use rand::{RngExt, SeedableRng};

    /// The span with nothing pruned: every pair's exact distance over its
    /// rate, the ground, the horizon.
    fn brute_force_span(
        model: &CollisionModel,
        q: &[f64],
        tree: &TreeObstacles,
        allowed: &Allowed,
        rates: &SweepRates,
        horizon: f64,
        min_clearance: f64,
    ) -> Option<f64> {
        let world = model.world_shapes(q, 0.0);
        let mut span = horizon;
        let mut limit = |d: f64, rate: f64| {
            if rate <= 0.0 {
                return Some(());
            }
            if d < min_clearance {
                return None;
            }
            span = span.min(d / rate);
            Some(())
        };
        for (i, (shape, aabb)) in world.iter().enumerate() {
            let rate = rates.rates[i];
            if !model.shapes[i].base {
                limit(aabb.min.z - GROUND_Z, rate)?;
            }
            for (node, capsule, _) in &tree.branches {
                if !(model.shapes[i].gripper && allowed.gripper_branches.contains(node)) {
                    limit(distance(shape, &WorldShape::Capsule(*capsule)), rate)?;
                }
            }
            for (fixed, _) in tree.fixed.iter() {
                limit(distance(shape, fixed), rate)?;
            }
        }
        let self_clearance = min_clearance.min(SELF_CLEARANCE);
        for (k, &(i, j)) in model.self_pairs.iter().enumerate() {
            let (d, rate) = (distance(&world[i].0, &world[j].0), rates.self_pairs[k]);
            if rate > 0.0 {
                if d < self_clearance {
                    return None;
                }
                span = span.min(d / rate);
            }
        }
        Some(span)
    }

    /// The bounding-box pruning, the overall bounds and the limiting pair carried
    /// along an edge change how much is computed, never the answer: on
    /// random edges near a tree, a post and a box, `free_span` equals the
    /// unpruned minimum over every pair (or rejects exactly when it does).
    #[test]
    fn pruned_spans_equal_the_unpruned_minimum() {
        let model = CollisionModel::new(Arm::default());
        let tree = generate(20, 3, &ScaParams::default()).unwrap();
        let obstacles = TreeObstacles::new(&tree).with_obstacles(&[
            Shape::Capsule {
                a: Point3::new(-0.3, 0.25, 0.0),
                b: Point3::new(-0.3, 0.25, 1.2),
                radius: 0.04,
            },
            Shape::turned_box(
                Point3::new(-0.2, -0.3, 0.5),
                Vector3::new(0.05, 0.2, 0.3),
                0.4,
            ),
        ]);
        let allowed = Allowed {
            gripper_branches: vec![tree.len() - 1],
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let (mut spans, mut rejected) = (0, 0);
        for _ in 0..400 {
            let a = JointVector::from_fn(6, |i| {
                rng.random_range(JOINT_LIMITS[i].0.max(-3.0)..JOINT_LIMITS[i].1.min(3.0))
            });
            let b = JointVector::from_fn(6, |i| a[i] + rng.random_range(-0.6..0.6));
            let rates = model.sweep_rates(&a, &b);
            for step in 0..6 {
                let t = step as f64 / 6.0;
                let q = a.lerp(&b, t);
                let horizon = 1.0 - t;
                let fast = model.free_span(&q, &obstacles, &allowed, &rates, horizon, 0.005);
                let slow =
                    brute_force_span(&model, &q, &obstacles, &allowed, &rates, horizon, 0.005);
                match (fast, slow) {
                    (Some(f), Some(s)) => {
                        assert!((f - s).abs() <= 1e-12 * s.max(1.0), "span {f} against {s}");
                        spans += 1;
                    }
                    (None, None) => rejected += 1,
                    _ => panic!("pruned {fast:?}, unpruned {slow:?}"),
                }
            }
        }
        assert!(
            spans > 300 && rejected > 300,
            "{spans} spans, {rejected} rejections"
        );
    }
}
