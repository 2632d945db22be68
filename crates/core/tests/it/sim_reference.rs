//! The push simulator against a deliberately simple, independent
//! minimiser on small random trees.

use crate::common::random_tree_and_pushes;
use crate::sim_physics::slot;
use treemanip_core::sim::{GRIP_OFFSET, Hold, Push, simulate};

/// A deliberately simple, independent minimiser: augmented Lagrangian over
/// all joints, its own forward kinematics and its own (3-vector) form of the
/// slot constraint, BFGS with finite-difference gradients.
mod reference {
    use super::*;
    use nalgebra::{DMatrix, DVector, Point3, Rotation3, Vector3};
    use treemanip_core::tree::Tree;

    pub fn positions(tree: &Tree, theta: &[f64]) -> Vec<Point3<f64>> {
        let n = tree.len();
        let mut world = vec![Rotation3::identity(); n];
        let mut pos = tree.positions().to_vec();
        // Parents precede children in generated trees.
        for j in 1..n {
            let p = tree.parent(j).unwrap();
            let r = Rotation3::new(Vector3::new(
                theta[3 * j],
                theta[3 * j + 1],
                theta[3 * j + 2],
            ));
            world[j] = world[p] * r;
            pos[j] = pos[p] + world[j] * (tree.position(j) - tree.position(p));
        }
        pos
    }

    pub fn solve(tree: &Tree, push: &Push) -> Vec<Point3<f64>> {
        let n = tree.len();
        let j = push.node;
        let i = tree.parent(j).unwrap();
        let axis0 = (tree.position(j) - tree.position(i)).normalize();
        let grip = tree.position(j) - axis0 * GRIP_OFFSET + push.vector;
        let sqrt_k: Vec<f64> = (0..n)
            .map(|k| tree.branch(k).map_or(1.0, |b| b.stiffness.sqrt()))
            .collect();
        let theta_of = |x: &[f64]| -> Vec<f64> {
            x.iter()
                .enumerate()
                .map(|(a, v)| v / sqrt_k[a / 3])
                .collect()
        };
        let constraint = |x: &[f64]| -> Vector3<f64> {
            let p = positions(tree, &theta_of(x));
            let axis = (p[j] - p[i]).normalize();
            let d = grip - p[i];
            d - axis * d.dot(&axis)
        };
        let dim = 3 * n;
        let mut x = vec![0.0; dim];
        let mut lambda = Vector3::zeros();
        let mu = 1e4;
        for _outer in 0..30 {
            let f = |x: &[f64]| {
                let c = constraint(x);
                0.5 * x[3..].iter().map(|v| v * v).sum::<f64>()
                    + lambda.dot(&c)
                    + 0.5 * mu * c.norm_squared()
            };
            x = bfgs(&f, x, dim);
            lambda += constraint(&x) * mu;
        }
        positions(tree, &theta_of(&x))
    }

    fn gradient(f: &dyn Fn(&[f64]) -> f64, x: &[f64]) -> DVector<f64> {
        let mut g = DVector::zeros(x.len());
        let mut probe = x.to_vec();
        for a in 3..x.len() {
            let h = 1e-7;
            probe[a] = x[a] + h;
            let up = f(&probe);
            probe[a] = x[a] - h;
            let down = f(&probe);
            probe[a] = x[a];
            g[a] = (up - down) / (2.0 * h);
        }
        g
    }

    fn bfgs(f: &dyn Fn(&[f64]) -> f64, x0: Vec<f64>, dim: usize) -> Vec<f64> {
        let mut x = DVector::from_vec(x0);
        let mut inv_h = DMatrix::<f64>::identity(dim, dim) * 1e-4;
        let mut g = gradient(f, x.as_slice());
        for _ in 0..2000 {
            if g.amax() < 1e-9 {
                break;
            }
            let d = -(&inv_h * &g);
            let fx = f(x.as_slice());
            let mut step = 1.0;
            while f((&x + &d * step).as_slice()) > fx + 1e-4 * step * g.dot(&d) && step > 1e-12 {
                step *= 0.5;
            }
            let s = &d * step;
            let nx = &x + &s;
            let ng = gradient(f, nx.as_slice());
            let y = &ng - &g;
            let sy = s.dot(&y);
            if sy > 1e-16 {
                let rho = 1.0 / sy;
                let eye = DMatrix::<f64>::identity(dim, dim);
                let left = &eye - (&s * y.transpose()) * rho;
                let right = &eye - (&y * s.transpose()) * rho;
                inv_h = &left * &inv_h * &right + (&s * s.transpose()) * rho;
            }
            x = nx;
            g = ng;
        }
        x.as_slice().to_vec()
    }
}

#[test]
fn an_independent_minimiser_agrees_on_small_trees() {
    let mut compared = 0;
    for seed in 0..40u64 {
        if compared == 6 {
            break;
        }
        let n = 5 + (seed as usize % 3);
        let (tree, pushes) = random_tree_and_pushes(500 + seed, n, 1);
        let push = pushes[0];
        let Ok(out) = simulate(&tree, &push, &slot()) else {
            continue;
        };
        if out.report.hold != Hold::OnAxis {
            continue;
        }
        let reference = reference::solve(&tree, &push);
        let worst = reference
            .iter()
            .zip(&out.final_positions)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        assert!(worst < 1e-4, "seed {seed}: the two disagree by {worst} m");
        compared += 1;
    }
    assert_eq!(compared, 6);
}
