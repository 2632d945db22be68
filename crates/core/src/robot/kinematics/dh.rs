//! The UR5's kinematic constants: Denavit–Hartenberg parameters and joint
//! limits. A module of their own so that forward kinematics ([`crate::robot::ur5`])
//! and the closed-form inverse ([`crate::robot::kinematics::ur_closed_form`]) both read them without
//! importing each other.

use std::f64::consts::{FRAC_PI_2, PI};

/// Universal Robots' UR5 DH parameters (m, rad).
pub const DH_D: [f64; 6] = [0.089159, 0.0, 0.0, 0.10915, 0.09465, 0.0823];
pub const DH_A: [f64; 6] = [0.0, -0.425, -0.39225, 0.0, 0.0, 0.0];
pub const DH_ALPHA: [f64; 6] = [FRAC_PI_2, 0.0, 0.0, FRAC_PI_2, -FRAC_PI_2, 0.0];

/// Joint position limits (rad): ±2π, the elbow ±π (it would hit itself).
pub const JOINT_LIMITS: [(f64, f64); 6] = [
    (-2.0 * PI, 2.0 * PI),
    (-2.0 * PI, 2.0 * PI),
    (-PI, PI),
    (-2.0 * PI, 2.0 * PI),
    (-2.0 * PI, 2.0 * PI),
    (-2.0 * PI, 2.0 * PI),
];
