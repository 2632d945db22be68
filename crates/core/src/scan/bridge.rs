//! Which parts of a cloud join the tree: gaps in its points bridged.
//!
//! A branch seen through leaves, or behind another branch, comes apart
//! into stretches. Each connected part of the cubes is joined to its
//! nearest neighbour part (Kruskal over the parts' closest pairs, in
//! [`crate::scan::extract()`]) when the evidence says it is wood cut off from
//! the tree, not a leaf, a fruit or noise:
//!
//! - a part shaped like a stretch of branch or larger than any leaf, at
//!   most the extraction's `max_gap` away; or
//! - a thin part ([`COVERED_MAX_WIDTH`]: not a fruit or a leaf) of
//!   [`MIN_PART_VOXELS`] cubes or more that looks like bark, at most
//!   [`COVERED_MAX_GAP`] away, where the gap is covered all the way
//!   ([`Cover`]): it runs under the leaves dropped from the cloud, or, where
//!   the sensor's place is known, behind what it saw ([`Shadows`]). A twig
//!   among its leaves, seen from one side, shows only the few centimetres
//!   of bark between them, too short to look like a branch and too far
//!   from the tree for a bare gap; a gap the sensor looked through is
//!   empty air.

use nalgebra::{Point3, Vector3};

use crate::geometry::principal::principal;
use crate::scan::neighbours::PointIndex;
use crate::scan::shadow::Shadows;

/// A part needs this many cubes to be bridged to the tree.
pub const MIN_PART_VOXELS: usize = 8;
/// A part is bridged when its length is this many times its width.
const ELONGATION: f64 = 2.5;
/// ... or when it spreads this much (m, standard deviation along its
/// longest axis: a straight 14 cm stretch, a 16 cm disc): more than a leaf
/// (2.5 cm radius, 1.25 cm), a cluster of a twig's leaves or a fruit.
/// Without it a fork seen apart from the tree was dropped as a fragment:
/// leafy one-view scans lost 8 points of recall at t = 1.0 that way
/// (0.697 with every leaf point removed; 0.778 bridged).
const SUBTREE_SPREAD: f64 = 0.04;

/// Largest gap (m) bridged where leaves cover it: a twig's length among
/// its leaves (the leaves of the synthetic scans sit 1-4 cm from twigs
/// 10-25 cm long).
pub const COVERED_MAX_GAP: f64 = 0.25;
/// A point of a gap is under leaves when a dropped leaf point lies within
/// this (m): a leaf's radius (2.5 cm) and the distance it stands off the
/// twig, less the gap a leaf leaves between it and its neighbours.
pub const LEAF_COVER: f64 = 0.04;
/// A part bridged under leaf cover must be thin: its spread across its
/// longest axis (standard deviation, m) at most this. A twig's bark has
/// about its radius over √2 (3.5 mm at 5 mm), a 3.5 cm fruit's cap or a
/// leaf's disc 1.2 cm and more.
pub const COVERED_MAX_WIDTH: f64 = 0.008;

/// Points of a gap tested for cover, this far apart (m).
const COVER_STEP: f64 = 0.01;

/// A part bridged under leaf cover must look like bark to the shape
/// classifier: its cubes' mean chance of being leaf at most this (the
/// classifier calls leaf above 0.55; what it left of a leaf scores near
/// that, a twig's bark well below).
pub const COVERED_MAX_LEAF_CHANCE: f64 = 0.3;

/// What tells a gap that something hid from one through empty air: the
/// points dropped as leaves, and where the sensor's place is known, the
/// shadows of everything it saw ([`Shadows`]).
pub struct Cover {
    leaves: Option<PointIndex>,
    shadows: Option<Shadows>,
    /// Each cube's chance of being leaf, where leaves went by shape (by
    /// colour, what is left is bark).
    leaf_chance: Option<Vec<f64>>,
}

impl Cover {
    /// `None` where no leaves were dropped and no shadows are known.
    /// `leaf_chance`: each cube's chance of being leaf (by shape), if that
    /// is how they were told.
    pub fn new(
        leaves: &[Point3<f64>],
        shadows: Option<Shadows>,
        leaf_chance: Option<Vec<f64>>,
    ) -> Option<Self> {
        let leaves = (!leaves.is_empty()).then(|| PointIndex::new(leaves));
        (leaves.is_some() || shadows.is_some()).then_some(Self {
            leaves,
            shadows,
            leaf_chance,
        })
    }

    /// Whether the cubes `part` look like bark (always, where leaves went
    /// by colour or none were dropped).
    fn looks_like_bark(&self, part: &[usize]) -> bool {
        self.leaf_chance.as_ref().is_none_or(|c| {
            part.iter().map(|&i| c[i]).sum::<f64>() / part.len().max(1) as f64
                <= COVERED_MAX_LEAF_CHANCE
        })
    }

    /// What covers the segment from `a` to `b`, if each of its points
    /// `COVER_STEP` (1 cm) apart, ends included, has a leaf point within
    /// [`LEAF_COVER`] or lies in the sensor's shadow.
    pub fn covers(&self, a: &Point3<f64>, b: &Point3<f64>) -> Option<Covered> {
        let d = b - a;
        let steps = (d.norm() / COVER_STEP).ceil().max(1.0) as usize;
        let mut by = Covered::Leaves;
        for s in 0..=steps {
            let p = a + d * (s as f64 / steps as f64);
            if self
                .leaves
                .as_ref()
                .is_some_and(|l| l.nearest(&p).1 <= LEAF_COVER)
            {
                continue;
            }
            if !self.shadows.as_ref().is_some_and(|h| h.hidden(&p)) {
                return None;
            }
            by = Covered::Shadow;
        }
        Some(by)
    }
}

/// What covers a gap.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Covered {
    /// Leaves all the way.
    Leaves,
    /// Somewhere only what the sensor saw in front of it.
    Shadow,
}

/// A gap that may be bridged: the closest pair of points of two parts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bridge {
    /// Its length (m).
    pub gap: f64,
    /// The point of one part and of the other.
    pub from: usize,
    pub to: usize,
    /// Bridged because leaves or the sensor's shadows cover it (the bare
    /// rule would not have); `None` when bridged bare.
    pub covered: Option<Covered>,
}

/// The closest pair of points of every two parts (of at least
/// [`MIN_PART_VOXELS`] cubes) that may be bridged (see the module
/// documentation), shortest first. `main` is the tree's part; `cover`,
/// where leaves were dropped, the leaves.
pub fn bridges(
    points: &[Point3<f64>],
    labels: &[usize],
    part_voxels: &[usize],
    main: usize,
    max_gap: f64,
    cover: Option<&Cover>,
) -> Vec<Bridge> {
    let parts = part_voxels.len();
    let mut of_part: Vec<Vec<usize>> = vec![Vec::new(); parts];
    for (i, &l) in labels.iter().enumerate() {
        if part_voxels[l] >= MIN_PART_VOXELS {
            of_part[l].push(i);
        }
    }
    // A part is bridged across a bare gap only when it is shaped like a
    // stretch of branch (at least ELONGATION times longer than wide) or
    // larger than any leaf or fruit (a fork or a whole subtree seen apart
    // from the tree behind leaves is not elongated): a leaf or a fruit seen
    // apart from its twig is neither.
    let spread = |l: usize| {
        let pts: Vec<Point3<f64>> = of_part[l].iter().map(|&i| points[i]).collect();
        principal(&pts).spread
    };
    let sized: Vec<usize> = (0..parts).filter(|&l| !of_part[l].is_empty()).collect();
    let spreads: Vec<_> = sized.iter().map(|&l| spread(l)).collect();
    let big: Vec<bool> = sized
        .iter()
        .zip(&spreads)
        .map(|(&l, s)| l == main || s[0] >= ELONGATION * s[1] || s[0] >= SUBTREE_SPREAD)
        .collect();
    // What may be bridged under leaves that is not big: a thin part (a
    // stretch of twig), not a fruit or a leaf the classifier left.
    let thin: Vec<bool> = spreads.iter().map(|s| s[1] <= COVERED_MAX_WIDTH).collect();
    let reach = if cover.is_some() {
        max_gap.max(COVERED_MAX_GAP)
    } else {
        max_gap
    };
    if sized.len() < 2 || reach <= 0.0 {
        return Vec::new();
    }
    let boxes: Vec<(Vector3<f64>, Vector3<f64>)> = sized
        .iter()
        .map(|&l| {
            of_part[l].iter().fold(
                (
                    Vector3::repeat(f64::INFINITY),
                    Vector3::repeat(f64::NEG_INFINITY),
                ),
                |(lo, hi), &i| (lo.inf(&points[i].coords), hi.sup(&points[i].coords)),
            )
        })
        .collect();
    let trees: Vec<PointIndex> = sized
        .iter()
        .map(|&l| {
            let pts: Vec<_> = of_part[l].iter().map(|&i| points[i]).collect();
            PointIndex::new(&pts)
        })
        .collect();
    let mut out = Vec::new();
    for x in 0..sized.len() {
        for y in x + 1..sized.len() {
            let bare = big[x] && big[y];
            if !bare && cover.is_none() {
                continue;
            }
            let (a, b) = (&boxes[x], &boxes[y]);
            let apart = (0..3).any(|k| a.0[k] > b.1[k] + reach || b.0[k] > a.1[k] + reach);
            if apart {
                continue;
            }
            // Query the smaller part's points in the larger part's tree.
            let (s, t) = if of_part[sized[x]].len() <= of_part[sized[y]].len() {
                (x, y)
            } else {
                (y, x)
            };
            let best = of_part[sized[s]]
                .iter()
                .map(|&i| {
                    let (j, d) = trees[t].nearest(&points[i]);
                    (d, i, of_part[sized[t]][j])
                })
                .min_by(|p, q| p.0.total_cmp(&q.0));
            let Some((gap, from, to)) = best else {
                continue;
            };
            let bridge = |covered| Bridge {
                gap,
                from,
                to,
                covered,
            };
            if bare && gap <= max_gap {
                out.push(bridge(None));
            } else if gap <= COVERED_MAX_GAP
                && let Some(by) = cover.and_then(|c| {
                    ((big[x] || thin[x] && c.looks_like_bark(&of_part[sized[x]]))
                        && (big[y] || thin[y] && c.looks_like_bark(&of_part[sized[y]])))
                    .then(|| c.covers(&points[from], &points[to]))
                    .flatten()
                })
            {
                out.push(bridge(Some(by)));
            }
        }
    }
    out.sort_by(|p, q| p.gap.total_cmp(&q.gap));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A line of cubes 4 mm apart from `from`, `count` of them, along `dir`.
    fn line(from: Point3<f64>, dir: Vector3<f64>, count: usize) -> Vec<Point3<f64>> {
        (0..count)
            .map(|k| from + dir.normalize() * (0.004 * k as f64))
            .collect()
    }

    /// A short stub of bark 20 cm from the tree is bridged only where
    /// leaves cover the gap between them; a long stretch 4 cm away is
    /// bridged across bare air too; a fruit under leaves is not thin, and
    /// is never bridged.
    #[test]
    fn a_stub_hidden_by_leaves_is_bridged_and_one_in_the_open_is_not() {
        // The tree: a 40 cm stem up z. Part 1: a compact block of 8 cubes
        // (what a twig shows between its leaves) 20 cm to the side.
        let mut points = line(Point3::origin(), Vector3::z(), 100);
        let mut labels = vec![0; points.len()];
        for dx in 0..2 {
            for dy in 0..2 {
                for dz in 0..2 {
                    points.push(Point3::new(
                        0.2 + 0.004 * dx as f64,
                        0.004 * dy as f64,
                        0.2 + 0.004 * dz as f64,
                    ));
                    labels.push(1);
                }
            }
        }
        // Part 2: a 12 cm stretch (elongated) 4 cm off the stem.
        for p in line(
            Point3::new(-0.04, 0.0, 0.1),
            Vector3::new(-1.0, 0.0, 1.0),
            30,
        ) {
            points.push(p);
            labels.push(2);
        }
        // Part 3: a compact block 30 cm away.
        for k in 0..8 {
            points.push(Point3::new(
                0.0,
                0.3 + 0.004 * (k % 2) as f64,
                0.3 + 0.004 * (k / 2) as f64,
            ));
            labels.push(3);
        }
        // Part 4: a 3.5 cm fruit's near half (a cap of points 4 mm apart)
        // 20 cm from the stem on the other side, under leaves too.
        let mut fruit = 0;
        for i in -8i32..=8 {
            for j in -8i32..=8 {
                let (u, v) = (0.004 * i as f64, 0.004 * j as f64);
                if u * u + v * v < 0.035 * 0.035 {
                    let w = (0.035f64 * 0.035 - u * u - v * v).sqrt();
                    points.push(Point3::new(-0.235 + w, u, 0.2 + v));
                    labels.push(4);
                    fruit += 1;
                }
            }
        }
        let part_voxels = vec![100, 8, 30, 8, fruit];
        let joined =
            |b: &[Bridge], l: usize| b.iter().any(|b| labels[b.from] == l || labels[b.to] == l);

        let bare = bridges(&points, &labels, &part_voxels, 0, 0.06, None);
        assert!(joined(&bare, 2), "the branch-like stretch 4 cm away");
        assert!(!joined(&bare, 1), "a compact stub 20 cm away, no leaves");
        assert!(!joined(&bare, 3));

        // Leaves along the gap from the stem to the stub, and around part 3
        // but not between it and the stem.
        let mut leaves: Vec<Point3<f64>> = (0..=20)
            .map(|k| Point3::new(0.01 * k as f64, 0.02, 0.2))
            .collect();
        leaves.push(Point3::new(0.0, 0.32, 0.32));
        leaves.extend((0..=20).map(|k| Point3::new(-0.01 * k as f64, 0.02, 0.2)));
        let cover = Cover::new(&leaves, None, None).unwrap();
        assert_eq!(
            cover.covers(&Point3::new(0.0, 0.0, 0.2), &Point3::new(0.2, 0.0, 0.2)),
            Some(Covered::Leaves)
        );
        assert!(
            cover
                .covers(&Point3::new(0.0, 0.0, 0.2), &Point3::new(0.0, 0.3, 0.3))
                .is_none()
        );
        let covered = bridges(&points, &labels, &part_voxels, 0, 0.06, Some(&cover));
        assert!(joined(&covered, 1), "the stub under leaves");
        assert!(
            covered
                .iter()
                .any(|b| b.covered.is_some() && labels[b.to] + labels[b.from] == 1)
        );
        assert!(joined(&covered, 2));
        assert!(!joined(&covered, 3), "the gap to part 3 is open air");
        assert!(!joined(&covered, 4), "a fruit is not thin");
    }
}
