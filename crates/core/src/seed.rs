//! Reproducible randomness: independent seeds derived from a base seed and
//! a path of numbers (split, size, index, …), so any single tree or episode
//! can be regenerated without the rest, and the draws built on them that
//! every layer shares.

use rand::{Rng, RngExt};

/// SplitMix64 folded over `parts`.
pub fn derive_seed(base: u64, parts: &[u64]) -> u64 {
    parts
        .iter()
        .fold(base, |x, &part| splitmix64(x ^ splitmix64(part)))
}

fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// One N(0, 1) draw (Box–Muller). Three of them make an isotropic
/// direction (pushes, search samples); one scales a log-normal stiffness.
pub fn standard_normal<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    let u1: f64 = 1.0 - rng.random::<f64>(); // (0, 1]
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}
