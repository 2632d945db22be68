//! Leaves: thin flat sheets wider than a branch. Around a point on a leaf,
//! the neighbours within [`SHEET_RADIUS`] spread in two directions and lie
//! in a plane; around a point on bark they spread along the branch (a
//! twig) or curve round it (a bough or the trunk, whose cross-section at
//! that scale is an arc, not a line). Points in sheets are dropped before
//! the skeleton is looked for.

use nalgebra::{Matrix3, Point3, Vector3};
use rayon::prelude::*;

use crate::scan::neighbours::PointIndex;

/// Neighbourhood radius (m): wider than a twig, narrower than a leaf.
pub const SHEET_RADIUS: f64 = 0.02;
/// Spread in two directions: λ₂ at least this share of λ₁ ...
const SPREAD_RATIO: f64 = 0.25;
/// ... and flat: λ₃ at most this share of λ₂.
const FLAT_RATIO: f64 = 0.1;

/// Whether each point lies in a sheet (a leaf).
pub fn sheets(points: &[Point3<f64>], index: &PointIndex) -> Vec<bool> {
    points
        .par_iter()
        .map(|p| {
            let near = index.near(p, 64, SHEET_RADIUS);
            if near.len() < 10 {
                return false;
            }
            let n = near.len() as f64;
            let mean = near
                .iter()
                .map(|(j, _)| points[*j].coords)
                .sum::<Vector3<f64>>()
                / n;
            let mut cov = Matrix3::zeros();
            for (j, _) in &near {
                let d = points[*j].coords - mean;
                cov += d * d.transpose();
            }
            let mut eig: Vec<f64> = cov.symmetric_eigenvalues().iter().copied().collect();
            eig.sort_by(|a, b| b.total_cmp(a));
            eig[1] >= SPREAD_RATIO * eig[0] && eig[2] <= FLAT_RATIO * eig[1]
        })
        .collect()
}
