//! `/v1/simulate`.

use serde::{Deserialize, Serialize};
use treemanip_core::sim::contact::Hold;
use treemanip_core::sim::loads::PeakStress;
use treemanip_core::sim::{ContactModel, SolverReport};
use utoipa::ToSchema;

use crate::api::types::schema::Vec3;
use crate::api::types::tree::TreeJson;

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct SimulateRequest {
    pub tree: TreeJson,
    /// The node the gripper holds (not the root).
    #[serde(deserialize_with = "crate::api::json::integer::usize")]
    #[schema(minimum = 1, maximum = 511)]
    pub contact_node: usize,
    /// Gripper displacement T (m).
    #[schema(value_type = Vec3)]
    pub push: Vec<f64>,
    #[serde(default)]
    pub contact: ContactJson,
    /// Carry the push out as a guarded move that stops where the
    /// contact force first reaches this (N, > 0): a plan's
    /// `guard_contact_force`, tried on this tree. The answer is the tree
    /// where the arm stopped.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(exclusive_minimum = 0.0)]
    pub stop_at_contact_force: Option<f64>,
}

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct SimulateResponse {
    /// Steady-state node positions p′ (m).
    #[schema(value_type = Vec<Vec3>)]
    pub final_positions: Vec<[f64; 3]>,
    /// p′ − p per node (m).
    #[schema(value_type = Vec<Vec3>)]
    pub displacements: Vec<[f64; 3]>,
    pub contact: ContactJson,
    /// The force the gripper applies to the branch (N); a wrist
    /// force/torque sensor reads the opposite. The same as
    /// `solver.contact_force`.
    #[schema(value_type = Vec3)]
    pub contact_force: [f64; 3],
    /// Per node (null at the root), the bending moment at the base of its
    /// branch in the held state, K_s |θ_b| (N·m), θ_b the joint rotation's
    /// component across the branch. It equals the contact force's moment
    /// about the joint.
    pub branch_moment: Vec<Option<f64>>,
    /// Per node, the twisting moment about its branch's axis (N·m).
    pub branch_twist: Vec<Option<f64>>,
    /// Per node (null at the root), the bending stress at the base of its
    /// branch, 4M/(πr³) (Pa). Absolute only as far as the tree's stiffness
    /// is: see `wood_modulus`.
    pub branch_stress: Vec<Option<f64>>,
    /// Per node (null at the root), the wood's Young's modulus the branch's
    /// stiffness implies, 2ℓK_s/(πr⁴) (Pa): 5 GPa when the tree gives no
    /// `stiffness` (the radius formula), else the caller's stiffness read
    /// back as a modulus.
    pub wood_modulus: Vec<Option<f64>>,
    /// The largest bending stress and its node (null: nothing bends).
    #[schema(required = true)]
    pub peak_stress: Option<PeakStressJson>,
    pub solver: SolverReportJson,
    /// With `stop_at_contact_force`: how much of the push was carried out.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub guarded: Option<GuardedJson>,
}

/// What a guarded push did.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(as = Guarded)]
pub struct GuardedJson {
    /// Share of the push carried out (1: the guard never tripped).
    pub fraction: f64,
    /// Whether the guard stopped the arm before the push's end.
    pub stopped: bool,
}

/// How the gripper holds the branch: `slot` (it may slide along the
/// slot; the default) or `pinned` (the node moves exactly by the push).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
#[schema(as = Contact)]
pub enum ContactJson {
    #[default]
    Slot,
    Pinned,
}

impl From<ContactJson> for ContactModel {
    fn from(c: ContactJson) -> Self {
        match c {
            ContactJson::Slot => ContactModel::Slot,
            ContactJson::Pinned => ContactModel::Pinned,
        }
    }
}

impl From<ContactModel> for ContactJson {
    fn from(c: ContactModel) -> Self {
        match c {
            ContactModel::Slot => ContactJson::Slot,
            ContactModel::Pinned => ContactJson::Pinned,
        }
    }
}

/// The most stressed branch: its bending stress (Pa) and node.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(as = PeakStress)]
pub struct PeakStressJson {
    pub stress: f64,
    pub node: usize,
}

impl From<PeakStress> for PeakStressJson {
    fn from(p: PeakStress) -> Self {
        Self {
            stress: p.stress,
            node: p.node,
        }
    }
}

/// What the gripper ended up holding: the branch in its slot (`on_axis`),
/// the node itself (`at_node`: the slot slid to the fork at the tip, or
/// the pinned contact) or the fork at the branch's base (`at_base`: the
/// slot slid back to it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
#[schema(as = Hold)]
pub enum HoldJson {
    OnAxis,
    AtNode,
    AtBase,
}

impl From<Hold> for HoldJson {
    fn from(h: Hold) -> Self {
        match h {
            Hold::OnAxis => HoldJson::OnAxis,
            Hold::AtNode => HoldJson::AtNode,
            Hold::AtBase => HoldJson::AtBase,
        }
    }
}

/// How the solve went: iterations, the constraint (m) and relative KKT
/// residuals, the elastic energy (J), the hold, where along the branch
/// it holds (m), the contact force (N) and the largest joint angle (rad).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(as = SolverReport)]
pub struct SolverReportJson {
    pub iterations: usize,
    /// m.
    pub constraint_residual: f64,
    pub kkt_residual: f64,
    /// J.
    pub energy: f64,
    pub hold: HoldJson,
    /// m.
    #[schema(required = true)]
    pub slide: Option<f64>,
    /// N.
    #[schema(value_type = Vec3)]
    pub contact_force: [f64; 3],
    /// rad.
    pub max_joint_angle: f64,
}

impl From<&SolverReport> for SolverReportJson {
    fn from(r: &SolverReport) -> Self {
        Self {
            iterations: r.iterations,
            constraint_residual: r.constraint_residual,
            kkt_residual: r.kkt_residual,
            energy: r.energy,
            hold: r.hold.into(),
            slide: r.slide,
            contact_force: r.contact_force,
            max_joint_angle: r.max_joint_angle,
        }
    }
}
