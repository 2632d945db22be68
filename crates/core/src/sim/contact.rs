//! How the ⊔-shaped gripper holds the contacted branch, as equality
//! constraints on the path joints.
//!
//! - [`ContactModel::Slot`] (default): the branch lies in the gripper's slot
//!   at a point [`GRIP_OFFSET`] back from the contacted node along the
//!   branch. The gripper moves by T; the branch may slide along the slot and
//!   turn in it, so only the two directions across the slot are constrained:
//!   the gripper point g = p⁰_j − 0.01·b̂ + T must lie on the deformed
//!   branch axis. Two constraints, c_r = u_r · (g − P_{m−1}), where u_1, u_2
//!   are unit vectors fixed to the branch, perpendicular to its axis.
//!   When the branch would slide out of the slot past its node: at a fork
//!   the slot catches on the child branches and from then on carries the
//!   node itself to g ([`Hold::AtNode`]); at a leaf tip the branch is lost.
//!   Slid back past the branch's base, the slot catches on the fork there
//!   the same way and carries the fork node to g ([`Hold::AtBase`]); at
//!   the trunk's foot, which nothing carries, the branch is lost.
//! - [`ContactModel::Pinned`]: the contacted node itself is carried exactly
//!   by T: P_m = p⁰_j + T. Three constraints.

use nalgebra::{DMatrix, DVector, Point3, Vector3};
use serde::{Deserialize, Serialize};

use super::path_joints::{ChainPose, PathChain};
use crate::tree::Tree;

/// Where the slot holds the branch: this far back from the contacted node
/// along the branch (m), as in the original data collection.
pub const GRIP_OFFSET: f64 = 0.01;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ContactModel {
    /// The branch may slide along the gripper's slot (2 constraints).
    #[default]
    Slot,
    /// The contacted node moves exactly by the push (3 constraints).
    Pinned,
}

impl std::str::FromStr for ContactModel {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "slot" => Ok(Self::Slot),
            "pinned" => Ok(Self::Pinned),
            other => Err(format!("unknown contact model `{other}` (slot or pinned)")),
        }
    }
}

/// What the gripper holds, as constraints.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Hold {
    /// The branch axis passes through the gripper point (2 constraints).
    OnAxis,
    /// The contacted node is at the gripper point (3 constraints).
    AtNode,
    /// The slot slid back to the fork at the contacted branch's base and
    /// caught there: the fork node is at the gripper point (3 constraints
    /// on the path to that node; the contacted branch moves rigidly with
    /// it).
    AtBase,
}

/// One push's contact constraints.
#[derive(Debug, Clone)]
pub struct Contact {
    pub hold: Hold,
    /// Where the gripper point ends up (m).
    pub target: Point3<f64>,
    /// Rest direction of the contacted branch (unit).
    pub rest_axis: Vector3<f64>,
    /// Two unit vectors perpendicular to `rest_axis` (slot model).
    rest_across: [Vector3<f64>; 2],
}

impl Contact {
    /// The constraints a push starts with under `model`.
    pub fn new(tree: &Tree, node: usize, push: &Vector3<f64>, model: ContactModel) -> Self {
        let rest_axis = tree.branch_direction(node).expect("non-root contact");
        let first = rest_axis.cross(&least_aligned_axis(&rest_axis)).normalize();
        let second = rest_axis.cross(&first);
        let (hold, target) = match model {
            ContactModel::Slot => (
                Hold::OnAxis,
                tree.position(node) - rest_axis * GRIP_OFFSET + push,
            ),
            ContactModel::Pinned => (Hold::AtNode, tree.position(node) + push),
        };
        Self {
            hold,
            target,
            rest_axis,
            rest_across: [first, second],
        }
    }

    /// The same gripper point, now holding the node itself (the slot caught
    /// on a fork).
    pub fn caught_at_node(&self) -> Self {
        Self {
            hold: Hold::AtNode,
            ..self.clone()
        }
    }

    /// The same hold with the gripper only `fraction` of the way along
    /// `push` (the last part of the push not yet made): for following the
    /// push path by continuation.
    pub fn partway(&self, push: &Vector3<f64>, fraction: f64) -> Self {
        Self {
            target: self.target - push * (1.0 - fraction),
            ..self.clone()
        }
    }

    pub fn rows(&self) -> usize {
        match self.hold {
            Hold::OnAxis => 2,
            Hold::AtNode | Hold::AtBase => 3,
        }
    }

    /// Constraint values (m) and their Jacobian with respect to the chain's
    /// joint rotation vectors (m/rad), rows × 3m.
    pub fn evaluate(&self, chain: &PathChain, pose: &ChainPose) -> (DVector<f64>, DMatrix<f64>) {
        let m = chain.len();
        let mut c = DVector::zeros(self.rows());
        let mut jac = DMatrix::zeros(self.rows(), 3 * m);
        let q_last = pose.orientations[m - 1];
        match self.hold {
            Hold::OnAxis => {
                let pivot = pose.points[m - 1];
                let d = self.target - pivot;
                for (r, across) in self.rest_across.iter().enumerate() {
                    let u = q_last * across;
                    c[r] = u.dot(&d);
                    let turn = u.cross(&d);
                    for k in 0..m {
                        // Joint k turns u (always) and moves the pivot (k < m).
                        let lever = pivot - pose.points[k];
                        let row = (turn - lever.cross(&u)).transpose() * pose.angular[k];
                        jac.view_mut((r, 3 * k), (1, 3)).copy_from(&row);
                    }
                }
            }
            Hold::AtNode | Hold::AtBase => {
                let tip = pose.points[m];
                c.copy_from(&(tip - self.target));
                for k in 0..m {
                    let lever = tip - pose.points[k];
                    let block = -lever.cross_matrix() * pose.angular[k];
                    jac.view_mut((0, 3 * k), (3, 3)).copy_from(&block);
                }
            }
        }
        (c, jac)
    }

    /// How far from the pivot (the contacted branch's parent
    /// node) the gripper holds the deformed branch, along its axis (m).
    pub fn slide(&self, chain: &PathChain, pose: &ChainPose) -> f64 {
        let m = chain.len();
        (pose.orientations[m - 1] * self.rest_axis).dot(&(self.target - pose.points[m - 1]))
    }

    /// The force the gripper exerts on the branch (N) from the constraint
    /// multipliers λ of  min E(θ) + λᵀc(θ): the Jacobian of the slot rows is
    /// −u_rᵀ ∂x/∂θ at the held point x, and that of the pinned rows +∂x/∂θ,
    /// so balancing K θ = (∂x/∂θ)ᵀ F gives F = Σ λ_r u_r, resp. F = −λ.
    pub fn force(
        &self,
        chain: &PathChain,
        pose: &ChainPose,
        lambda: &DVector<f64>,
    ) -> Vector3<f64> {
        match self.hold {
            Hold::OnAxis => {
                let q = pose.orientations[chain.len() - 1];
                self.rest_across
                    .iter()
                    .enumerate()
                    .map(|(r, across)| q * across * lambda[r])
                    .sum()
            }
            Hold::AtNode | Hold::AtBase => -Vector3::new(lambda[0], lambda[1], lambda[2]),
        }
    }
}

/// The coordinate axis most perpendicular to `v`, for building a basis.
fn least_aligned_axis(v: &Vector3<f64>) -> Vector3<f64> {
    let a = v.abs();
    if a.x <= a.y && a.x <= a.z {
        Vector3::x()
    } else if a.y <= a.z {
        Vector3::y()
    } else {
        Vector3::z()
    }
}
