//! What each 4 mm cube's surroundings look like: how the cubes around it
//! spread at four scales (1 and 2 cm around it, 4 and 8 cm around its
//! 16 mm cube). A leaf is a 5 cm flat disc, a twig a line, a thick branch
//! a curved sheet that runs on past any leaf.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use crate::geometry::principal::principal;
use crate::scan::neighbours::PointIndex;
use crate::scan::voxel::{Voxels, voxelize};

/// The cube edge (m) the features are computed on (the classifier was
/// trained on it, whatever the extraction's own cube).
pub const VOXEL: f64 = 0.004;
/// Neighbourhood radii (m) over the 4 mm cubes.
pub const FINE_SCALES: [f64; 2] = [0.01, 0.02];
/// The edge (m) of the coarser cubes the larger scales are read on: 64
/// neighbours of a 4 mm cube on a sheet of bark reach only about 2 cm, so
/// a trunk's bark and a leaf would look alike; at 16 mm they reach 9 cm,
/// past any leaf.
pub const COARSE_VOXEL: f64 = 0.016;
/// Neighbourhood radii (m) over the coarse cubes.
pub const COARSE_SCALES: [f64; 2] = [0.04, 0.08];
/// Features per scale.
pub const PER_SCALE: usize = 8;
/// Features of the coarse scales.
const COARSE_FEATURES: usize = COARSE_SCALES.len() * PER_SCALE;
/// Features per cube.
pub const FEATURES: usize = FINE_SCALES.len() * PER_SCALE + COARSE_FEATURES;
/// At most this many neighbouring cubes per query (bounds the work in
/// dense clouds; the classifier was trained with the same bound).
const NEIGHBOURS: usize = 64;
/// One cube's features.
pub type Features = [f32; FEATURES];

/// A cloud in 4 mm cubes and in coarse cubes, with each fine cube's
/// coarse one.
pub struct Grids {
    pub fine: Voxels,
    pub(super) fine_index: PointIndex,
    pub(super) coarse: Voxels,
    pub(super) coarse_index: PointIndex,
}

impl Grids {
    pub fn new(points: &[Point3<f64>]) -> Self {
        let fine = voxelize(points, VOXEL);
        let fine_index = PointIndex::new(&fine.centres);
        // Coarse cubes of the fine cubes' centres, each weighted by its
        // points.
        let mut coarse = voxelize(&fine.centres, COARSE_VOXEL);
        coarse.counts.iter_mut().for_each(|c| *c = 0);
        for (i, &k) in coarse.of_point.iter().enumerate() {
            coarse.counts[k] += fine.counts[i];
        }
        let coarse_index = PointIndex::new(&coarse.centres);
        Self {
            fine,
            fine_index,
            coarse,
            coarse_index,
        }
    }
}

/// Per scale r, over the cubes `near` (nearest first) within r: the
/// number of cubes (log) and their mean distance over r (how the cubes
/// fill the ball, not how many points they hold: the scanner's density
/// must not matter, and a dense patch of bark close to the scanner once
/// looked like a leaf facing it), the second and third spreads over
/// the first, the first spread over r, how upright the main axis and the
/// normal are, and how far the neighbours' mean is from the cube over r
/// (an edge or a tip).
///
/// One query at the largest scale serves the smaller: the neighbours come
/// nearest first, so those within a smaller r are a prefix of them, the
/// same as that scale's own query (the nearest [`NEIGHBOURS`] within r)
/// would give.
fn scales(
    voxels: &Voxels,
    all: &[(usize, f64)],
    c: &Point3<f64>,
    radii: &[f64],
    up: &Vector3<f64>,
    f: &mut [f32],
) {
    for (s, &r) in radii.iter().enumerate() {
        let within = all.partition_point(|&(_, d)| d <= r);
        let near = &all[..within];
        let out = &mut f[s * PER_SCALE..(s + 1) * PER_SCALE];
        out[0] = (near.len() as f32).ln_1p();
        out[1] =
            (near.iter().map(|&(_, d)| d).sum::<f64>() / (near.len().max(1) as f64 * r)) as f32;
        if near.len() < 4 {
            continue;
        }
        let q: Vec<Point3<f64>> = near.iter().map(|&(j, _)| voxels.centres[j]).collect();
        let p = principal(&q);
        let first = p.spread[0].max(1e-9);
        out[2] = (p.spread[1] / first) as f32;
        out[3] = (p.spread[2] / first) as f32;
        out[4] = (p.spread[0] / r) as f32;
        out[5] = p.axes[0].dot(up).abs() as f32;
        out[6] = p.axes[2].dot(up).abs() as f32;
        out[7] = ((p.mean - c).norm() / r) as f32;
    }
}

/// Each fine cube's nearest cubes (at most `NEIGHBOURS` within the
/// largest fine scale), nearest first: the one query both the shape
/// features and the context ([`super::context`]) read, made once. Indices
/// only (4 bytes a neighbour, 256 a cube); distances are recomputed.
pub struct FineNeighbours {
    offsets: Vec<usize>,
    items: Vec<u32>,
}

impl FineNeighbours {
    pub fn new(grids: &Grids) -> Self {
        let lists: Vec<Vec<u32>> = grids
            .fine
            .centres
            .par_iter()
            .map(|c| {
                grids
                    .fine_index
                    .near(c, NEIGHBOURS, FINE_SCALES[FINE_SCALES.len() - 1])
                    .into_iter()
                    .map(|(j, _)| j as u32)
                    .collect()
            })
            .collect();
        let mut offsets = Vec::with_capacity(lists.len() + 1);
        offsets.push(0);
        let mut items = Vec::with_capacity(lists.iter().map(Vec::len).sum());
        for list in lists {
            items.extend(list);
            offsets.push(items.len());
        }
        Self { offsets, items }
    }

    /// Fine cube `v`'s neighbours with their distances (m), nearest first.
    pub fn of(&self, grids: &Grids, v: usize) -> Vec<(usize, f64)> {
        let c = grids.fine.centres[v];
        self.items[self.offsets[v]..self.offsets[v + 1]]
            .iter()
            .map(|&j| (j as usize, (grids.fine.centres[j as usize] - c).norm()))
            .collect()
    }
}

/// The features of every fine cube, `up` the cloud's up (unit).
pub fn features(grids: &Grids, up: &Vector3<f64>) -> Vec<Features> {
    features_and_neighbours(grids, up).0
}

/// [`features`], and the neighbours they were read from (for the
/// context).
pub fn features_and_neighbours(
    grids: &Grids,
    up: &Vector3<f64>,
) -> (Vec<Features>, FineNeighbours) {
    features_and_neighbours_with(grids, &coarse_features(grids, up), up)
}

/// [`features_and_neighbours`] with the coarse cubes' features already
/// computed ([`coarse_features`]).
pub(super) fn features_and_neighbours_with(
    grids: &Grids,
    coarse: &[[f32; COARSE_FEATURES]],
    up: &Vector3<f64>,
) -> (Vec<Features>, FineNeighbours) {
    let neighbours = FineNeighbours::new(grids);
    let features = (0..grids.fine.centres.len())
        .into_par_iter()
        .map(|v| fine_features_from(grids, coarse, up, v, &neighbours.of(grids, v)))
        .collect();
    (features, neighbours)
}

/// [`features`] of the fine cubes `ids` only.
pub fn features_of(grids: &Grids, up: &Vector3<f64>, ids: &[usize]) -> Vec<Features> {
    fine_features(grids, &coarse_features(grids, up), up, ids)
}

/// The coarse scales' features of every coarse cube: computed once and
/// shared by the fine cubes in it.
pub(super) fn coarse_features(grids: &Grids, up: &Vector3<f64>) -> Vec<[f32; COARSE_FEATURES]> {
    grids
        .coarse
        .centres
        .par_iter()
        .map(|c| {
            let mut f = [0.0f32; COARSE_FEATURES];
            let all =
                grids
                    .coarse_index
                    .near(c, NEIGHBOURS, COARSE_SCALES[COARSE_SCALES.len() - 1]);
            scales(&grids.coarse, &all, c, &COARSE_SCALES, up, &mut f);
            f
        })
        .collect()
}

/// The features of the fine cubes `ids`: the fine scales around the cube,
/// then `coarse`'s features of its coarse cube.
pub(super) fn fine_features(
    grids: &Grids,
    coarse: &[[f32; COARSE_FEATURES]],
    up: &Vector3<f64>,
    ids: &[usize],
) -> Vec<Features> {
    ids.par_iter()
        .map(|&v| {
            let all = grids.fine_index.near(
                &grids.fine.centres[v],
                NEIGHBOURS,
                FINE_SCALES[FINE_SCALES.len() - 1],
            );
            fine_features_from(grids, coarse, up, v, &all)
        })
        .collect()
}

/// Fine cube `v`'s features from its neighbours `all` (nearest first).
fn fine_features_from(
    grids: &Grids,
    coarse: &[[f32; COARSE_FEATURES]],
    up: &Vector3<f64>,
    v: usize,
    all: &[(usize, f64)],
) -> Features {
    let mut f = [0.0f32; FEATURES];
    let split = FINE_SCALES.len() * PER_SCALE;
    let c = &grids.fine.centres[v];
    scales(&grids.fine, all, c, &FINE_SCALES, up, &mut f[..split]);
    f[split..].copy_from_slice(&coarse[grids.coarse.of_point[v]]);
    f
}
