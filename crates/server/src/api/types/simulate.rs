//! `/v1/simulate`.

use serde::{Deserialize, Serialize};
use treemanip_core::sim::loads::PeakStress;
use treemanip_core::sim::{ContactModel, SolverReport};

use crate::api::types::tree::TreeJson;

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimulateRequest {
    pub tree: TreeJson,
    #[serde(deserialize_with = "crate::api::json::integer::usize")]
    pub contact_node: usize,
    /// Gripper displacement T (m).
    pub push: Vec<f64>,
    /// `slot` (default) or `pinned`.
    #[serde(default)]
    pub contact: ContactModel,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SimulateResponse {
    /// Steady-state node positions p′ (m).
    pub final_positions: Vec<[f64; 3]>,
    /// p′ − p per node (m).
    pub displacements: Vec<[f64; 3]>,
    pub contact: ContactModel,
    /// The force the gripper applies to the branch (N); a wrist
    /// force/torque sensor reads the opposite. The same as
    /// `solver.contact_force`.
    pub contact_force: [f64; 3],
    /// Per node, the bending moment at the base of its branch (N·m); null
    /// at the root. See `treemanip_core::sim::loads`.
    pub branch_moment: Vec<Option<f64>>,
    /// Per node, the twisting moment about its branch's axis (N·m).
    pub branch_twist: Vec<Option<f64>>,
    /// Per node, the bending stress at the base of its branch (Pa).
    pub branch_stress: Vec<Option<f64>>,
    /// Per node, the wood's Young's modulus its branch's stiffness implies
    /// (Pa): 5 GPa with the default stiffness, else the caller's.
    pub wood_modulus: Vec<Option<f64>>,
    /// The largest bending stress and its node (null: nothing bends).
    pub peak_stress: Option<PeakStress>,
    pub solver: SolverReport,
}
