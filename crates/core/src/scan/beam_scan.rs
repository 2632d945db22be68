//! A laser's beam-model scan of a branch, for the tests of the scan steps
//! that undo the beam (`silhouette`, the extraction's `sensor: laser`).
//!
//! A pulse's footprint is a disc; a pulse that grazes a branch returns an
//! echo at the mean range of what its sub-beams hit, placed on the pulse's
//! central axis. So the branch is seen wider than it is by up to the
//! footprint's radius on either side, with flat wings: the widening the
//! extraction is told to take off.

use nalgebra::Point3;
use rand::{RngExt, SeedableRng};

/// How a stem is scanned.
pub struct BeamScan {
    /// The footprint's radius (m).
    pub beam: f64,
    /// Pulses this far apart across the view (m).
    pub step: f64,
    /// Rows of pulses, 2 mm apart up the stem.
    pub rows: usize,
    /// Depth noise (m, standard deviation, uniform), seeded.
    pub noise: f64,
}

/// One side of a vertical stem of radius `r` on the z axis, scanned from
/// +y: each pulse's return at the mean depth of the footprint's sub-beams
/// (a disc of 11 × 11 grid points) that hit it.
pub fn scanned_stem(r: f64, scan: &BeamScan) -> Vec<Point3<f64>> {
    let w = scan.beam;
    let sub: Vec<f64> = (-5..=5)
        .flat_map(|i| (-5..=5).map(move |j| (i as f64 / 5.0, j as f64 / 5.0)))
        .filter(|(u, v)| u * u + v * v <= 1.0)
        .map(|(u, _)| u * w)
        .collect();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let mut out = Vec::new();
    for row in 0..scan.rows {
        let z = 0.002 * row as f64;
        let mut x = -(r + w);
        while x <= r + w {
            let depths: Vec<f64> = sub
                .iter()
                .filter(|u| (x + *u).abs() < r)
                .map(|u| (r * r - (x + u) * (x + u)).sqrt())
                .collect();
            if !depths.is_empty() {
                let y = depths.iter().sum::<f64>() / depths.len() as f64;
                // Uniform on ±√3 σ: standard deviation σ.
                let noise = scan.noise * (rng.random::<f64>() - 0.5) * 2.0 * 3f64.sqrt();
                out.push(Point3::new(x, y + noise, z));
            }
            x += scan.step;
        }
    }
    out
}
