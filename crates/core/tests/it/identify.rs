//! Stiffness identification (`treemanip_core::identify`) against hidden
//! stiffness: synthetic probes simulated on a perturbed tree, the fit
//! started from the radius formula.

use nalgebra::{Point3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use treemanip_core::identify::probes::{ProbeRequest, choose_probes};
use treemanip_core::identify::{
    IdentifyConfig, Noise, Posterior, Probe, Scale, Status, identify, observe, validate_probes,
    with_stiffness,
};
use treemanip_core::sim::{ContactModel, Push};
use treemanip_core::tree::{ScaParams, StiffnessVariation, Tree, generate};

/// A tree (radius formula) and its hidden truth (ε ~ N(0, σ²) per branch,
/// times `global`).
fn scenario(n: usize, seed: u64, sigma: f64, global: f64) -> (Tree, Tree) {
    let nominal = generate(n, seed, &ScaParams::default()).unwrap();
    let variation = StiffnessVariation {
        branch_log_sigma: sigma,
        global_factor: 1.0,
    };
    let varied = variation.apply(&nominal, &mut ChaCha8Rng::seed_from_u64(seed + 100));
    let k: Vec<f64> = varied
        .branches()
        .iter()
        .map(|b| b.map_or(0.0, |b| b.stiffness * global))
        .collect();
    (nominal.clone(), with_stiffness(&nominal, &k))
}

fn probes(
    truth: &Tree,
    nominal: &Tree,
    count: usize,
    noise: &Noise,
    force: bool,
    seed: u64,
) -> Vec<Probe> {
    let posterior = Posterior::prior(nominal, &IdentifyConfig::default());
    let request = ProbeRequest {
        count,
        ..ProbeRequest::default()
    };
    let chosen = choose_probes(
        nominal,
        &posterior,
        &request,
        &IdentifyConfig::default(),
        &|_| true,
    );
    assert_eq!(chosen.len(), count, "enough candidate probes simulate");
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    chosen
        .iter()
        .filter_map(|c| observe(truth, c.push, c.contact, noise, force, &mut rng))
        .collect()
}

/// |ln K̂ − ln K| after removing the best common offset (the level
/// positions cannot see), over the branches with `status`.
fn ratio_errors(estimate: &[Option<f64>], truth: &Tree, keep: &[bool]) -> Vec<f64> {
    let d: Vec<(usize, f64)> = (1..truth.len())
        .filter(|&j| keep[j])
        .map(|j| {
            (
                j,
                estimate[j].unwrap().ln() - truth.branch(j).unwrap().stiffness.ln(),
            )
        })
        .collect();
    let offset = d.iter().map(|x| x.1).sum::<f64>() / d.len().max(1) as f64;
    d.iter().map(|x| (x.1 - offset).abs()).collect()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
fn recovers_stiffness_ratios_better_than_the_radius_formula() {
    let noise = Noise::default();
    let (mut fitted, mut formula) = (Vec::new(), Vec::new());
    for seed in 0..3 {
        let (nominal, truth) = scenario(15, 40 + seed, 0.3, 1.0);
        let probes = probes(&truth, &nominal, 5, &noise, false, seed);
        validate_probes(&nominal, &probes, &noise).unwrap();
        let result = identify(&nominal, &probes, &IdentifyConfig::default());
        assert_eq!(result.scale, Scale::Relative);
        assert!(result.fit.converged, "{:?}", result.fit);
        assert!(result.fit.position_rms < result.fit.prior_position_rms);
        // Within a few noise levels: the model is exact.
        assert!(
            result.fit.position_rms < 1.5 * noise.position,
            "{:?}",
            result.fit
        );
        let identified: Vec<bool> = result
            .status
            .iter()
            .map(|s| *s == Some(Status::Identified))
            .collect();
        assert!(identified.iter().filter(|x| **x).count() >= 3);
        let nominal_k: Vec<Option<f64>> = nominal
            .branches()
            .iter()
            .map(|b| b.map(|b| b.stiffness))
            .collect();
        fitted.extend(ratio_errors(&result.stiffness, &truth, &identified));
        formula.extend(ratio_errors(&nominal_k, &truth, &identified));
        // Relative scale keeps the prior's level.
        let level = |k: &[Option<f64>]| k.iter().flatten().map(|k| k.ln()).sum::<f64>();
        assert!((level(&result.stiffness) - level(&nominal_k)).abs() < 1e-9);
        // Branches off every probed path are reported as such, at the prior.
        for j in 1..nominal.len() {
            let on_path = probes
                .iter()
                .any(|p| nominal.path_to_root(p.push.node).contains(&j));
            assert_eq!(
                result.status[j] == Some(Status::Unobserved),
                !on_path,
                "node {j}"
            );
        }
    }
    let (fit, prior) = (median(fitted), median(formula));
    assert!(
        fit < 0.5 * prior && fit < 0.1,
        "median |ln K̂/K| {fit} vs formula {prior}"
    );
}

#[test]
fn a_global_factor_is_invisible_without_force_and_recovered_with_it() {
    let noise = Noise {
        position: 0.001,
        force: 0.02,
    };
    let (nominal, truth) = scenario(13, 5, 0.3, 1.0);
    let (_, scaled) = scenario(13, 5, 0.3, 3.0);
    let a = identify(
        &nominal,
        &probes(&truth, &nominal, 4, &noise, false, 1),
        &IdentifyConfig::default(),
    );
    let b = identify(
        &nominal,
        &probes(&scaled, &nominal, 4, &noise, false, 1),
        &IdentifyConfig::default(),
    );
    for j in 1..nominal.len() {
        let (ka, kb) = (a.stiffness[j].unwrap(), b.stiffness[j].unwrap());
        assert!((ka / kb - 1.0).abs() < 1e-6, "node {j}: {ka} vs {kb}");
    }
    let config = IdentifyConfig {
        noise,
        ..IdentifyConfig::default()
    };
    let c = identify(
        &nominal,
        &probes(&scaled, &nominal, 4, &noise, true, 1),
        &config,
    );
    assert_eq!(c.scale, Scale::Absolute);
    let identified: Vec<usize> = (1..nominal.len())
        .filter(|&j| c.status[j] == Some(Status::Identified))
        .collect();
    assert!(!identified.is_empty());
    let mean_log_error = identified
        .iter()
        .map(|&j| (c.stiffness[j].unwrap() / scaled.branch(j).unwrap().stiffness).ln())
        .sum::<f64>()
        / identified.len() as f64;
    assert!(mean_log_error.abs() < 0.08, "level off by {mean_log_error}");
    // The interval holds the estimate.
    for j in 1..nominal.len() {
        let (lo, hi) = c.interval[j].unwrap();
        assert!(lo < c.stiffness[j].unwrap() && c.stiffness[j].unwrap() < hi);
    }
}

#[test]
fn chosen_probes_spread_over_the_tree() {
    let (nominal, _) = scenario(21, 9, 0.3, 1.0);
    let posterior = Posterior::prior(&nominal, &IdentifyConfig::default());
    let request = ProbeRequest {
        count: 4,
        ..ProbeRequest::default()
    };
    let chosen = choose_probes(
        &nominal,
        &posterior,
        &request,
        &IdentifyConfig::default(),
        &|_| true,
    );
    assert_eq!(chosen.len(), 4);
    // Each sharpens the paper's pushes' predictions, and tells about ln K.
    for c in &chosen {
        assert!(c.prediction_variance_reduction > 0.0, "{c:?}");
        assert!(c.information_gain > 0.0, "{c:?}");
    }

    let nodes: std::collections::BTreeSet<usize> = chosen.iter().map(|c| c.push.node).collect();
    assert!(nodes.len() >= 3, "probes repeat a leaf: {nodes:?}");
    // A filter that allows nothing yields nothing.
    assert!(
        choose_probes(
            &nominal,
            &posterior,
            &request,
            &IdentifyConfig::default(),
            &|_| false
        )
        .is_empty()
    );
}

#[test]
fn probes_that_cannot_come_from_the_tree_are_named() {
    let (nominal, truth) = scenario(11, 3, 0.3, 1.0);
    let noise = Noise::default();
    let good = probes(&truth, &nominal, 2, &noise, true, 2);
    let check = |edit: &dyn Fn(&mut Probe)| {
        let mut p = good.clone();
        edit(&mut p[1]);
        validate_probes(&nominal, &p, &noise).unwrap_err()
    };
    let e = check(&|p| p.push.node = 0);
    assert_eq!((e.probe, e.field), (1, "contact_node"));
    let e = check(&|p| p.push.vector.x = f64::NAN);
    assert_eq!((e.probe, e.field), (1, "push"));
    let e = check(&|p| p.observed.pop().map(|_| ()).unwrap());
    assert_eq!(e.field, "observed_positions");
    let e = check(&|p| p.observed[4] = Some(Point3::new(f64::INFINITY, 0.0, 0.0)));
    assert_eq!(e.field, "observed_positions");
    let e = check(&|p| p.contact_force = Some(Vector3::zeros()));
    assert_eq!(e.field, "contact_force");
    let far = |p: &mut Probe| {
        let j = nominal.len() - 1;
        p.observed[j] = p.observed[j].map(|o| o + Vector3::new(0.3, 0.0, 0.0));
    };
    let e = check(&far);
    assert!(e.message.contains("cannot come from this tree"), "{e}");
    // Missing nodes are fine.
    let mut sparse = good.clone();
    sparse[0].observed[2] = None;
    validate_probes(&nominal, &sparse, &noise).unwrap();
}

#[test]
fn a_probe_whose_slot_slides_to_a_fork_is_rejected_not_fitted() {
    let (nominal, truth) = scenario(15, 11, 0.3, 1.0);
    let noise = Noise::default();
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    // Pushes along an inner branch's own axis slide the slot to its fork.
    let slid = (1..nominal.len())
        .filter(|&j| !nominal.is_leaf(j))
        .flat_map(|j| [0.1, -0.1].map(|s| (j, nominal.branch_direction(j).unwrap() * s)))
        .map(|(node, vector)| Push { node, vector })
        .find(|push| {
            let probe = Probe {
                push: *push,
                contact: ContactModel::Slot,
                observed: vec![],
                contact_force: None,
            };
            treemanip_core::identify::simulate_probe(&nominal, &probe)
                .is_ok_and(|o| o.report.hold == treemanip_core::sim::Hold::AtNode)
        })
        .expect("some push along a branch slides to its fork");
    let slid = observe(&truth, slid, ContactModel::Slot, &noise, false, &mut rng).unwrap();
    let mut all = probes(&truth, &nominal, 3, &noise, false, 3);
    all.push(slid);
    let result = identify(&nominal, &all, &IdentifyConfig::default());
    assert_eq!(result.rejected.len(), 1, "{:?}", result.rejected);
    assert_eq!(result.rejected[0].probe, 3);
    assert_eq!(result.rejected[0].reason, "hold_switched");
    assert!(result.fit.converged);
}
