//! Inverse kinematics (layer 2 of [`crate::robot`]).
//!
//! - [`numeric_ik`]: damped least squares for any chain, with restarts;
//! - [`dh`]: the UR5's Denavit-Hartenberg parameters;
//! - [`ur_closed_form`]: the UR family's eight closed-form solutions;
//! - [`ur_kinematics`]: recognising a UR-like chain and solving it in closed
//!   form.

pub mod dh;
pub mod numeric_ik;
pub mod ur_closed_form;
pub mod ur_kinematics;
