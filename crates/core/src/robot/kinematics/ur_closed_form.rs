//! Closed-form inverse kinematics of the UR5 (after K. P. Hawkins,
//! "Analytic Inverse Kinematics for the Universal Robots UR-5/UR-10 Arms",
//! 2013): up to eight solutions per flange pose — shoulder left/right (θ1),
//! wrist up/down (θ5), elbow up/down (θ3).
//!
//! Singular cases: with the wrist centre on the shoulder axis (shoulder
//! singularity) the two θ1 branches coincide and are returned once; with
//! θ5 = 0 (wrist singularity, axes 4 and 6 aligned) θ6 is free and is taken
//! from the caller's reference configuration, the rest follow from it.

use std::f64::consts::{FRAC_PI_2, PI};

use nalgebra::{Matrix4, Vector4};

use crate::robot::kinematics::dh::{DH_A, DH_ALPHA, DH_D, JOINT_LIMITS};

/// The lengths of a UR arm's DH model (m); the twists α are the same for
/// every UR (±π/2 at joints 1, 4 and 5).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UrDh {
    pub d: [f64; 6],
    pub a: [f64; 6],
}

/// The UR5's (Universal Robots' published parameters).
pub const UR5_DH: UrDh = UrDh { d: DH_D, a: DH_A };

/// One DH link transform Rz(θ) Tz(d) Tx(a) Rx(α) of the UR5.
pub fn dh_transform(i: usize, theta: f64) -> Matrix4<f64> {
    dh_transform_with(&UR5_DH, i, theta)
}

/// One DH link transform Rz(θ) Tz(d) Tx(a) Rx(α) of the arm `dh`.
pub fn dh_transform_with(dh: &UrDh, i: usize, theta: f64) -> Matrix4<f64> {
    let (ct, st) = (theta.cos(), theta.sin());
    let (ca, sa) = (DH_ALPHA[i].cos(), DH_ALPHA[i].sin());
    let (a, d) = (dh.a[i], dh.d[i]);
    #[rustfmt::skip]
    let m = Matrix4::new(
        ct, -st * ca,  st * sa, a * ct,
        st,  ct * ca, -ct * sa, a * st,
        0.0,      sa,       ca, d,
        0.0,     0.0,      0.0, 1.0,
    );
    m
}

/// Flange pose in the DH base frame (UR5).
pub fn forward(q: &[f64; 6]) -> Matrix4<f64> {
    forward_with(&UR5_DH, q)
}

/// Flange pose in the DH base frame of the arm `dh`.
pub fn forward_with(dh: &UrDh, q: &[f64; 6]) -> Matrix4<f64> {
    (0..6).fold(Matrix4::identity(), |t, i| {
        t * dh_transform_with(dh, i, q[i])
    })
}

/// Below this |sin θ5| the wrist counts as singular.
const WRIST_SINGULAR: f64 = 1e-9;

/// All solutions for the flange pose `t06` (in the DH base frame), each
/// joint in (−π, π]. `reference` supplies θ6 at a wrist singularity.
/// Empty when the pose is out of reach.
pub fn solve(t06: &Matrix4<f64>, reference: &[f64; 6]) -> Vec<[f64; 6]> {
    solve_with(&UR5_DH, t06, reference)
}

/// [`solve`] for the UR arm `dh`.
pub fn solve_with(dh: &UrDh, t06: &Matrix4<f64>, reference: &[f64; 6]) -> Vec<[f64; 6]> {
    let dh_transform = |i: usize, theta: f64| dh_transform_with(dh, i, theta);
    let (d4, d6) = (dh.d[3], dh.d[5]);
    let (a2, a3) = (dh.a[1], dh.a[2]);
    let mut out = Vec::with_capacity(8);

    // θ1 from the wrist centre p05 (the flange pulled back by d6).
    let p05 = t06 * Vector4::new(0.0, 0.0, -d6, 1.0);
    let r = p05.x.hypot(p05.y);
    if r < d4.abs() {
        return out; // the wrist centre is inside the shoulder's offset cylinder
    }
    let psi = p05.y.atan2(p05.x);
    let phi = (d4 / r).clamp(-1.0, 1.0).acos();
    let mut theta1s = vec![psi + phi + FRAC_PI_2, psi - phi + FRAC_PI_2];
    if phi < 1e-12 {
        theta1s.pop(); // shoulder singularity: one branch
    }
    let p06 = t06.fixed_view::<3, 1>(0, 3);
    let t60 = rigid_inverse(t06);
    for theta1 in theta1s {
        let (s1, c1) = theta1.sin_cos();
        let cos5 = (p06.x * s1 - p06.y * c1 - d4) / d6;
        if cos5.abs() > 1.0 + 1e-12 {
            continue;
        }
        let base5 = cos5.clamp(-1.0, 1.0).acos();
        let theta5s: &[f64] = if base5 < 1e-12 {
            &[0.0]
        } else {
            &[base5, -base5]
        };
        for &theta5 in theta5s {
            let s5 = theta5.sin();
            let theta6 = if s5.abs() < WRIST_SINGULAR {
                reference[5]
            } else {
                let (xx, xy) = (t60[(0, 0)], t60[(1, 0)]);
                let (yx, yy) = (t60[(0, 1)], t60[(1, 1)]);
                ((-xy * s1 + yy * c1) / s5).atan2((xx * s1 - yx * c1) / s5)
            };
            // Planar 3R problem of joints 2, 3, 4 in frame 1.
            let t14 = rigid_inverse(&dh_transform(0, theta1))
                * t06
                * rigid_inverse(&(dh_transform(4, theta5) * dh_transform(5, theta6)))
                * rigid_inverse(&dh_transform(3, 0.0));
            // t14 now maps frame 3' (frame 4 without θ4) into frame 1.
            let p13 = t14.fixed_view::<3, 1>(0, 3);
            let reach2 = p13.x * p13.x + p13.y * p13.y;
            let cos3 = (reach2 - a2 * a2 - a3 * a3) / (2.0 * a2 * a3);
            if cos3.abs() > 1.0 + 1e-12 {
                continue;
            }
            let base3 = cos3.clamp(-1.0, 1.0).acos();
            let theta3s: &[f64] = if base3 < 1e-12 {
                &[0.0]
            } else {
                &[base3, -base3]
            };
            for &theta3 in theta3s {
                let theta2 = p13.y.atan2(p13.x) - (a3 * theta3.sin()).atan2(a2 + a3 * theta3.cos());
                // θ4 turns frame 3 into frame 4 about z: read it off the rotation
                // that remains after joints 2 and 3.
                let t34 = rigid_inverse(&(dh_transform(1, theta2) * dh_transform(2, theta3))) * t14;
                let theta4 = t34[(1, 0)].atan2(t34[(0, 0)]);
                out.push([theta1, theta2, theta3, theta4, theta5, theta6].map(wrap));
            }
        }
    }
    out
}

/// The inverse of a rigid transform [R p; 0 1]: [Rᵀ −Rᵀp; 0 1], in closed
/// form (a general 4×4 inverse is several times the work).
fn rigid_inverse(t: &Matrix4<f64>) -> Matrix4<f64> {
    let r = t.fixed_view::<3, 3>(0, 0).transpose();
    let p = -(r * t.fixed_view::<3, 1>(0, 3));
    let mut out = Matrix4::identity();
    out.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
    out.fixed_view_mut::<3, 1>(0, 3).copy_from(&p);
    out
}

/// Into (−π, π].
pub fn wrap(angle: f64) -> f64 {
    let mut a = angle % (2.0 * PI);
    if a <= -PI {
        a += 2.0 * PI;
    } else if a > PI {
        a -= 2.0 * PI;
    }
    a
}

/// The equivalent of `q` (each joint moved by multiples of 2π) that is
/// closest to `reference` joint by joint and within the limits; `None` when
/// some joint has no equivalent inside its limits.
pub fn nearest_within_limits(q: &[f64; 6], reference: &[f64; 6]) -> Option<[f64; 6]> {
    let mut out = [0.0; 6];
    for i in 0..6 {
        let (lo, hi) = JOINT_LIMITS[i];
        let k = ((reference[i] - q[i]) / (2.0 * PI)).round();
        let mut best: Option<f64> = None;
        for shift in [k - 1.0, k, k + 1.0] {
            let candidate = q[i] + shift * 2.0 * PI;
            if (lo..=hi).contains(&candidate)
                && best.is_none_or(|b| (candidate - reference[i]).abs() < (b - reference[i]).abs())
            {
                best = Some(candidate);
            }
        }
        out[i] = best?;
    }
    Some(out)
}
