//! The collision model: the arm's shapes, the tree's and the obstacles', and
//! whether a configuration or a straight edge between two is free.

use nalgebra::{Isometry3, Point3};
use parry3d_f64::shape::Capsule;
use serde::Serialize;

use crate::geometry::convert::vec3;
use crate::geometry::shape::Shape;
use crate::robot::arm::Arm;
use crate::robot::model::joint_vector::{JointVector, MAX_DOF};
use crate::robot::model::self_pairs::OFTEN;
use crate::tree::Tree;

use crate::geometry::aabb::Aabb;
use crate::geometry::world_shape::{WorldShape, WorldShapes, intersects};
use crate::robot::collision::bounds::from_axis;

/// Clearance two arm shapes of a self-collision pair need (m), however
/// much the environment checks grow the shapes. The pairs a description
/// leaves checked were sampled with shapes as they are (MoveIt pads no
/// self-collision either), and real arms hold links a few millimetres apart
/// in valid poses (the Panda's links 5 and 7 at home).
pub const SELF_CLEARANCE: f64 = 0.001;

/// Added to each lever arm ([`Arm::lever_arms`]): covers the margin that
/// shapes are grown by in checks (half the edge resolution) (m).
const LEVER_ARM_SLACK: f64 = 0.02;
/// Random configurations over which a pair of the added ⊔ gripper and an
/// arm link must always touch to be left unchecked (as MoveIt's setup
/// assistant leaves "always in collision" pairs).
const GRIPPER_PAIR_SAMPLES: usize = 200;

/// Height of the ground plane (m).
pub const GROUND_Z: f64 = 0.0;

/// What a configuration collides with.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Hit {
    Ground {
        link: String,
    },
    Branch {
        link: String,
        node: usize,
    },
    SelfCollision {
        link: String,
        other: String,
    },
    /// One of the fixed obstacles (posts, wires, neighbouring stems), by its
    /// index in the list given.
    Obstacle {
        link: String,
        index: usize,
    },
}

/// The tree's branches as capsules, and any fixed obstacles around it.
#[derive(Debug, Clone)]
pub struct TreeObstacles {
    /// (node the branch ends at, capsule, bounding box)
    pub(super) branches: Vec<(usize, Capsule, Aabb)>,
    /// Fixed obstacles, never touched by anything.
    pub(super) fixed: std::sync::Arc<[(WorldShape, Aabb)]>,
    /// One box around all of them: an arm shape far from it skips the lot.
    pub(super) bounds: Aabb,
}

type Branches = Vec<(usize, Capsule, Aabb)>;

impl TreeObstacles {
    pub(super) fn from_parts(
        branches: Branches,
        fixed: std::sync::Arc<[(WorldShape, Aabb)]>,
    ) -> Self {
        let bounds = branches
            .iter()
            .map(|b| &b.2)
            .chain(fixed.iter().map(|f| &f.1))
            .fold(Aabb::EMPTY, |all, b| all.union(b));
        Self {
            branches,
            fixed,
            bounds,
        }
    }

    /// The tree at rest.
    pub fn new(tree: &Tree) -> Self {
        Self::deformed(tree, tree.positions())
    }

    pub(super) fn branches_at(tree: &Tree, positions: &[Point3<f64>]) -> Branches {
        tree.branches_iter()
            .map(|(j, b)| {
                let parent = tree.parent(j).expect("non-root");
                let (a, c) = (positions[parent].coords, positions[j].coords);
                (
                    j,
                    Capsule::new(vec3(&a), vec3(&c), b.radius),
                    Aabb::of_capsule(&a, &c, b.radius),
                )
            })
            .collect()
    }

    /// The tree with its nodes at `positions` (same topology and radii).
    pub fn deformed(tree: &Tree, positions: &[Point3<f64>]) -> Self {
        Self::from_parts(Self::branches_at(tree, positions), Vec::new().into())
    }

    /// These obstacles with `obstacles` added as fixed ones.
    pub fn with_obstacles(self, obstacles: &[Shape]) -> Self {
        let mut fixed = self.fixed.to_vec();
        fixed.extend(
            obstacles
                .iter()
                .map(|o| o.world(&Isometry3::identity(), 0.0)),
        );
        Self::from_parts(self.branches, fixed.into())
    }

    /// The same fixed obstacles around the tree with its nodes at
    /// `positions` (a snapshot during a push).
    pub fn with_tree_at(&self, tree: &Tree, positions: &[Point3<f64>]) -> Self {
        Self::from_parts(Self::branches_at(tree, positions), self.fixed.clone())
    }

    /// Nothing to hit (an empty workcell but for the ground).
    pub fn empty() -> Self {
        Self::from_parts(Vec::new(), Vec::new().into())
    }

    /// Arbitrary capsules (node label, endpoints, radius), e.g. a wall of
    /// obstacles in a test scene.
    pub fn from_capsules(capsules: &[(usize, Point3<f64>, Point3<f64>, f64)]) -> Self {
        let branches = capsules
            .iter()
            .map(|(node, a, b, r)| {
                (
                    *node,
                    Capsule::new(vec3(&a.coords), vec3(&b.coords), *r),
                    Aabb::of_capsule(&a.coords, &b.coords, *r),
                )
            })
            .collect();
        Self::from_parts(branches, Vec::new().into())
    }
}

/// Which contacts are allowed in a query.
#[derive(Debug, Clone, Default)]
pub struct Allowed {
    /// Branches (by the node they end at) the gripper — palm, fingers and the
    /// flange link they are bolted to — may touch: the contacted branch
    /// during a push.
    pub gripper_branches: Vec<usize>,
}

#[derive(Debug, Clone)]
pub(crate) struct ShapeSlot {
    pub(super) link: usize,
    pub(super) shape: Shape,
    /// Rigid with the tip (tool, hand, flange): may touch the held branch.
    pub(super) gripper: bool,
    /// Fixed to the base: not checked against the ground.
    pub(super) base: bool,
    /// Which joints move this shape.
    pub(super) moved_by: [bool; MAX_DOF],
}

/// The arm's collision geometry and which link pairs to test for
/// self-collision.
#[derive(Debug, Clone)]
pub struct CollisionModel {
    pub robot: Arm,
    pub(super) shapes: Vec<ShapeSlot>,
    /// Pairs of indices into `shapes`.
    pub(super) self_pairs: Vec<(usize, usize)>,
    pub(super) names: Vec<String>,
    /// [`Arm::lever_arms`], with [`LEVER_ARM_SLACK`].
    pub(super) lever_arms: JointVector,
    /// Per variable, [`Arm::drives_several_joints`], found once here.
    pub(super) drives_several: [bool; MAX_DOF],
}

impl CollisionModel {
    /// The arm, skipping the self-collision pairs its description disables
    /// and any pair of the added ⊔ gripper with a link it always touches.
    pub fn new(robot: Arm) -> Self {
        let disabled = robot.disabled_pairs().to_vec();
        let mut model = Self::with_disabled_pairs(robot, &disabled);
        model.drop_gripper_pairs_always_touching();
        model
    }

    /// The arm, skipping self-collision checks between the named link pairs
    /// (besides parent/child pairs, which are never checked).
    pub fn with_disabled_pairs(robot: Arm, disabled_pairs: &[(String, String)]) -> Self {
        let names: Vec<String> = robot.link_names().map(str::to_owned).collect();
        let mut shapes = Vec::new();
        for (link, (_, link_shapes)) in robot.link_shapes().enumerate() {
            for shape in link_shapes {
                shapes.push(ShapeSlot {
                    link,
                    shape: shape.clone(),
                    gripper: robot.carried_by_tip(link),
                    base: robot.fixed_to_base(link),
                    moved_by: std::array::from_fn(|i| i < robot.dof() && robot.moved_by(link, i)),
                });
            }
        }
        let adjacent =
            |a: usize, b: usize| robot.link_parent(a) == Some(b) || robot.link_parent(b) == Some(a);
        let disabled = |a: &str, b: &str| {
            disabled_pairs
                .iter()
                .any(|(x, y)| (x == a && y == b) || (x == b && y == a))
        };
        let mut self_pairs = Vec::new();
        for i in 0..shapes.len() {
            for j in (i + 1)..shapes.len() {
                let (la, lb) = (shapes[i].link, shapes[j].link);
                if la == lb || adjacent(la, lb) || disabled(&names[la], &names[lb]) {
                    continue;
                }
                // The tool, the tip and what is welded to it are one rigid
                // body; so are the base's links.
                if (shapes[i].gripper && shapes[j].gripper) || (shapes[i].base && shapes[j].base) {
                    continue;
                }
                self_pairs.push((i, j));
            }
        }
        let lever_arms = robot.lever_arms(LEVER_ARM_SLACK);
        let drives_several =
            std::array::from_fn(|i| i < robot.dof() && robot.drives_several_joints(i));
        Self {
            robot,
            shapes,
            self_pairs,
            names,
            lever_arms,
            drives_several,
        }
    }

    /// Drops the self-collision pairs of the added ⊔ gripper with a link
    /// that it touches in at least [`OFTEN`] of [`GRIPPER_PAIR_SAMPLES`]
    /// random configurations (a hand it is bolted past, a wrist housing
    /// whose fitted capsule reaches past the flange), as the description's
    /// sampler does for the arm's own pairs: it could not know of the
    /// gripper.
    pub(super) fn drop_gripper_pairs_always_touching(&mut self) {
        let Some(gripper) = self.robot.gripper_link() else {
            return;
        };
        let candidates: Vec<usize> = (0..self.self_pairs.len())
            .filter(|&k| {
                let (i, j) = self.self_pairs[k];
                self.shapes[i].link == gripper || self.shapes[j].link == gripper
            })
            .collect();
        if candidates.is_empty() {
            return;
        }
        let mut touching = vec![0usize; self.self_pairs.len()];
        let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(7);
        for _ in 0..GRIPPER_PAIR_SAMPLES {
            let q =
                crate::robot::model::urdf_chain::random_configuration(self.robot.chain(), &mut rng);
            let world = self.world_shapes(&q, 0.0);
            for &k in &candidates {
                let (i, j) = self.self_pairs[k];
                touching[k] += usize::from(intersects(&world[i].0, &world[j].0));
            }
        }
        let mut k = 0;
        self.self_pairs.retain(|_| {
            let often = touching[k] as f64 >= OFTEN * GRIPPER_PAIR_SAMPLES as f64;
            let keep = !(candidates.contains(&k) && often);
            k += 1;
            keep
        });
    }

    /// [`Arm::lever_arms`] as the edge checks use them.
    pub fn lever_arms(&self) -> &JointVector {
        &self.lever_arms
    }

    /// World-frame capsules (endpoints, radius) of every capsule- or
    /// sphere-shaped link part at `q`, with the link name: for tests and
    /// drawings.
    pub fn capsules_at(&self, q: &[f64]) -> Vec<(&str, Point3<f64>, Point3<f64>, f64)> {
        let poses = self.robot.link_poses(q);
        self.shapes
            .iter()
            .filter_map(|slot| {
                let (a, b, r) = match &slot.shape {
                    Shape::Capsule { a, b, radius } => (*a, *b, *radius),
                    Shape::Sphere { centre, radius } => (*centre, *centre, *radius),
                    _ => return None,
                };
                let p = poses[slot.link];
                Some((self.names[slot.link].as_str(), p * a, p * b, r))
            })
            .collect()
    }

    /// R_i(q) for each joint i: the largest distance from joint i's axis
    /// of any point of a shape it moves, each shape grown by `margin` (1
    /// for a prismatic joint, which moves every point as fast as itself).
    /// A rotation Δq_i moves no such point farther than R_i |Δq_i|; the
    /// planning scene spaces its edge checks by it.
    pub fn axis_reach(&self, q: &[f64], margin: f64) -> JointVector {
        let poses = self.robot.link_poses(q);
        let axes = self.robot.joint_axes(&poses);
        let dof = self.robot.dof();
        let mut reach = JointVector::zeros(dof);
        for (i, (_, _, prismatic)) in axes.iter().enumerate() {
            if *prismatic {
                reach[i] = 1.0;
            }
        }
        for i in (0..dof).filter(|&i| self.drives_several[i]) {
            // Several axes: the lever arm bounds them together.
            reach[i] = self.lever_arms[i] + margin;
        }
        for slot in &self.shapes {
            let (points, pad) = slot.shape.bounding_points(&poses[slot.link], margin);
            let single_axis = |i: usize| !axes[i].2 && !self.drives_several[i];
            for i in (0..dof).filter(|&i| slot.moved_by[i] && single_axis(i)) {
                for p in &points {
                    reach[i] = reach[i].max(from_axis(&axes[i], p) + pad);
                }
            }
        }
        reach
    }

    /// Link names of the self-collision pairs that are checked.
    pub fn self_collision_pairs(&self) -> Vec<(&str, &str)> {
        self.self_pairs
            .iter()
            .map(|&(i, j)| {
                (
                    self.names[self.shapes[i].link].as_str(),
                    self.names[self.shapes[j].link].as_str(),
                )
            })
            .collect()
    }

    pub(super) fn world_shapes(&self, q: &[f64], margin: f64) -> WorldShapes {
        self.world_shapes_at(&self.robot.link_poses(q), margin)
    }

    pub(super) fn world_shapes_at(&self, poses: &[Isometry3<f64>], margin: f64) -> WorldShapes {
        self.shapes
            .iter()
            .map(|slot| slot.shape.world(&poses[slot.link], margin))
            .collect()
    }

    /// The first collision of configuration `q`, or `None` when it is free.
    pub fn check(&self, q: &[f64], tree: &TreeObstacles, allowed: &Allowed) -> Option<Hit> {
        self.check_with_margin(q, tree, allowed, 0.0)
    }

    /// As [`Self::check`], with every robot shape grown by `margin` (m): a
    /// configuration free with margin δ/2 stays free while no robot point
    /// moves more than δ/2, which makes discrete edge checks conservative.
    pub fn check_with_margin(
        &self,
        q: &[f64],
        tree: &TreeObstacles,
        allowed: &Allowed,
        margin: f64,
    ) -> Option<Hit> {
        let poses = self.robot.link_poses(q);
        let world = self.world_shapes_at(&poses, margin);
        let name = |i: usize| self.names[self.shapes[i].link].clone();
        for (i, (_, aabb)) in world.iter().enumerate() {
            if !self.shapes[i].base && aabb.min.z < GROUND_Z {
                // AABB min z is exact for capsules and boxes.
                return Some(Hit::Ground { link: name(i) });
            }
        }
        for (i, (shape, aabb)) in world.iter().enumerate() {
            if !aabb.overlaps(&tree.bounds) {
                continue;
            }
            for (node, capsule, branch_box) in &tree.branches {
                if !aabb.overlaps(branch_box) {
                    continue;
                }
                if self.shapes[i].gripper && allowed.gripper_branches.contains(node) {
                    continue;
                }
                if intersects(shape, &WorldShape::Capsule(*capsule)) {
                    return Some(Hit::Branch {
                        link: name(i),
                        node: *node,
                    });
                }
            }
        }
        for (i, (shape, aabb)) in world.iter().enumerate() {
            for (index, (obstacle, obstacle_box)) in tree.fixed.iter().enumerate() {
                if !aabb.overlaps(obstacle_box) {
                    continue;
                }
                if intersects(shape, obstacle) {
                    return Some(Hit::Obstacle {
                        link: name(i),
                        index,
                    });
                }
            }
        }
        // Self-collision with at most SELF_CLEARANCE between the shapes.
        let self_margin = SELF_CLEARANCE / 2.0;
        let own;
        let arm_world = if margin > self_margin && !self.self_pairs.is_empty() {
            own = self.world_shapes_at(&poses, self_margin);
            &own
        } else {
            &world
        };
        for &(i, j) in &self.self_pairs {
            if !arm_world[i].1.overlaps(&arm_world[j].1) {
                continue;
            }
            if intersects(&arm_world[i].0, &arm_world[j].0) {
                return Some(Hit::SelfCollision {
                    link: name(i),
                    other: name(j),
                });
            }
        }
        None
    }

    /// Every checked self-collision pair in contact at `q` (link names), as
    /// [`Self::check`] sees them but all of them, not the first: for
    /// reports of which pairs block an arm.
    pub fn self_contacts(&self, q: &[f64]) -> Vec<(&str, &str)> {
        let world = self.world_shapes(q, SELF_CLEARANCE / 2.0);
        let mut out: Vec<(&str, &str)> = Vec::new();
        for &(i, j) in &self.self_pairs {
            if world[i].1.overlaps(&world[j].1) && intersects(&world[i].0, &world[j].0) {
                let pair = (
                    self.names[self.shapes[i].link].as_str(),
                    self.names[self.shapes[j].link].as_str(),
                );
                if !out.contains(&pair) {
                    out.push(pair);
                }
            }
        }
        out
    }
}
