//! The solver finds the steady state of the pushes the data set is made of:
//! over random Space Colonization trees and paper-style pushes, with slot
//! and pinned contact, a push either settles (constraints met, KKT point)
//! or is refused for a physical reason (lost branch, out of reach, folded),
//! and "did not converge" stays below 0.1 % of attempts.
//!
//! Before the solver's stopping test was made aware of rounding (the test
//! on the Newton step) and the continuation along the push path was added,
//! this failed: 0.7 % of slot and 4 % of pinned pushes were reported as not
//! converged, most of them with a constraint residual of 0.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use treemanip::sim::sampling::PushDistribution;
use treemanip::sim::{ContactModel, SimConfig, SimError, simulate};
use treemanip::tree::{ScaParams, generate};

fn not_converged_rate(contact: ContactModel) -> (usize, usize) {
    let config = SimConfig {
        contact,
        ..SimConfig::default()
    };
    let (mut attempts, mut failed) = (0, 0);
    for (k, n) in (0..40).map(|k| (k, [10, 13, 16, 19, 24, 30][k % 6])) {
        let tree = generate(n, 9_000 + k as u64, &ScaParams::default()).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(k as u64);
        for _ in 0..60 {
            let push = PushDistribution::default().sample(&tree, &mut rng);
            attempts += 1;
            match simulate(&tree, &push, &config) {
                Ok(out) => {
                    assert!(out.report.constraint_residual < 1e-9, "{:?}", out.report);
                    assert!(out.report.kkt_residual < 1e-6, "{:?}", out.report);
                    let moved = (out.final_positions[push.node] - tree.position(push.node)).norm();
                    assert!(moved.is_finite() && moved < 1.0);
                }
                Err(SimError::NotConverged { .. }) => failed += 1,
                Err(
                    SimError::LostBranch { .. }
                    | SimError::OutOfReach { .. }
                    | SimError::OverRotated { .. },
                ) => {}
                Err(other) => panic!("unexpected refusal of {push:?}: {other}"),
            }
        }
    }
    (attempts, failed)
}

#[test]
fn slot_pushes_converge() {
    let (attempts, failed) = not_converged_rate(ContactModel::Slot);
    assert!(
        failed * 1000 < attempts,
        "{failed} of {attempts} did not converge"
    );
}

#[test]
fn pinned_pushes_converge() {
    let (attempts, failed) = not_converged_rate(ContactModel::Pinned);
    assert!(
        failed * 1000 < attempts,
        "{failed} of {attempts} did not converge"
    );
}
