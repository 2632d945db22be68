//! What a push is for. The paper asks for a whole target shape; growers ask
//! for a fruit or a line of sight to be cleared of branches, or for one
//! branch to be brought into reach. Each [`Objective`] scores the tree's
//! held state by a residual in metres, 0 when fully satisfied for `clear`
//! and `reach`, so one search serves them all.
//!
//! Branches are capsules: the segment parent → node with the branch's
//! radius. Distances between branches and regions are signed (negative
//! when they overlap): exact segment geometry for spheres and capsules,
//! parry's contact query for boxes.

use nalgebra::{Point3, Vector3};
use parry3d_f64::math::{Pose, Rot3, Vec3};
use parry3d_f64::query::contact;
use parry3d_f64::query::details::closest_points_segment_segment_with_locations_nD;
use parry3d_f64::shape::{Ball, Capsule, Cuboid, Segment, Shape};
use serde::{Deserialize, Serialize};

use super::predict::max_node_error;
use crate::tree::Tree;

/// A region of space: a fruit (sphere), a box, or a line of sight (a
/// capsule from a camera point to a fruit).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Region {
    Sphere {
        centre: Point3<f64>,
        radius: f64,
    },
    /// A box turned by `yaw` (rad) about the vertical, as obstacle boxes.
    Box {
        centre: Point3<f64>,
        half_extents: Vector3<f64>,
        #[serde(default)]
        yaw: f64,
    },
    Capsule {
        a: Point3<f64>,
        b: Point3<f64>,
        radius: f64,
    },
}

fn vec3(p: &Point3<f64>) -> Vec3 {
    Vec3::new(p.x, p.y, p.z)
}

impl Region {
    /// The region as a parry shape and its pose.
    fn shape(&self) -> (Box<dyn Shape>, Pose) {
        match self {
            Region::Sphere { centre, radius } => (
                Box::new(Ball::new(*radius)),
                Pose::from_translation(vec3(centre)),
            ),
            Region::Box {
                centre,
                half_extents,
                yaw,
            } => (
                Box::new(Cuboid::new(Vec3::new(
                    half_extents.x,
                    half_extents.y,
                    half_extents.z,
                ))),
                Pose::from_parts(vec3(centre), Rot3::from_rotation_z(*yaw)),
            ),
            Region::Capsule { a, b, radius } => (
                Box::new(Capsule::new(vec3(a), vec3(b), *radius)),
                Pose::IDENTITY,
            ),
        }
    }

    /// A point inside the region (its centre).
    pub fn centre(&self) -> Point3<f64> {
        match self {
            Region::Sphere { centre, .. } | Region::Box { centre, .. } => *centre,
            Region::Capsule { a, b, .. } => nalgebra::center(a, b),
        }
    }
}

/// A region prepared for many distance queries.
struct PreparedRegion {
    region: Region,
    shape: Box<dyn Shape>,
    pose: Pose,
}

/// The closest points of segments a–b and c–d.
fn closest_points(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> (Vec3, Vec3) {
    let (l1, l2) = closest_points_segment_segment_with_locations_nD((&a, &b), (&c, &d));
    (
        Segment::new(a, b).point_at(&l1),
        Segment::new(c, d).point_at(&l2),
    )
}

/// A unit vector perpendicular to `axis`.
fn any_perpendicular(axis: Vec3) -> Vec3 {
    let helper = if axis.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
    let p = axis.cross(helper);
    if p.length() > 1e-12 {
        p.normalize()
    } else {
        Vec3::X
    }
}

impl PreparedRegion {
    fn new(region: &Region) -> Self {
        let (shape, pose) = region.shape();
        Self {
            region: region.clone(),
            shape,
            pose,
        }
    }

    /// Signed distance from the capsule a–b of `radius` (negative: depth of
    /// overlap) and the unit direction from the region toward the branch.
    /// Spheres and capsules are a segment (or point) grown by a radius, as
    /// branches are, so their signed distance is exact and has no
    /// degenerate case (a fruit centred on a branch's axis); boxes use
    /// parry's contact query.
    fn signed_distance(
        &self,
        a: &Point3<f64>,
        b: &Point3<f64>,
        radius: f64,
    ) -> (f64, Vector3<f64>) {
        let (a, b) = (vec3(a), vec3(b));
        let grown = |core_a: Vec3, core_b: Vec3, core_radius: f64| {
            let (on_branch, on_core) = closest_points(a, b, core_a, core_b);
            let gap = on_branch - on_core;
            let away = if gap.length() > 1e-12 {
                gap.normalize()
            } else {
                any_perpendicular(b - a)
            };
            (gap.length() - core_radius - radius, away)
        };
        let (dist, away) = match &self.region {
            Region::Sphere { centre, radius: r } => grown(vec3(centre), vec3(centre), *r),
            Region::Capsule {
                a: p,
                b: q,
                radius: r,
            } => grown(vec3(p), vec3(q), *r),
            Region::Box { centre, .. } => {
                let capsule = Capsule::new(a, b, radius);
                match contact(
                    &Pose::IDENTITY,
                    &capsule,
                    &self.pose,
                    &*self.shape,
                    f64::MAX,
                )
                .ok()
                .flatten()
                {
                    // normal1 points from the branch toward the region.
                    Some(c) => (c.dist, -c.normal1),
                    None => {
                        let (on_branch, _) = closest_points(a, b, vec3(centre), vec3(centre));
                        (0.0, (on_branch - vec3(centre)).normalize_or(Vec3::Z))
                    }
                }
            }
        };
        (dist, Vector3::new(away.x, away.y, away.z))
    }
}

/// One branch's intrusion into a `clear` objective's regions (inflated by
/// the margin): how deep, and the direction that would take it out.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrusion {
    /// The branch's node.
    pub node: usize,
    /// margin − signed distance (m), > 0.
    pub depth: f64,
    /// Unit direction from the region toward the branch.
    pub away: Vector3<f64>,
}

/// What the push should achieve, judged on the held state.
#[derive(Debug, Clone, PartialEq)]
pub enum Objective {
    /// The paper's objective: every node (or, with `weights`, the weighted
    /// ones) near its target. Residual: the largest weighted node distance.
    Shape {
        targets: Vec<Point3<f64>>,
        /// Per node, ≥ 0; 0 ignores a node. `None`: every node weighs 1.
        weights: Option<Vec<f64>>,
    },
    /// Keep every branch at least `margin` away from every region.
    /// Residual: the deepest intrusion into a region inflated by the
    /// margin, 0 when clear.
    Clear { regions: Vec<Region>, margin: f64 },
    /// Bring `node` into `region`. Residual: its distance to the region.
    Reach { node: usize, region: Region },
}

/// Default `clear` margin (m): about a gripper finger's width, so a picker
/// reaching for the fruit does not brush the branch.
pub const DEFAULT_CLEAR_MARGIN: f64 = 0.01;

/// A residual at or below this counts as satisfied (m): the solver's own
/// tolerance is far finer, this absorbs rounding in region distances.
pub const SATISFIED: f64 = 1e-6;

impl Objective {
    /// The full-shape objective of the paper.
    pub fn shape(targets: Vec<Point3<f64>>) -> Self {
        Self::Shape {
            targets,
            weights: None,
        }
    }

    /// The full target shape, when the objective is one (the contact
    /// policy was trained only for those).
    pub fn full_shape(&self) -> Option<&[Point3<f64>]> {
        match self {
            Objective::Shape {
                targets,
                weights: None,
            } => Some(targets),
            _ => None,
        }
    }

    /// The objective's name as requests spell it.
    pub fn kind(&self) -> &'static str {
        match self {
            Objective::Shape { .. } => "shape",
            Objective::Clear { .. } => "clear",
            Objective::Reach { .. } => "reach",
        }
    }

    /// Whether satisfying it is all-or-nothing (residual 0), so that ties
    /// are broken by load and push length.
    pub fn has_goal_region(&self) -> bool {
        !matches!(self, Objective::Shape { .. })
    }

    /// A reusable scorer (regions prepared once).
    pub fn scorer(&self) -> Scorer<'_> {
        let regions = match self {
            Objective::Clear { regions, .. } => regions.iter().map(PreparedRegion::new).collect(),
            Objective::Reach { region, .. } => vec![PreparedRegion::new(region)],
            Objective::Shape { .. } => Vec::new(),
        };
        Scorer {
            objective: self,
            regions,
        }
    }

    /// The residual of `tree` with its nodes at `positions` (m).
    pub fn residual(&self, tree: &Tree, positions: &[Point3<f64>]) -> f64 {
        self.scorer().residual(tree, positions)
    }
}

/// An [`Objective`] with its regions prepared for repeated scoring.
pub struct Scorer<'a> {
    objective: &'a Objective,
    regions: Vec<PreparedRegion>,
}

impl Scorer<'_> {
    /// The residual of `tree` with its nodes at `positions` (m).
    pub fn residual(&self, tree: &Tree, positions: &[Point3<f64>]) -> f64 {
        match self.objective {
            Objective::Shape {
                targets,
                weights: None,
            } => max_node_error(positions, targets),
            Objective::Shape {
                targets,
                weights: Some(w),
            } => positions
                .iter()
                .zip(targets)
                .zip(w)
                .map(|((p, t), w)| w * (p - t).norm())
                .fold(0.0, f64::max),
            Objective::Clear { .. } => self
                .intrusions(tree, positions)
                .iter()
                .map(|i| i.depth)
                .fold(0.0, f64::max),
            Objective::Reach { node, .. } => {
                let p = positions[*node];
                let region = &self.regions[0];
                region.shape.distance_to_point(&region.pose, vec3(&p), true)
            }
        }
    }

    /// Per branch, its nearest region: (node, signed distance, unit
    /// direction from that region toward the branch). Empty without
    /// regions to clear.
    fn nearest_regions<'s>(
        &'s self,
        tree: &'s Tree,
        positions: &'s [Point3<f64>],
    ) -> impl Iterator<Item = (usize, f64, Vector3<f64>)> + 's {
        tree.branches_iter().filter_map(move |(node, branch)| {
            let parent = tree.parent(node)?;
            let (a, b) = (positions[parent], positions[node]);
            self.regions
                .iter()
                .map(|r| r.signed_distance(&a, &b, branch.radius))
                .max_by(|x, y| (-x.0).total_cmp(&-y.0))
                .map(|(dist, away)| (node, dist, away))
        })
    }

    /// For `clear`: the smallest signed distance between any branch and any
    /// region (m; negative: overlapping), the clearance reached; `None`
    /// for other objectives.
    pub fn clearance(&self, tree: &Tree, positions: &[Point3<f64>]) -> Option<f64> {
        let Objective::Clear { .. } = self.objective else {
            return None;
        };
        Some(
            self.nearest_regions(tree, positions)
                .map(|(_, dist, _)| dist)
                .fold(f64::INFINITY, f64::min),
        )
    }

    /// For `clear`: every branch closer than the margin to a region, its
    /// deepest intrusion over the regions; empty for other objectives.
    pub fn intrusions(&self, tree: &Tree, positions: &[Point3<f64>]) -> Vec<Intrusion> {
        let Objective::Clear { margin, .. } = self.objective else {
            return Vec::new();
        };
        self.nearest_regions(tree, positions)
            .map(|(node, dist, away)| Intrusion {
                node,
                depth: margin - dist,
                away,
            })
            .filter(|i| i.depth > 0.0)
            .collect()
    }
}

/// Loads a push may not exceed: what keeps a branch from breaking and the
/// gripper from crushing the bark.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Limits {
    /// Largest bending stress allowed at any branch's base (Pa).
    pub max_stress: f64,
    /// Largest force the gripper may apply (N).
    pub max_contact_force: f64,
}

/// Default stress limit (Pa): the modulus of rupture of green hardwood,
/// about 60 MPa (USDA Forest Products Laboratory, Wood Handbook, FPL-GTR-282
/// (2021), Table 5-3a: green sugar maple 65 MPa, black cherry 55, white
/// oak 57, red maple 53), divided by a safety factor of 1.5.
pub const DEFAULT_MAX_STRESS: f64 = 40e6;
/// Default contact-force limit (N): the range of the UR5e's wrist
/// force/torque sensor (50 N, Universal Robots UR5e technical
/// specifications), so that a push stays one the robot can feel. The
/// simulated trees need more for many of the dataset's 5-15 cm pushes
/// (median 88 N on the test split: `docs/results/tasks_eval.md`), which is
/// why the planner prefers the least loading push that does the job.
pub const DEFAULT_MAX_CONTACT_FORCE: f64 = 50.0;

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_stress: DEFAULT_MAX_STRESS,
            max_contact_force: DEFAULT_MAX_CONTACT_FORCE,
        }
    }
}

/// How a push's loads compare with the limits.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LoadMargin {
    /// 1 − peak stress / limit: > 0 within the limit.
    pub stress: f64,
    /// 1 − contact force / limit.
    pub contact_force: f64,
}

impl Limits {
    pub fn margin(&self, loads: &crate::sim::loads::PushLoads) -> LoadMargin {
        LoadMargin {
            stress: 1.0 - loads.peak_stress / self.max_stress,
            contact_force: 1.0 - loads.contact_force / self.max_contact_force,
        }
    }

    /// Whether `loads` stay within both limits.
    pub fn allow(&self, loads: &crate::sim::loads::PushLoads) -> bool {
        loads.peak_stress <= self.max_stress && loads.contact_force <= self.max_contact_force
    }
}
