//! Stiffness that varies independently of a tree's geometry.
//!
//! The radius formula K_s = Eπr⁴/(2ℓ) ([`super::Wood`]) makes a branch's
//! stiffness a fixed function of its shape, so a model trained on such trees
//! never needs to read K_s. Real branches differ: the wood's modulus varies
//! between trees, branches and seasons, and K_s ∝ r⁴ turns a 10 % error in a
//! measured radius into a 46 % error in K_s. Both are multiplicative, so
//! the variation is log-normal per branch, times one factor for the whole
//! tree:
//!
//! K_s,b = K_formula,b · exp(ε_b) · g,  ε_b ~ N(0, σ²) independent per
//! branch, log g ~ U(−log G, log G).
//!
//! σ = 0.5 (a factor e^±0.5 ≈ 0.6–1.6 for one standard deviation) covers the
//! perturbations the identification is evaluated on (σ = 0.3 and 0.5). The
//! global factor changes no displacement of a displacement-controlled push
//! (the steady state depends only on stiffness ratios), only forces and
//! moments; it is there so that nothing learned can lean on the absolute
//! level. Damping follows stiffness (K_d = ratio · K_s).

use rand::{Rng, RngExt};
use serde::{Deserialize, Serialize};

use super::{Branch, Tree};
use crate::seed::standard_normal;

/// How a tree's stiffness is varied away from the radius formula.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StiffnessVariation {
    /// σ of the per-branch log factor ε_b (0: no per-branch variation).
    pub branch_log_sigma: f64,
    /// G: the whole tree's factor g is log-uniform in [1/G, G] (1: none).
    pub global_factor: f64,
}

impl Default for StiffnessVariation {
    /// No variation: the radius formula as it is.
    fn default() -> Self {
        Self::NONE
    }
}

/// A variation that cannot be applied.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StiffnessVariationError {
    #[error("branch_log_sigma must be finite and in [0, 2], it is {0}")]
    Sigma(f64),
    #[error("global_factor must be finite and in [1, 100], it is {0}")]
    Global(f64),
}

impl StiffnessVariation {
    pub const NONE: StiffnessVariation = StiffnessVariation {
        branch_log_sigma: 0.0,
        global_factor: 1.0,
    };

    /// The training data's variation for stiffness-aware models: σ = 0.5
    /// per branch, a global factor up to 4 either way.
    pub const TRAINING: StiffnessVariation = StiffnessVariation {
        branch_log_sigma: 0.5,
        global_factor: 4.0,
    };

    pub fn is_none(&self) -> bool {
        self.branch_log_sigma == 0.0 && self.global_factor == 1.0
    }

    pub fn validate(&self) -> Result<(), StiffnessVariationError> {
        if !(0.0..=2.0).contains(&self.branch_log_sigma) {
            return Err(StiffnessVariationError::Sigma(self.branch_log_sigma));
        }
        if !(1.0..=100.0).contains(&self.global_factor) {
            return Err(StiffnessVariationError::Global(self.global_factor));
        }
        Ok(())
    }

    /// The per-branch factors exp(ε_b)·g (index by node; 1 at the root),
    /// drawn from `rng`.
    pub fn factors<R: Rng + ?Sized>(&self, n: usize, rng: &mut R) -> Vec<f64> {
        let log_g = if self.global_factor > 1.0 {
            let log_max = self.global_factor.ln();
            (2.0 * rng.random::<f64>() - 1.0) * log_max
        } else {
            0.0
        };
        (0..n)
            .map(|j| {
                if j == 0 {
                    return 1.0;
                }
                let eps = if self.branch_log_sigma > 0.0 {
                    self.branch_log_sigma * standard_normal(rng)
                } else {
                    0.0
                };
                (eps + log_g).exp()
            })
            .collect()
    }

    /// `tree` with its branches' stiffness (and damping) multiplied by
    /// factors drawn from `rng`; the geometry is unchanged.
    pub fn apply<R: Rng + ?Sized>(&self, tree: &Tree, rng: &mut R) -> Tree {
        if self.is_none() {
            return tree.clone();
        }
        let factors = self.factors(tree.len(), rng);
        let branches: Vec<Option<Branch>> = tree
            .branches()
            .iter()
            .zip(&factors)
            .map(|(b, f)| {
                b.map(|b| Branch {
                    stiffness: b.stiffness * f,
                    damping: b.damping * f,
                    ..b
                })
            })
            .collect();
        Tree::new(tree.positions().to_vec(), tree.parents().to_vec(), branches)
            .expect("scaling positive stiffness keeps a valid tree valid")
    }
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    use super::*;
    use crate::tree::{ScaParams, generate};

    #[test]
    fn factors_follow_the_stated_distribution() {
        let variation = StiffnessVariation {
            branch_log_sigma: 0.5,
            global_factor: 1.0,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let logs: Vec<f64> = (0..200)
            .flat_map(|_| variation.factors(51, &mut rng).into_iter().skip(1))
            .map(f64::ln)
            .collect();
        let mean = logs.iter().sum::<f64>() / logs.len() as f64;
        let var = logs.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / logs.len() as f64;
        assert!(mean.abs() < 0.02, "mean log factor {mean}");
        assert!((var.sqrt() - 0.5).abs() < 0.02, "σ {}", var.sqrt());

        // The global factor alone: one log-uniform factor for every branch.
        let global = StiffnessVariation {
            branch_log_sigma: 0.0,
            global_factor: 4.0,
        };
        let mut seen = (f64::INFINITY, f64::NEG_INFINITY);
        for _ in 0..2000 {
            let f = global.factors(5, &mut rng);
            assert!(f[1..].iter().all(|x| (x - f[1]).abs() < 1e-12));
            seen = (seen.0.min(f[1]), seen.1.max(f[1]));
        }
        assert!(
            seen.0 >= 0.25 && seen.0 < 0.27 && seen.1 <= 4.0 && seen.1 > 3.7,
            "{seen:?}"
        );
    }

    #[test]
    fn apply_scales_stiffness_and_damping_and_keeps_the_geometry() {
        let tree = generate(15, 2, &ScaParams::default()).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let varied = StiffnessVariation::TRAINING.apply(&tree, &mut rng);
        assert_eq!(varied.positions(), tree.positions());
        assert_eq!(varied.parents(), tree.parents());
        let mut changed = 0;
        for ((_, a), (_, b)) in tree.branches_iter().zip(varied.branches_iter()) {
            assert_eq!((a.radius, a.length), (b.radius, b.length));
            assert!((b.damping / b.stiffness - a.damping / a.stiffness).abs() < 1e-12);
            changed += usize::from((b.stiffness / a.stiffness - 1.0).abs() > 1e-9);
        }
        assert!(changed >= 13, "{changed} of 14 branches changed");
        assert_eq!(StiffnessVariation::NONE.apply(&tree, &mut rng), tree);
    }

    #[test]
    fn out_of_range_variations_are_refused() {
        for (sigma, global) in [
            (-0.1, 1.0),
            (f64::NAN, 1.0),
            (0.5, 0.5),
            (0.5, f64::INFINITY),
        ] {
            let v = StiffnessVariation {
                branch_log_sigma: sigma,
                global_factor: global,
            };
            assert!(v.validate().is_err(), "{v:?}");
        }
        assert!(StiffnessVariation::TRAINING.validate().is_ok());
    }
}
