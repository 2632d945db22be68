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
