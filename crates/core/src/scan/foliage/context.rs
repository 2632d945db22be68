//! A second look at each cube, knowing how the stage before called its
//! neighbours (auto-context: Tu & Bai, 2010).
//!
//! Shape alone cannot tell a twig from the leaves around it: a twig of
//! 5 mm radius carries eight 5 cm leaves within 1-4 cm, so at 4-8 cm its
//! surroundings are mostly leaf, and the first stage called 36 % of the
//! terminal twigs' bark points foliage on the test split's one-view leafy
//! scans (0.6 % of the other bark). What the first stage left as bark
//! still shows the twig: a line of cubes running through this one. These
//! features describe the neighbourhood as the previous stage called it:
//! the chances around the cube at four scales, the shape of the cubes
//! called bark (is there a line through this cube, and how far is the
//! cube from it?) at 2, 4 and 8 cm, and the shape of the cubes called
//! leaf at 2 cm (is this cube on a flat disc of them?).

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use super::shape::{FineNeighbours, Grids};
use crate::geometry::principal::principal;
use crate::scan::neighbours::PointIndex;

/// Features of one cube's context.
pub const CONTEXT_FEATURES: usize = 27;
/// A cube called bark by the previous stage when its chance is below this.
const BARK_BELOW: f64 = 0.5;
/// At most this many cubes per query (bounds the work in dense clouds).
const NEIGHBOURS: usize = 64;
/// ... and at the 4 cm scale over the fine cubes (a 4 mm twig seen from
/// one side fills about 50 of them).
const WIDE_NEIGHBOURS: usize = 128;

/// One cube's context.
pub type ContextFeatures = [f32; CONTEXT_FEATURES];

/// The mean of `chances` over the cubes `near`, each weighted by its
/// points (0 over none).
pub(super) fn mean_chance(near: &[(usize, f64)], chances: &[f64], counts: &[usize]) -> f64 {
    let (mut sum, mut weight) = (0.0, 0.0);
    for &(j, _) in near {
        sum += chances[j] * counts[j] as f64;
        weight += counts[j] as f64;
    }
    sum / weight.max(1.0)
}

/// What a coarse cube's surroundings say, shared by its fine cubes.
struct CoarseContext {
    /// Mean chance within 4 and 8 cm.
    chance: [f32; 2],
    /// The cubes called bark within 4 cm (fine) and 8 cm (coarse).
    lines: [Line; 2],
}

/// The line through some cubes: their number (log) and spreads, and
/// their mean and main axis where there are enough to draw one.
struct Line {
    own: [f32; 4],
    through: Option<(Point3<f64>, Vector3<f64>)>,
}

/// The line through the cubes `q`: the number (log) and spreads of `q`
/// (the second and third over the first, the first over `r`), its mean
/// and main axis. Fewer than three cubes read as no line at all.
fn line(q: &[Point3<f64>], r: f64) -> Line {
    let count = (q.len() as f32).ln_1p();
    if q.len() < 3 {
        return Line {
            own: [count, 1.0, 1.0, 0.0],
            through: None,
        };
    }
    let p = principal(q);
    let first = p.spread[0].max(1e-9);
    Line {
        own: [
            count,
            (p.spread[1] / first) as f32,
            (p.spread[2] / first) as f32,
            (first / r) as f32,
        ],
        through: Some((p.mean, p.axes[0])),
    }
}

/// A line's features seen from `c`: its own four, then how far `c` is
/// from its axis and from its mean, over `r` (2 for no line).
fn line_from(line: &Line, c: &Point3<f64>, r: f64, out: &mut [f32]) {
    out[..4].copy_from_slice(&line.own);
    let Some((mean, axis)) = line.through else {
        out[4..6].copy_from_slice(&[2.0, 2.0]);
        return;
    };
    let d = c - mean;
    out[4] = ((d - axis * d.dot(&axis)).norm() / r) as f32;
    out[5] = (d.norm() / r) as f32;
}

/// The context of every fine cube of `grids`, given the previous stage's
/// chance of each (unsmoothed). Each fine cube reads the neighbours the
/// shape features were read from (its nearest cubes within 2 cm, parted
/// into those called bark and leaf); each coarse cube makes two queries,
/// shared by the fine cubes in it.
pub fn context_features(
    grids: &Grids,
    neighbours: &FineNeighbours,
    chances: &[f64],
) -> Vec<ContextFeatures> {
    let fine = &grids.fine;
    let coarse = &grids.coarse;
    // Each coarse cube's chance: its fine cubes', weighted by their points
    // (a coarse cube's count is its fine cubes' points).
    let mut coarse_chance = vec![0.0; coarse.centres.len()];
    for (v, &k) in coarse.of_point.iter().enumerate() {
        coarse_chance[k] += chances[v] * fine.counts[v] as f64;
    }
    for (p, &w) in coarse_chance.iter_mut().zip(&coarse.counts) {
        *p /= w.max(1) as f64;
    }
    let bark: Vec<Point3<f64>> = (0..fine.centres.len())
        .filter(|&v| chances[v] < BARK_BELOW)
        .map(|v| fine.centres[v])
        .collect();
    let bark_index = PointIndex::new(&bark);
    let coarse_context: Vec<CoarseContext> = coarse
        .centres
        .par_iter()
        .map(|c| {
            let wide = grids.coarse_index.near(c, NEIGHBOURS, 0.08);
            let within = wide.partition_point(|&(_, d)| d <= 0.04);
            let coarse_bark: Vec<Point3<f64>> = wide
                .iter()
                .filter(|&&(k, _)| coarse_chance[k] < BARK_BELOW)
                .map(|&(k, _)| coarse.centres[k])
                .collect();
            let fine_bark: Vec<Point3<f64>> = bark_index
                .near(c, WIDE_NEIGHBOURS, 0.04)
                .iter()
                .map(|&(j, _)| bark[j])
                .collect();
            CoarseContext {
                chance: [
                    mean_chance(&wide[..within], &coarse_chance, &coarse.counts) as f32,
                    mean_chance(&wide, &coarse_chance, &coarse.counts) as f32,
                ],
                lines: [line(&fine_bark, 0.04), line(&coarse_bark, 0.08)],
            }
        })
        .collect();
    fine.centres
        .par_iter()
        .enumerate()
        .map(|(v, c)| {
            let mut f = [0.0f32; CONTEXT_FEATURES];
            f[0] = chances[v] as f32;
            let near = neighbours.of(grids, v);
            let within = near.partition_point(|&(_, d)| d <= 0.01);
            f[1] = mean_chance(&near[..within], chances, &fine.counts) as f32;
            f[2] = mean_chance(&near, chances, &fine.counts) as f32;
            let around = &coarse_context[coarse.of_point[v]];
            f[3..5].copy_from_slice(&around.chance);
            let (mut bark, mut leaf) = (Vec::new(), Vec::new());
            for &(j, _) in &near {
                let called = if chances[j] < BARK_BELOW {
                    &mut bark
                } else {
                    &mut leaf
                };
                called.push(fine.centres[j]);
            }
            line_from(&line(&bark, 0.02), c, 0.02, &mut f[5..11]);
            line_from(&around.lines[0], c, 0.04, &mut f[11..17]);
            line_from(&around.lines[1], c, 0.08, &mut f[17..23]);
            // On a flat disc of leaf cubes: their number, flatness, and
            // how far off their plane and their mean this cube is.
            f[23] = (leaf.len() as f32).ln_1p();
            if leaf.len() >= 3 {
                let p = principal(&leaf);
                let d = c - p.mean;
                f[24] = (p.spread[2] / p.spread[0].max(1e-9)) as f32;
                f[25] = (d.dot(&p.axes[2]).abs() / 0.02) as f32;
                f[26] = (d.norm() / 0.02) as f32;
            } else {
                f[24..27].copy_from_slice(&[1.0, 1.0, 2.0]);
            }
            f
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scan::foliage::shape::features_and_neighbours;
    use nalgebra::Vector3;

    /// Every cube called one thing (no bark, or no leaf) leaves the other
    /// set empty: the context is still defined (no line, no plane).
    #[test]
    fn a_cloud_called_all_leaf_or_all_bark_has_a_context() {
        let points: Vec<Point3<f64>> = (0..2000)
            .map(|i| {
                let a = i as f64 * 0.618_034 * std::f64::consts::TAU;
                let r = 0.025 * ((i as f64 + 0.5) / 2000.0).sqrt();
                Point3::new(r * a.cos(), r * a.sin(), 0.0005 * (i % 3) as f64)
            })
            .collect();
        let grids = Grids::new(&points);
        let (_, near) = features_and_neighbours(&grids, &Vector3::z());
        for called in [0.0, 1.0] {
            let chances = vec![called; grids.fine.centres.len()];
            let context = context_features(&grids, &near, &chances);
            assert_eq!(context.len(), grids.fine.centres.len());
            assert!(context.iter().flatten().all(|x| x.is_finite()));
            let lines = &context[0][5..23];
            if called == 1.0 {
                // No bark: no line at any scale.
                assert_eq!(lines[0], 0.0, "{lines:?}");
                assert_eq!(lines[4], 2.0, "{lines:?}");
            } else {
                // No leaf: no plane.
                assert_eq!(context[0][23], 0.0);
            }
        }
    }
}
