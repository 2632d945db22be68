//! The linearised push: the quasi-static model's answer to first order in
//! the joint rotations, in closed form.
//!
//! With every joint at rest, turning path joint k (at P_{k−1}) by θ_k moves
//! the held point g by θ_k × r_k, r_k = g − P_{k−1}. The energy ½ Σ K_k
//! |θ_k|² is least, for a given contact force λ, at θ_k = K_k⁻¹ r_k × λ, so
//! g moves by δ = C λ with the path's compliance
//!
//! ```text
//!     C = Σ_k K_k⁻¹ (|r_k|² I − r_k r_kᵀ).
//! ```
//!
//! The pinned hold asks δ = T (λ = C⁻¹ T); the slot asks only the two
//! components across the branch (λ in that plane, 2 × 2). Exact for small
//! pushes; for the paper's 5-15 cm pushes on 10 cm branches the rotations
//! are large and it is a first guess, which the path forward model
//! ([`crate::graph::path`]) corrects. It costs O(path) and never fails.

use nalgebra::{Matrix2, Matrix3, Point3, Vector2, Vector3};

use super::Push;
use super::contact::{ContactModel, GRIP_OFFSET};
use crate::tree::Tree;

/// Each path joint's rotation (node of the branch it turns, θ in rad) under
/// the linearised model; empty for the root or a node out of range.
pub fn linear_rotations(
    tree: &Tree,
    push: &Push,
    contact: ContactModel,
) -> Vec<(usize, Vector3<f64>)> {
    let c = push.node;
    if c == 0 || c >= tree.len() {
        return Vec::new();
    }
    let axis = tree.branch_direction(c).unwrap_or_else(Vector3::z);
    let held = match contact {
        ContactModel::Slot => tree.position(c) - axis * GRIP_OFFSET,
        ContactModel::Pinned => tree.position(c),
    };
    least_energy_turns(
        tree,
        tree.positions(),
        c,
        &held,
        &axis,
        &push.vector,
        contact,
    )
}

/// The least-energy turns of node `c`'s path joints, the tree placed at
/// `positions`, that move the point `held` of `c`'s branch by `shift`
/// (pinned), or by `shift`'s two components across the branch direction
/// `axis` (slot: the branch may slide along it). Each is a rotation vector
/// (rad, world frame) about its joint where `positions` put it, keyed by the
/// node of the branch it turns, contact first. At rest this is the
/// linearised push ([`linear_rotations`]); placed elsewhere, one step of
/// the same solve from there. Empty for the root or a node out of range.
pub fn least_energy_turns(
    tree: &Tree,
    positions: &[Point3<f64>],
    c: usize,
    held: &Point3<f64>,
    axis: &Vector3<f64>,
    shift: &Vector3<f64>,
    contact: ContactModel,
) -> Vec<(usize, Vector3<f64>)> {
    if c == 0 || c >= tree.len() || positions.len() != tree.len() {
        return Vec::new();
    }
    let mut path = tree.path_to_root(c);
    path.pop();
    let joints: Vec<(usize, Vector3<f64>, f64)> = path
        .iter()
        .map(|&a| {
            let joint = positions[tree.parent(a).expect("non-root")];
            (
                a,
                held - joint,
                1.0 / tree.branch(a).expect("non-root").stiffness,
            )
        })
        .collect();
    let mut compliance = Matrix3::zeros();
    for (_, r, s) in &joints {
        compliance += (Matrix3::identity() * r.norm_squared() - r * r.transpose()) * *s;
    }
    let force = match contact {
        ContactModel::Pinned => compliance
            .pseudo_inverse(1e-12)
            .map_or_else(|_| Vector3::zeros(), |inv| inv * shift),
        ContactModel::Slot => {
            let helper = if axis.x.abs() < 0.9 {
                Vector3::x()
            } else {
                Vector3::y()
            };
            let e1 = axis.cross(&helper).normalize();
            let e2 = axis.cross(&e1);
            let a = Matrix2::new(
                e1.dot(&(compliance * e1)),
                e1.dot(&(compliance * e2)),
                e2.dot(&(compliance * e1)),
                e2.dot(&(compliance * e2)),
            );
            let b = Vector2::new(e1.dot(shift), e2.dot(shift));
            a.try_inverse().map_or_else(Vector3::zeros, |inv| {
                let x = inv * b;
                e1 * x.x + e2 * x.y
            })
        }
    };
    joints
        .iter()
        .map(|(a, r, s)| (*a, r.cross(&force) * *s))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{SimConfig, simulate};
    use crate::tree::{OrchardParams, generate_orchard};

    #[test]
    fn small_pushes_match_the_simulator_to_second_order() {
        let tree = generate_orchard(120, 3, &OrchardParams::default()).unwrap();
        let node = (1..tree.len())
            .filter(|&j| !tree.is_leaf(j) && tree.depth(j) >= 5)
            .max_by_key(|&j| tree.depth(j))
            .unwrap();
        let across = tree
            .branch_direction(node)
            .unwrap()
            .cross(&Vector3::z())
            .normalize();
        for contact in [ContactModel::Pinned, ContactModel::Slot] {
            let config = SimConfig {
                contact,
                ..SimConfig::default()
            };
            let mut gaps = Vec::new();
            for length in [0.002, 0.004] {
                let push = Push {
                    node,
                    vector: across * length,
                };
                let exact = simulate(&tree, &push, &config).unwrap();
                let mut all = vec![Vector3::zeros(); tree.len()];
                for (j, t) in linear_rotations(&tree, &push, contact) {
                    all[j] = t;
                }
                let linear = crate::sim::deformed_positions(&tree, &all);
                let gap = linear
                    .iter()
                    .zip(&exact.final_positions)
                    .map(|(a, b)| (a - b).norm())
                    .fold(0.0, f64::max);
                gaps.push(gap);
            }
            // Second order: twice the push, four times the gap.
            let ratio = gaps[1] / gaps[0];
            assert!((3.0..5.0).contains(&ratio), "{contact:?}: {gaps:?}");
            assert!(gaps[0] < 1e-4, "{contact:?}: {gaps:?}");
        }
    }
}
