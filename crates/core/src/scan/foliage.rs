//! Leaves told from bark by shape alone, for clouds without colours (a
//! LiDAR's, or a depth camera's without RGB).
//!
//! Each 4 mm cube of the cloud is described by how the cubes around it
//! spread at four scales (1 and 2 cm around it, 4 and 8 cm around its
//! 16 mm cube: a leaf is a 5 cm flat disc, a twig a line, a thick branch a
//! curved sheet that runs on past any leaf), and a small
//! classifier ([`FoliageClassifier`], a three-layer perceptron trained on
//! synthetic scans of train-split trees by `treemanip train-foliage`)
//! gives the chance that the cube is leaf. The chances are averaged over
//! [`SMOOTHING_RADIUS`] (leaves are whole discs; a twig's cube that looks
//! flat is alone among twig cubes) and cubes above one half are foliage.
//!
//! A hand-made rule (flat patches grown by their normals, dropped when no
//! larger than a leaf) found only 47 % of the leaf points and took 3-7 %
//! of the bark: at 3 mm noise half the leaf points do not look flat at
//! 1.5 cm, and a leaf seen edge-on looks like a twig. The classifier
//! weighs all the scales together.

use std::sync::OnceLock;

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::geometry::principal::principal;
use crate::model::mlp::Mlp;
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
/// Cubes' chances are averaged within this radius (m).
pub const SMOOTHING_RADIUS: f64 = 0.008;
/// At most this many cubes are averaged (8 mm holds about 30 cubes of a
/// flat leaf).
const SMOOTHING_NEIGHBOURS: usize = 32;
/// A cube whose averaged chance is above this is foliage.
pub const THRESHOLD: f64 = 0.5;

/// One cube's features.
pub type Features = [f32; FEATURES];

/// A cloud in 4 mm cubes and in coarse cubes, with each fine cube's
/// coarse one.
pub struct Grids {
    pub fine: Voxels,
    fine_index: PointIndex,
    coarse: Voxels,
    coarse_index: PointIndex,
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

/// The features of every fine cube, `up` the cloud's up (unit).
pub fn features(grids: &Grids, up: &Vector3<f64>) -> Vec<Features> {
    let all: Vec<usize> = (0..grids.fine.centres.len()).collect();
    features_of(grids, up, &all)
}

/// [`features`] of the fine cubes `ids` only.
pub fn features_of(grids: &Grids, up: &Vector3<f64>, ids: &[usize]) -> Vec<Features> {
    fine_features(grids, &coarse_features(grids, up), up, ids)
}

/// The coarse scales' features of every coarse cube: computed once and
/// shared by the fine cubes in it.
fn coarse_features(grids: &Grids, up: &Vector3<f64>) -> Vec<[f32; COARSE_FEATURES]> {
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
fn fine_features(
    grids: &Grids,
    coarse: &[[f32; COARSE_FEATURES]],
    up: &Vector3<f64>,
    ids: &[usize],
) -> Vec<Features> {
    ids.par_iter()
        .map(|&v| {
            let c = &grids.fine.centres[v];
            let mut f = [0.0f32; FEATURES];
            let all = grids
                .fine_index
                .near(c, NEIGHBOURS, FINE_SCALES[FINE_SCALES.len() - 1]);
            let split = FINE_SCALES.len() * PER_SCALE;
            scales(&grids.fine, &all, c, &FINE_SCALES, up, &mut f[..split]);
            f[split..].copy_from_slice(&coarse[grids.coarse.of_point[v]]);
            f
        })
        .collect()
}

/// How the classifier was made and how it did on trees it never saw.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FoliageCard {
    /// The command that regenerates it.
    pub command: String,
    pub seed: u64,
    /// What it was trained on.
    pub data: String,
    /// Cubes trained on.
    pub examples: usize,
    /// On the test split's leafy one-view scans (3 mm): the share of leaf
    /// points called foliage, and of bark points.
    pub held_out_leaf_found: f64,
    pub held_out_bark_lost: f64,
}

/// The per-cube classifier: features normalised by the training set's
/// mean and standard deviation, then an [`Mlp`] giving the logit of leaf.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FoliageClassifier {
    pub mean: Vec<f32>,
    pub std: Vec<f32>,
    pub mlp: Mlp,
    pub card: FoliageCard,
}

static SHIPPED: OnceLock<FoliageClassifier> = OnceLock::new();

impl FoliageClassifier {
    /// The classifier shipped in `models/foliage.json`, built into the
    /// library.
    pub fn shipped() -> &'static Self {
        SHIPPED.get_or_init(|| {
            let c: Self = serde_json::from_str(include_str!("../../../../models/foliage.json"))
                .expect("models/foliage.json is a foliage classifier (checked by a test)");
            c.check()
                .expect("models/foliage.json is well formed (checked by a test)");
            c
        })
    }

    /// Whether the shapes fit [`FEATURES`] and one output.
    pub fn check(&self) -> Result<(), String> {
        let [a, b, c] = &self.mlp.layers;
        let ok = self.mean.len() == FEATURES
            && self.std.len() == FEATURES
            && a.inputs == FEATURES
            && b.inputs == a.outputs
            && c.inputs == b.outputs
            && c.outputs == 1
            && [a, b, c]
                .iter()
                .all(|l| l.weight.len() == l.inputs * l.outputs && l.bias.len() == l.outputs);
        ok.then_some(())
            .ok_or_else(|| format!("a foliage classifier takes {FEATURES} features to 1 logit"))
    }

    /// Features normalised as the classifier reads them.
    pub fn normalise(&self, f: &Features) -> Features {
        let mut out = [0.0f32; FEATURES];
        for k in 0..FEATURES {
            out[k] = (f[k] - self.mean[k]) / self.std[k].max(1e-6);
        }
        out
    }

    /// The chance that a cube with features `f` is leaf.
    pub fn chance(&self, f: &Features) -> f64 {
        let logit = self.mlp.apply(&self.normalise(f))[0] as f64;
        1.0 / (1.0 + (-logit).exp())
    }
}

/// Which points of a cloud are foliage by shape.
#[derive(Debug, Clone)]
pub struct FoliageCall {
    /// Per point.
    pub foliage: Vec<bool>,
    /// The share of the points called foliage.
    pub share: f64,
}

/// Every this many cubes are classified to tell whether a cloud is leafy
/// before all are ([`call_foliage`] with a `min_share`): a bare cloud then
/// costs an eighth of a leafy one.
const SURVEY_STRIDE: usize = 8;

/// Calls each of `points` foliage or not with `classifier`. With
/// `min_share`, first a survey of every [`SURVEY_STRIDE`]th cube: when
/// less than that share of the surveyed points look like leaf, `None`
/// (the cloud is not leafy) without classifying the rest.
pub fn call_foliage(
    points: &[Point3<f64>],
    up: &Vector3<f64>,
    classifier: &FoliageClassifier,
    min_share: Option<f64>,
) -> Option<FoliageCall> {
    let grids = Grids::new(points);
    let voxels = &grids.fine;
    let coarse = coarse_features(&grids, up);
    if let Some(min) = min_share {
        let survey: Vec<usize> = (0..voxels.centres.len()).step_by(SURVEY_STRIDE).collect();
        let (mut leaf, mut all) = (0usize, 0usize);
        for (f, &v) in fine_features(&grids, &coarse, up, &survey)
            .iter()
            .zip(&survey)
        {
            all += voxels.counts[v];
            if classifier.chance(f) > THRESHOLD {
                leaf += voxels.counts[v];
            }
        }
        if (leaf as f64) < min * all as f64 {
            return None;
        }
    }
    let all: Vec<usize> = (0..voxels.centres.len()).collect();
    let chances: Vec<f64> = fine_features(&grids, &coarse, up, &all)
        .par_iter()
        .map(|f| classifier.chance(f))
        .collect();
    let leafy: Vec<bool> = voxels
        .centres
        .par_iter()
        .map(|c| {
            let (mut sum, mut weight) = (0.0, 0.0);
            for (j, _) in grids
                .fine_index
                .near(c, SMOOTHING_NEIGHBOURS, SMOOTHING_RADIUS)
            {
                let w = voxels.counts[j] as f64;
                sum += chances[j] * w;
                weight += w;
            }
            weight > 0.0 && sum / weight > THRESHOLD
        })
        .collect();
    let foliage: Vec<bool> = voxels.of_point.iter().map(|&v| leafy[v]).collect();
    let share = foliage.iter().filter(|&&f| f).count() as f64 / points.len().max(1) as f64;
    Some(FoliageCall { foliage, share })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scan::scanner::{Origin, ScanParams, scan};
    use crate::tree::{ScaParams, generate};

    #[test]
    fn the_shipped_classifier_is_well_formed_and_says_how_it_was_made() {
        let c = FoliageClassifier::shipped();
        assert!(c.check().is_ok());
        assert!(
            c.card.command.contains("train-foliage"),
            "{}",
            c.card.command
        );
        assert!(c.card.held_out_leaf_found > 0.8, "{:?}", c.card);
        assert!(c.card.held_out_bark_lost < 0.15, "{:?}", c.card);
    }

    /// On a leafy scan of a tree the classifier never saw (another seed
    /// than the training split's), most leaf points are called foliage
    /// and few bark points are.
    #[test]
    fn leaves_are_told_from_bark_by_shape() {
        let tree = generate(20, 4242, &ScaParams::default()).unwrap();
        let scanned = scan(
            &tree,
            &ScanParams {
                viewpoints: 1,
                noise: 0.003,
                leaves_per_twig: 8,
                seed: 5,
                ..ScanParams::default()
            },
        )
        .unwrap();
        let call = call_foliage(
            &scanned.cloud.points,
            &Vector3::z(),
            FoliageClassifier::shipped(),
            None,
        )
        .unwrap();
        let (mut leaf, mut leaf_found, mut bark, mut bark_lost) = (0, 0, 0, 0);
        for (o, f) in scanned.origins.iter().zip(&call.foliage) {
            match o {
                Origin::Leaf => {
                    leaf += 1;
                    leaf_found += usize::from(*f);
                }
                Origin::Branch(_) => {
                    bark += 1;
                    bark_lost += usize::from(*f);
                }
                _ => {}
            }
        }
        assert!(leaf > 1000 && bark > 1000, "{leaf} {bark}");
        let found = leaf_found as f64 / leaf as f64;
        let lost = bark_lost as f64 / bark as f64;
        assert!(found > 0.85, "leaf points found {found}");
        assert!(lost < 0.12, "bark points lost {lost}");
    }
}
