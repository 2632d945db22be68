//! How close an extracted skeleton is to the true one, by the measures the
//! tree-reconstruction literature reports:
//!
//! - **recall** and **precision at t** (Smart-Tree, Dobbs et al. 2023):
//!   both centrelines are sampled every [`SAMPLE_STEP`]; a true sample is
//!   recalled when the extracted skeleton passes within t × its true
//!   radius, an extracted sample is precise when it lies within t × the
//!   radius of some true branch;
//! - **radius error** (mm): at each recalled true sample, the extracted
//!   radius of the nearest extracted branch against the true one, by the
//!   true radius;
//! - **branch points matched**: the share of true forks with an extracted
//!   fork within [`FORK_TOLERANCE`];
//! - **topology**: the share of true branches (runs between forks) whose
//!   extracted counterpart (the extracted branch nearest most of its
//!   samples) grows from the counterpart of the true parent branch.

use nalgebra::Point3;
use rayon::prelude::*;

use crate::scan::skeleton::{Skeleton, point_segment};

/// Distance between centreline samples (m).
pub const SAMPLE_STEP: f64 = 0.005;
/// An extracted fork this close (m) to a true one matches it.
pub const FORK_TOLERANCE: f64 = 0.05;

/// Radius classes (m, lower bounds) the radius error is reported by.
pub const RADIUS_CLASSES: [f64; 3] = [0.0, 0.005, 0.01];

#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ScanScore {
    /// Recall at t = 0.5 and t = 1.0.
    pub recall: [f64; 2],
    /// Precision at t = 0.5 and t = 1.0.
    pub precision: [f64; 2],
    /// Median absolute radius error (mm) over recalled true samples whose
    /// true radius is at least each of [`RADIUS_CLASSES`]; NaN where none.
    pub radius_error_mm: [f64; 3],
    pub branch_points_matched: f64,
    pub topology: f64,
}

struct Sample {
    at: Point3<f64>,
    radius: f64,
    /// The segment (its end node) it lies on.
    node: usize,
}

fn samples(s: &Skeleton) -> Vec<Sample> {
    let mut out = Vec::new();
    for (j, p) in s.parents.iter().enumerate() {
        let Some(p) = *p else { continue };
        let (a, b) = (s.positions[p], s.positions[j]);
        let steps = ((b - a).norm() / SAMPLE_STEP).ceil().max(1.0) as usize;
        for k in 0..steps {
            out.push(Sample {
                at: a + (b - a) * ((k as f64 + 0.5) / steps as f64),
                radius: s.radius[j],
                node: j,
            });
        }
    }
    out
}

/// For each point, the nearest segment's end node and the distance (and,
/// with `scaled`, the smallest distance − t·radius over segments).
fn nearest(points: &[Sample], s: &Skeleton) -> Vec<(usize, f64)> {
    let segs: Vec<(usize, Point3<f64>, Point3<f64>)> = s
        .parents
        .iter()
        .enumerate()
        .filter_map(|(j, p)| p.map(|p| (j, s.positions[p], s.positions[j])))
        .collect();
    points
        .par_iter()
        .map(|q| {
            segs.iter()
                .map(|(j, a, b)| (*j, point_segment(&q.at, a, b).0))
                .min_by(|x, y| x.1.total_cmp(&y.1))
                .unwrap_or((0, f64::INFINITY))
        })
        .collect()
}

/// Scores `found` against `truth`.
pub fn score(truth: &Skeleton, found: &Skeleton) -> ScanScore {
    let true_samples = samples(truth);
    let found_samples = samples(found);
    let to_found = nearest(&true_samples, found);
    let ts = [0.5, 1.0];
    let recall = ts.map(|t| {
        share(
            true_samples
                .iter()
                .zip(&to_found)
                .filter(|(s, n)| n.1 <= t * s.radius)
                .count(),
            true_samples.len(),
        )
    });
    // Precision: within t × the radius of *some* true branch.
    let true_segs: Vec<(Point3<f64>, Point3<f64>, f64)> = truth.segments().collect();
    let precision = ts.map(|t| {
        let hits = found_samples
            .par_iter()
            .filter(|q| {
                true_segs
                    .iter()
                    .any(|(a, b, r)| point_segment(&q.at, a, b).0 <= t * r)
            })
            .count();
        share(hits, found_samples.len())
    });
    let radius_error_mm = RADIUS_CLASSES.map(|lo| {
        let mut errors: Vec<f64> = true_samples
            .iter()
            .zip(&to_found)
            .filter(|(s, n)| s.radius >= lo && n.1 <= s.radius)
            .map(|(s, n)| (found.radius[n.0] - s.radius).abs() * 1e3)
            .collect();
        errors.sort_by(f64::total_cmp);
        errors.get(errors.len() / 2).copied().unwrap_or(f64::NAN)
    });
    let found_forks = found.branch_points();
    let true_forks = truth.branch_points();
    let matched = true_forks
        .iter()
        .filter(|&&f| {
            found_forks
                .iter()
                .any(|&g| (found.positions[g] - truth.positions[f]).norm() <= FORK_TOLERANCE)
        })
        .count();
    ScanScore {
        recall,
        precision,
        radius_error_mm,
        branch_points_matched: share(matched, true_forks.len()),
        topology: topology(truth, found, &true_samples, &to_found, &found_samples),
    }
}

fn topology(
    truth: &Skeleton,
    found: &Skeleton,
    true_samples: &[Sample],
    to_found: &[(usize, f64)],
    found_samples: &[Sample],
) -> f64 {
    let (true_chains, true_chain_of) = truth.chains();
    let (found_chains, found_chain_of) = found.chains();
    if found_chains.is_empty() {
        return 0.0;
    }
    // Each found chain's true chain: the majority of its samples' nearest.
    let to_true = nearest(found_samples, truth);
    let mut votes = vec![vec![0usize; true_chains.len()]; found_chains.len()];
    for (s, n) in found_samples.iter().zip(&to_true) {
        if let (Some(f), Some(t)) = (found_chain_of[s.node], true_chain_of[n.0]) {
            votes[f][t] += 1;
        }
    }
    let found_to_true: Vec<Option<usize>> = votes
        .iter()
        .map(|v| {
            v.iter()
                .enumerate()
                .max_by_key(|(_, c)| **c)
                .filter(|(_, c)| **c > 0)
                .map(|(t, _)| t)
        })
        .collect();
    // Each true chain's counterpart: the found chain nearest most of its
    // recalled samples.
    let mut counter_votes = vec![vec![0usize; found_chains.len()]; true_chains.len()];
    for (s, n) in true_samples.iter().zip(to_found) {
        if n.1 <= s.radius.max(0.01)
            && let (Some(t), Some(f)) = (true_chain_of[s.node], found_chain_of[n.0])
        {
            counter_votes[t][f] += 1;
        }
    }
    let mut right = 0;
    let mut total = 0;
    for (t, chain) in true_chains.iter().enumerate() {
        let Some(true_parent) = chain.parent else {
            continue;
        };
        total += 1;
        let counterpart = counter_votes[t]
            .iter()
            .enumerate()
            .max_by_key(|(_, c)| **c)
            .filter(|(_, c)| **c > 0)
            .map(|(f, _)| f);
        let Some(f) = counterpart else { continue };
        if found_chains[f]
            .parent
            .and_then(|p| found_to_true[p])
            .is_some_and(|p| p == true_parent)
        {
            right += 1;
        }
    }
    share(right, total)
}

fn share(hits: usize, of: usize) -> f64 {
    if of == 0 {
        1.0
    } else {
        hits as f64 / of as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tree::{ScaParams, generate};

    #[test]
    fn a_tree_scores_perfectly_against_itself_and_a_shifted_copy_does_not() {
        let tree = generate(20, 11, &ScaParams::default()).unwrap();
        let truth = Skeleton::of_tree(&tree);
        let s = score(&truth, &truth);
        assert_eq!(s.recall, [1.0, 1.0]);
        assert_eq!(s.precision, [1.0, 1.0]);
        assert_eq!(s.radius_error_mm[0], 0.0);
        assert_eq!(s.branch_points_matched, 1.0);
        assert_eq!(s.topology, 1.0);
        let mut shifted = truth.clone();
        for p in &mut shifted.positions {
            p.x += 0.007;
        }
        let s = score(&truth, &shifted);
        // Every branch is 5 mm or thicker: t = 0.5 misses the thin ones.
        assert!(s.recall[0] < 0.8, "{s:?}");
        assert!(s.recall[1] < 1.0);
    }
}
