//! Forward kinematics and analytic Jacobians of the joints on one
//! root-to-node path.
//!
//! Only the joints between the root and the contacted node can move in a
//! quasi-static push: every other joint carries no load (gravity is off and
//! the branches are massless), so it keeps its rest angle. A [`PathChain`]
//! therefore holds just those joints, as local rotation vectors θ_k
//! (exponential coordinates, the joint's rotation relative to its rest pose).
//!
//! Branch k's world orientation is Q_k = Q_{k−1} · exp(θ_k), and its end node
//! sits at P_k = P_{k−1} + Q_k (p⁰_k − p⁰_{k−1}). Perturbing θ_k by δ turns
//! everything beyond joint k by the world rotation ω = Q_k J_r(θ_k) δ about
//! P_{k−1}, where J_r is the right Jacobian of SO(3); that gives every
//! Jacobian in closed form.

use nalgebra::{Matrix3, Point3, Rotation3, Vector3};

use crate::tree::Tree;

/// The movable joints between the root and one node.
#[derive(Debug, Clone)]
pub struct PathChain {
    /// Path nodes a_1 … a_m (a_m is the contacted node); a_0 is the root.
    pub nodes: Vec<usize>,
    /// Rest offsets p⁰_{a_k} − p⁰_{a_{k−1}}.
    offsets: Vec<Vector3<f64>>,
    /// K_s of each path joint (N·m/rad).
    pub stiffness: Vec<f64>,
    root: Point3<f64>,
}

/// The chain in one configuration.
#[derive(Debug, Clone)]
pub struct ChainPose {
    /// Q_k, world orientation of branch a_k (k = 1 … m).
    pub orientations: Vec<Rotation3<f64>>,
    /// P_0 … P_m: the root, then each path node.
    pub points: Vec<Point3<f64>>,
    /// W_k = Q_k J_r(θ_k): maps δθ_k to the world rotation it causes.
    pub angular: Vec<Matrix3<f64>>,
}

impl PathChain {
    pub fn new(tree: &Tree, node: usize) -> Self {
        let mut nodes = tree.path_to_root(node);
        nodes.pop(); // the root
        nodes.reverse();
        let offsets = nodes
            .iter()
            .map(|&a| tree.position(a) - tree.position(tree.parent(a).expect("non-root")))
            .collect();
        let stiffness = nodes
            .iter()
            .map(|&a| tree.branch(a).expect("non-root").stiffness)
            .collect();
        Self {
            nodes,
            offsets,
            stiffness,
            root: tree.position(0),
        }
    }

    /// Number of joints m (the contacted node's depth).
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// `theta` holds 3·m numbers: θ_1, …, θ_m.
    pub fn pose(&self, theta: &[f64]) -> ChainPose {
        let m = self.len();
        let mut orientations = Vec::with_capacity(m);
        let mut points = Vec::with_capacity(m + 1);
        let mut angular = Vec::with_capacity(m);
        let mut q = Rotation3::identity();
        let mut p = self.root;
        points.push(p);
        for k in 0..m {
            let t = Vector3::new(theta[3 * k], theta[3 * k + 1], theta[3 * k + 2]);
            q *= Rotation3::new(t);
            p += q * self.offsets[k];
            orientations.push(q);
            points.push(p);
            angular.push(q.matrix() * right_jacobian(&t));
        }
        ChainPose {
            orientations,
            points,
            angular,
        }
    }
}

/// Right Jacobian of SO(3): exp(θ + δ) ≈ exp(θ) exp(J_r(θ) δ).
pub fn right_jacobian(theta: &Vector3<f64>) -> Matrix3<f64> {
    let angle2 = theta.norm_squared();
    let hat = theta.cross_matrix();
    if angle2 < 1e-12 {
        // Series to second order; exact to rounding for such small angles.
        return Matrix3::identity() - hat * 0.5 + hat * hat / 6.0;
    }
    let angle = angle2.sqrt();
    Matrix3::identity() - hat * ((1.0 - angle.cos()) / angle2)
        + hat * hat * ((angle - angle.sin()) / (angle2 * angle))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn right_jacobian_matches_finite_differences() {
        for theta in [
            Vector3::new(0.3, -0.2, 0.9),
            Vector3::new(1e-7, 2e-7, -1e-7),
            Vector3::new(0.0, 2.5, 0.1),
        ] {
            let jr = right_jacobian(&theta);
            let base = Rotation3::new(theta);
            for i in 0..3 {
                let mut d = Vector3::zeros();
                d[i] = 1e-4;
                // exp(θ + δ) and exp(θ) exp(J_r δ) agree to O(|δ|²); a wrong
                // column would leave an O(|δ|) gap.
                let exact = Rotation3::new(theta + d);
                let linear = base * Rotation3::new(jr * d);
                let gap = (exact.matrix() - linear.matrix()).norm();
                assert!(gap < 1e-7, "{theta:?} column {i}: gap {gap}");
            }
        }
    }
}
