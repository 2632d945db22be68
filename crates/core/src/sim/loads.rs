//! What a held push does to the wood: the moment each joint's spring carries
//! and the bending stress at the base of its branch.
//!
//! A joint's spring carries the moment K_s θ (N·m). In equilibrium it equals
//! the contact force's moment about the joint, (g − P_joint) × F, with g the
//! point where the gripper holds (tested to solver precision). The rotation
//! splits into bending (θ_b, perpendicular to the branch) and twist (along
//! it); bending is what breaks a branch. The bending stress at the base of a
//! solid round branch is σ = M r / I = 4 M / (π r³) (Pa).
//!
//! Stress needs absolute stiffness: K_s = E π r⁴ / (2 ℓ) gives back the
//! wood's modulus E = 2 ℓ K_s / (π r⁴) each branch's stiffness implies
//! (5 GPa for the radius formula, [`crate::tree::wood::DEFAULT_YOUNG_MODULUS`]).
//! A stiffness known only up to a factor (identified from positions alone)
//! scales every moment and stress by that factor.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::tree::Tree;

/// Per-branch loads of one held push, indexed by node (`None` at the root).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BranchLoads {
    /// Bending moment at the branch's base, K_s |θ_b| (N·m).
    pub bending_moment: Vec<Option<f64>>,
    /// Twisting moment about the branch's axis, K_s |θ · â| (N·m).
    pub twisting_moment: Vec<Option<f64>>,
    /// Bending stress at the branch's base, 4 M / (π r³) (Pa).
    pub bending_stress: Vec<Option<f64>>,
    /// The Young's modulus the branch's stiffness implies, 2 ℓ K_s / (π r⁴)
    /// (Pa).
    pub implied_modulus: Vec<Option<f64>>,
    /// The largest bending stress (Pa) and its node (`None`: nothing bends).
    pub peak_stress: Option<PeakStress>,
}

/// The most stressed branch.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PeakStress {
    /// Pa.
    pub stress: f64,
    pub node: usize,
}

/// The loads of `tree` deformed by `joint_rotations` (one rotation vector
/// per node, in its parent's frame, as [`super::PushOutcome`] gives them).
pub fn branch_loads(tree: &Tree, joint_rotations: &[Vector3<f64>]) -> BranchLoads {
    let n = tree.len();
    let mut loads = BranchLoads {
        bending_moment: vec![None; n],
        twisting_moment: vec![None; n],
        bending_stress: vec![None; n],
        implied_modulus: vec![None; n],
        peak_stress: None,
    };
    for (node, branch) in tree.branches_iter() {
        let theta = joint_rotations
            .get(node)
            .copied()
            .unwrap_or_else(Vector3::zeros);
        // Frames coincide at rest, so the rest direction is the branch axis
        // in the frame θ is expressed in (and θ is the same about the
        // deformed axis: the rotation leaves its own axis fixed).
        let axis = tree.branch_direction(node).unwrap_or_else(Vector3::z);
        let along = theta.dot(&axis);
        let bending = (theta - axis * along).norm();
        let moment = branch.stiffness * bending;
        let stress = 4.0 * moment / (std::f64::consts::PI * branch.radius.powi(3));
        loads.bending_moment[node] = Some(moment);
        loads.twisting_moment[node] = Some(branch.stiffness * along.abs());
        loads.bending_stress[node] = Some(stress);
        loads.implied_modulus[node] = Some(
            2.0 * branch.length * branch.stiffness / (std::f64::consts::PI * branch.radius.powi(4)),
        );
        if stress > 0.0 && loads.peak_stress.is_none_or(|p| stress > p.stress) {
            loads.peak_stress = Some(PeakStress { stress, node });
        }
    }
    loads
}

/// The loads a planner weighs a push by: the most stressed branch and the
/// force the gripper must apply.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PushLoads {
    /// Largest bending stress over the branches (Pa), 0 when nothing bends.
    pub peak_stress: f64,
    /// The branch (its node) where the peak occurs.
    pub peak_node: Option<usize>,
    /// Magnitude of the force the gripper applies to the branch (N).
    pub contact_force: f64,
}

impl PushLoads {
    /// The simulator's own numbers for a solved push.
    pub fn of_outcome(tree: &Tree, outcome: &super::PushOutcome) -> Self {
        Self::of_state(tree, &outcome.joint_rotations, outcome.report.contact_force)
    }

    /// The loads of a held state: its joint rotations and contact force.
    pub fn of_state(
        tree: &Tree,
        joint_rotations: &[Vector3<f64>],
        contact_force: [f64; 3],
    ) -> Self {
        let peak = branch_loads(tree, joint_rotations).peak_stress;
        Self {
            peak_stress: peak.map_or(0.0, |p| p.stress),
            peak_node: peak.map(|p| p.node),
            contact_force: Vector3::from(contact_force).norm(),
        }
    }

    /// The loads implied by node positions alone (a forward model's
    /// prediction), for a push held at `push.node`.
    ///
    /// Only the joints on the path root → contact node carry a moment (the
    /// steady state minimises the spring energy, and a joint off the path can
    /// relax to zero), so only they are read; whatever a model predicts
    /// elsewhere is noise, and a few millimetres of it on a thin twig would
    /// read as tens of MPa. Along the path each branch's deformed direction
    /// gives its rotation: the smallest rotation carrying the branch's rest
    /// direction, turned by its parent's estimated orientation, onto the
    /// predicted one. That is the bending rotation θ_b (twist leaves no
    /// trace in positions and does not bend). The contact force F follows
    /// from the moment balance K_s θ = (g − P_joint) × F at every path joint
    /// (least squares in angle, g the gripper's hold point: for the slot
    /// the rest hold point moved by the push, for the pinned model the
    /// node), and each joint's moment from it, M = |(g − P_joint) × F|, so
    /// σ = 4M/(πr³) as [`branch_loads`].
    pub fn from_positions(
        tree: &Tree,
        push: &super::Push,
        positions: &[nalgebra::Point3<f64>],
        contact: super::ContactModel,
    ) -> Self {
        use nalgebra::{Matrix3, Rotation3};
        let mut loads = Self {
            peak_stress: 0.0,
            peak_node: None,
            contact_force: 0.0,
        };
        if push.node == 0 || push.node >= tree.len() || positions.len() != tree.len() {
            return loads;
        }
        let mut path = tree.path_to_root(push.node);
        path.reverse(); // root first
        let grip = match contact {
            super::ContactModel::Slot => {
                tree.position(push.node)
                    - tree.branch_direction(push.node).unwrap_or_else(Vector3::z)
                        * super::contact::GRIP_OFFSET
                    + push.vector
            }
            super::ContactModel::Pinned => positions[push.node],
        };
        let mut orientation = Rotation3::identity();
        let (mut normal, mut rhs) = (Matrix3::zeros(), Vector3::zeros());
        // (node, lever arm g − P_joint, radius) of each path joint.
        let mut joints = Vec::with_capacity(path.len());
        for pair in path.windows(2) {
            let (parent, node) = (pair[0], pair[1]);
            let Some(branch) = tree.branch(node) else {
                continue;
            };
            let rest = orientation * (tree.position(node) - tree.position(parent));
            let now = positions[node] - positions[parent];
            let bend = Rotation3::rotation_between(&rest, &now).unwrap_or_else(|| {
                // Folded straight back: half a turn about any perpendicular.
                Rotation3::new(rest.cross(&Vector3::x()).normalize() * std::f64::consts::PI)
            });
            let theta = bend.scaled_axis();
            orientation = bend * orientation;
            // K θ = r × F = [r]× F, in least squares over the path's
            // joints, each equation divided by K: the residual is then an
            // angle, the quantity a prediction errs in about equally at
            // every joint (a stiff trunk's tiny predicted rotation error
            // would otherwise dominate the force).
            let lever = grip - positions[parent];
            let skew = lever.cross_matrix() / branch.stiffness;
            normal += skew.transpose() * skew;
            rhs += skew.transpose() * theta;
            joints.push((node, lever, branch.radius));
        }
        let Ok(inverse) = normal.pseudo_inverse(1e-12) else {
            return loads;
        };
        let force = inverse * rhs;
        loads.contact_force = force.norm();
        // Each joint's moment from that force, M = |r × F|, not K|θ| read
        // joint by joint: at equilibrium they are equal, but a trunk's
        // stiffness times a millimetre of predicted noise reads as
        // gigapascals on a large tree (the path model's median stress error
        // at N = 200 was 150× that way).
        for (node, lever, radius) in joints {
            let stress = 4.0 * lever.cross(&force).norm() / (std::f64::consts::PI * radius.powi(3));
            if stress > loads.peak_stress {
                loads.peak_stress = stress;
                loads.peak_node = Some(node);
            }
        }
        loads
    }
}
