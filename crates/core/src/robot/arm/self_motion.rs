//! Moving a redundant arm along its self-motion: the one-parameter family
//! of configurations of a 7-joint arm that hold the tool still (the elbow
//! swinging about the shoulder-wrist line). A pre-contact configuration
//! whose elbow or wrist housing touches a branch often has a free one a
//! short swing away; random IK restarts find other families, not the
//! neighbours of this one.

use nalgebra::{DVector, Matrix6, Vector6};

use crate::robot::arm::{Arm, SAME_SOLUTION, Solver};
use crate::robot::model::joint_vector::JointVector;

impl Arm {
    /// Configurations holding the tool where `q` holds it, one per step in
    /// `swings` (rad, along the unit null-space direction of the
    /// Jacobian at `q`) that solves back onto the pose within the joint
    /// limits and differs from `q` and the others. Empty for arms without
    /// redundancy (and for the UR closed form, which has none).
    pub fn self_motions(&self, q: &JointVector, swings: &[f64]) -> Vec<JointVector> {
        let n = self.dof();
        if !matches!(self.solver, Solver::Numeric) || n <= 6 {
            return Vec::new();
        }
        let (tip, jac) = self.chain.jacobian(q);
        let jjt = Matrix6::from_fn(|r, c| (0..n).map(|k| jac[(r, k)] * jac[(c, k)]).sum::<f64>())
            + Matrix6::identity() * 1e-9;
        let Some(cholesky) = jjt.cholesky() else {
            return Vec::new();
        };
        // (I − J⁺J) e_k for each joint axis; the longest is the null space
        // (one-dimensional for 7 joints) best resolved.
        let null = (0..n)
            .map(|k| {
                let jv = Vector6::from_fn(|r, _| jac[(r, k)]);
                let y = cholesky.solve(&jv);
                let mut v =
                    DVector::from_fn(n, |i, _| -(0..6).map(|r| jac[(r, i)] * y[r]).sum::<f64>());
                v[k] += 1.0;
                v
            })
            .max_by(|a, b| a.norm().total_cmp(&b.norm()));
        let Some(null) = null.filter(|v| v.norm() > 1e-6) else {
            return Vec::new();
        };
        let null = null.normalize();
        let limits = self.chain.limits();
        let mut out: Vec<JointVector> = Vec::new();
        for swing in swings {
            let start: Vec<f64> = (0..n)
                .map(|i| (q[i] + swing * null[i]).clamp(limits[i].0, limits[i].1))
                .collect();
            if let Some(r) = self.solve_from(&tip, &start) {
                if r.max_abs_diff(q) > SAME_SOLUTION
                    && out.iter().all(|o| o.max_abs_diff(&r) > SAME_SOLUTION)
                {
                    out.push(r);
                }
            }
        }
        out
    }
}
