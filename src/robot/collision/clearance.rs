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

use nalgebra::Point3;
use parry3d_f64::query::details::closest_points_segment_segment_with_locations_nD;

use super::{Aabb, Allowed, CollisionModel, GROUND_Z, ShapeSlot, TreeObstacles, WorldShape};
use crate::robot::ur5::{DH_A, DH_D, FINGER_LENGTH, LinkShape, TOOL_OFFSET};

/// Largest capsule radius plus the gripper's half width, added to the
/// kinematic reach to bound every collision shape (m).
const SHAPE_SLACK: f64 = 0.1;

/// R_i: an upper bound on the distance from joint i's axis to any point of
/// the robot's collision shapes (m) in any configuration, from the chain of
/// DH lengths beyond it.
pub const LEVER_ARMS: [f64; 6] = {
    let tool = TOOL_OFFSET + FINGER_LENGTH + SHAPE_SLACK;
    let wrist = DH_D[4] + DH_D[5] + tool;
    let forearm = -DH_A[2] + DH_D[3] + wrist;
    let arm = -DH_A[1] + forearm;
    [arm, arm, forearm, wrist, DH_D[5] + tool, tool]
};

/// Points that bound a shape at `pose`, and how far the shape reaches
/// beyond them (grown by `margin`).
pub(super) fn bounding_points(
    slot: &ShapeSlot,
    pose: &nalgebra::Isometry3<f64>,
    margin: f64,
) -> ([Point3<f64>; 2], f64) {
    match &slot.shape {
        LinkShape::Capsule { a, b, radius } => (
            [pose * Point3::from(*a), pose * Point3::from(*b)],
            radius + margin,
        ),
        LinkShape::Box {
            centre,
            half_extents,
        } => {
            let c = pose * centre * Point3::origin();
            ([c, c], half_extents.norm() + margin)
        }
    }
}

/// How fast each shape can move along one edge, per unit of t.
#[derive(Debug, Clone)]
pub struct SweepRates {
    /// Per shape and joint: how fast that joint's rotation moves the
    /// shape's points (m per unit t); 0 for joints that do not move it.
    by_joint: Vec<[f64; 6]>,
    /// Per shape: the sum over joints, its speed in the world.
    rates: Vec<f64>,
    /// Per self-collision pair of the model: how fast the two approach.
    self_pairs: Vec<f64>,
}

impl SweepRates {
    /// The largest rate of any shape.
    pub fn max(&self) -> f64 {
        self.rates.iter().copied().fold(0.0, f64::max)
    }

    /// How fast shapes `i` and `j` can approach each other: a joint that
    /// moves both carries them rigidly together, so only the joints that
    /// move exactly one of them count.
    fn relative(&self, model: &CollisionModel, i: usize, j: usize) -> f64 {
        let (mi, mj) = (&model.shapes[i].moved_by, &model.shapes[j].moved_by);
        (0..6)
            .map(|k| match (mi[k], mj[k]) {
                (true, false) => self.by_joint[i][k],
                (false, true) => self.by_joint[j][k],
                _ => 0.0,
            })
            .sum()
    }
}

impl CollisionModel {
    /// Sweep rates of every shape along the edge `a` → `b`: for each joint
    /// i moving the shape, its reach from i's axis at `a` plus how far the
    /// joints beyond i can carry it away from that axis during the edge
    /// (never more than [`LEVER_ARMS`]), times |b_i − a_i|. Joints before i
    /// move the point and the axis together, so they do not change that
    /// distance.
    pub fn sweep_rates(&self, a: &[f64; 6], b: &[f64; 6]) -> SweepRates {
        let poses = self.robot.link_poses(a);
        let axes = self.robot.joint_axes(&poses);
        let dq: [f64; 6] = std::array::from_fn(|i| (b[i] - a[i]).abs());
        let by_joint: Vec<[f64; 6]> = self
            .shapes
            .iter()
            .map(|slot| {
                let (points, pad) = bounding_points(slot, &poses[slot.link], 0.0);
                std::array::from_fn(|i| {
                    if !slot.moved_by[i] || dq[i] == 0.0 {
                        return 0.0;
                    }
                    let (o, d) = &axes[i];
                    let reach = points
                        .iter()
                        .map(|p| {
                            let v = p - o;
                            (v - d * v.dot(d)).norm() + pad
                        })
                        .fold(0.0, f64::max);
                    let drift: f64 = (i + 1..6)
                        .filter(|&j| slot.moved_by[j])
                        .map(|j| LEVER_ARMS[j] * dq[j])
                        .sum();
                    (reach + drift).min(LEVER_ARMS[i]) * dq[i]
                })
            })
            .collect();
        let rates = by_joint.iter().map(|r| r.iter().sum()).collect();
        let mut sweep = SweepRates {
            by_joint,
            rates,
            self_pairs: Vec::new(),
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
    /// rest are settled by their bounding boxes.
    pub fn free_span(
        &self,
        q: &[f64; 6],
        tree: &TreeObstacles,
        allowed: &Allowed,
        rates: &SweepRates,
        horizon: f64,
        min_clearance: f64,
    ) -> Option<f64> {
        let world = self.world_shapes(q, 0.0);
        let mut span = horizon;
        // Pairs whose bounding boxes are close enough to matter, with the
        // span their boxes' distance allows (a lower bound on the true one;
        // −1 for boxes closer than the clearance asked).
        let mut pending: Vec<(f64, f64, Pair)> = Vec::new();
        let mut consider = |lower: f64, rate: f64, pair: Pair| {
            if rate <= 0.0 {
                return;
            }
            if lower < min_clearance {
                pending.push((-1.0, rate, pair));
            } else if lower < rate * horizon {
                pending.push((lower / rate, rate, pair));
            }
        };
        for (i, (_, aabb)) in world.iter().enumerate() {
            let rate = rates.rates[i];
            if rate <= 0.0 {
                // Does not move along this edge: as free as at the edge's
                // start, which the caller has checked.
                continue;
            }
            if !self.shapes[i].base {
                // Exact: a box's lowest point is its shape's lowest point.
                let d = aabb.min.z - GROUND_Z;
                if d < min_clearance {
                    return None;
                }
                span = span.min(d / rate);
            }
            for (b, (node, _, branch_box)) in tree.branches.iter().enumerate() {
                if self.shapes[i].gripper && allowed.gripper_branches.contains(node) {
                    continue;
                }
                consider(aabb.distance(branch_box), rate, Pair::Branch(i, b));
            }
            for (f, (_, obstacle_box)) in tree.fixed.iter().enumerate() {
                consider(aabb.distance(obstacle_box), rate, Pair::Fixed(i, f));
            }
        }
        for (k, &(i, j)) in self.self_pairs.iter().enumerate() {
            consider(
                world[i].1.distance(&world[j].1),
                rates.self_pairs[k],
                Pair::Arm(i, j),
            );
        }
        // The most constraining first: once a pair's lower bound allows the
        // span found so far, so do all the rest.
        pending.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        for (lower_span, rate, pair) in pending {
            if lower_span >= span {
                break;
            }
            let d = match pair {
                Pair::Branch(i, b) => {
                    distance(&world[i].0, &WorldShape::Capsule(tree.branches[b].1))
                }
                Pair::Fixed(i, f) => distance(&world[i].0, &tree.fixed[f].0),
                Pair::Arm(i, j) => distance(&world[i].0, &world[j].0),
            };
            if d < min_clearance {
                return None;
            }
            span = span.min(d / rate);
        }
        Some(span)
    }
}

/// A pair of shapes whose distance may limit the span: an arm shape and a
/// branch or fixed obstacle (by index), or two arm shapes.
#[derive(Debug, Clone, Copy)]
enum Pair {
    Branch(usize, usize),
    Fixed(usize, usize),
    Arm(usize, usize),
}

impl Aabb {
    /// Distance between two boxes: a lower bound on the distance between
    /// any shapes inside them.
    fn distance(&self, other: &Aabb) -> f64 {
        (self.min - other.max)
            .sup(&(other.min - self.max))
            .sup(&nalgebra::Vector3::zeros())
            .norm()
    }
}

/// Distance between two shapes (0 when they touch or overlap): closed form
/// for two capsules, parry's GJK otherwise.
fn distance(a: &WorldShape, b: &WorldShape) -> f64 {
    let ((pa, sa), (pb, sb)) = (a.as_query(), b.as_query());
    if let (Some(c1), Some(c2)) = (sa.as_capsule(), sb.as_capsule()) {
        let (s1, s2) = (c1.segment.transformed(&pa), c2.segment.transformed(&pb));
        let (l1, l2) =
            closest_points_segment_segment_with_locations_nD((&s1.a, &s1.b), (&s2.a, &s2.b));
        let gap = (s1.point_at(&l1) - s2.point_at(&l2)).length();
        return (gap - c1.radius - c2.radius).max(0.0);
    }
    parry3d_f64::query::distance(&pa, sa, &pb, sb).map_or(0.0, |d| d.distance.max(0.0))
}
