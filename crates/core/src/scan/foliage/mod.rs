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
//!
//! Shape alone takes the twigs with their leaves, so later stages look
//! again with the earlier stage's calls of the cubes around
//! ([`context`]): on the test split's one-view leafy scans (3 mm) the
//! terminal twigs' bark points called foliage went from 36 % to 21 %.

pub mod context;
pub mod shape;

use std::sync::OnceLock;

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

pub use context::{CONTEXT_FEATURES, ContextFeatures, context_features};

use context::mean_chance;
pub use shape::{
    FEATURES, Features, FineNeighbours, Grids, VOXEL, features, features_and_neighbours,
    features_of,
};

use crate::model::mlp::Mlp;
use shape::{coarse_features, features_and_neighbours_with, fine_features};

/// Cubes' chances are averaged within this radius (m).
pub const SMOOTHING_RADIUS: f64 = 0.012;
/// At most this many cubes are averaged (12 mm holds about 30 cubes of a
/// flat leaf).
const SMOOTHING_NEIGHBOURS: usize = 32;
/// A cube whose averaged chance is above this is foliage. With the
/// smoothing radius, chosen on 42 leafy one-view scans (3 mm) of trees
/// neither the training nor the evaluation uses (generator seed 99;
/// recall / precision at 1.0 r): 0.5 and 8 mm 0.757 / 0.896, 0.5 and
/// 12 mm 0.751 / 0.912, 0.55 and 12 mm 0.760 / 0.909, 0.6 and 12 mm
/// 0.765 / 0.897.
pub const THRESHOLD: f64 = 0.55;
/// A surveyed cube looks like leaf when the first stage's chance is above
/// this ([`call_foliage`]'s `min_share`).
const SURVEY_THRESHOLD: f64 = 0.5;
/// The inputs of a stage after the first: the cube's shape, then its
/// context.
pub const STAGE_INPUTS: usize = FEATURES + CONTEXT_FEATURES;

/// How the classifier was made and how it did on trees it never saw.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FoliageCard {
    /// The command that regenerates it.
    pub command: String,
    pub seed: u64,
    /// What it was trained on.
    pub data: String,
    /// Cubes trained on (per stage).
    pub examples: usize,
    /// On the test split's leafy one-view scans (3 mm): the share of leaf
    /// points called foliage, and of bark points.
    pub held_out_leaf_found: f64,
    pub held_out_bark_lost: f64,
}

/// One stage: its inputs normalised by the training set's mean and
/// standard deviation, then an [`Mlp`] giving the logit of leaf.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Stage {
    pub mean: Vec<f32>,
    pub std: Vec<f32>,
    pub mlp: Mlp,
}

impl Stage {
    /// Whether the shapes fit `inputs` and one output.
    fn check(&self, inputs: usize) -> bool {
        let [a, b, c] = &self.mlp.layers;
        self.mean.len() == inputs
            && self.std.len() == inputs
            && a.inputs == inputs
            && b.inputs == a.outputs
            && c.inputs == b.outputs
            && c.outputs == 1
            && [a, b, c]
                .iter()
                .all(|l| l.weight.len() == l.inputs * l.outputs && l.bias.len() == l.outputs)
    }

    /// Inputs normalised as the stage reads them.
    pub fn normalise(&self, x: &[f32]) -> Vec<f32> {
        x.iter()
            .zip(self.mean.iter().zip(&self.std))
            .map(|(v, (m, s))| (v - m) / s.max(1e-6))
            .collect()
    }

    /// The chance that a cube with inputs `x` is leaf.
    pub fn chance(&self, x: &[f32]) -> f64 {
        let logit = self.mlp.apply(&self.normalise(x))[0] as f64;
        1.0 / (1.0 + (-logit).exp())
    }
}

/// The per-cube classifier: the first stage reads a cube's [`Features`];
/// each later one those and the cube's [`ContextFeatures`] under the
/// stage before.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FoliageClassifier {
    pub stages: Vec<Stage>,
    pub card: FoliageCard,
}

static SHIPPED: OnceLock<FoliageClassifier> = OnceLock::new();

impl FoliageClassifier {
    /// The classifier shipped in `models/foliage.json`, built into the
    /// library.
    pub fn shipped() -> &'static Self {
        SHIPPED.get_or_init(|| {
            let c: Self = serde_json::from_str(include_str!("../../../../../models/foliage.json"))
                .expect("models/foliage.json is a foliage classifier (checked by a test)");
            c.check()
                .expect("models/foliage.json is well formed (checked by a test)");
            c
        })
    }

    /// Whether there is a first stage taking [`FEATURES`] inputs and
    /// later ones taking [`STAGE_INPUTS`], each to one logit.
    pub fn check(&self) -> Result<(), String> {
        let ok = !self.stages.is_empty()
            && self
                .stages
                .iter()
                .enumerate()
                .all(|(k, s)| s.check(if k == 0 { FEATURES } else { STAGE_INPUTS }));
        ok.then_some(()).ok_or_else(|| {
            format!(
                "a foliage classifier's first stage takes {FEATURES} features to 1 logit, each later one {STAGE_INPUTS}"
            )
        })
    }

    /// The first stage's chance that a cube with features `f` is leaf.
    pub fn first_chance(&self, f: &Features) -> f64 {
        self.stages[0].chance(f)
    }

    /// Every fine cube's chance of leaf after `stages` stages (all when
    /// more than there are), from the cubes' `features` and the
    /// `neighbours` they were read from ([`features_and_neighbours`]).
    pub fn chances(
        &self,
        grids: &Grids,
        (features, neighbours): (&[Features], &FineNeighbours),
        stages: usize,
    ) -> Vec<f64> {
        let mut p: Vec<f64> = features.par_iter().map(|f| self.first_chance(f)).collect();
        for stage in self.stages.iter().take(stages).skip(1) {
            let context = context_features(grids, neighbours, &p);
            p = features
                .par_iter()
                .zip(&context)
                .map(|(f, c)| stage.chance(&stage_inputs(f, c)))
                .collect();
        }
        p
    }
}

/// A later stage's inputs: the cube's shape, then its context.
pub fn stage_inputs(f: &Features, c: &ContextFeatures) -> [f32; STAGE_INPUTS] {
    let mut x = [0.0f32; STAGE_INPUTS];
    x[..FEATURES].copy_from_slice(f);
    x[FEATURES..].copy_from_slice(c);
    x
}

/// Which points of a cloud are foliage by shape.
#[derive(Debug, Clone)]
pub struct FoliageCall {
    /// Per point.
    pub foliage: Vec<bool>,
    /// Per point, the smoothed chance that it is leaf (0-1; foliage above
    /// [`THRESHOLD`]).
    pub chance: Vec<f64>,
    /// The share of the points called foliage.
    pub share: f64,
}

/// Every this many cubes are classified to tell whether a cloud is leafy
/// before all are ([`call_foliage`] with a `min_share`): a bare cloud then
/// costs an eighth of a leafy one.
const SURVEY_STRIDE: usize = 8;

/// A cloud without colours is leafy when the shape classifier calls at
/// least this share of its points foliage: on bare scans it calls a few
/// per cent (bark seen at a glancing angle), on leafy ones about half.
pub const LEAFY_SHARE: f64 = 0.2;
/// Excess green (2g − r − b of the chromaticity) above which a point's
/// colour is foliage (Woebbecke et al. 1995): bark, soil and fruit score
/// near or below zero, leaves about 0.5.
pub const FOLIAGE_EXCESS_GREEN: f64 = 0.15;

/// Whether a colour is foliage green (dark colours never are: too little
/// light to tell).
pub fn is_foliage([r, g, b]: [u8; 3]) -> bool {
    let sum = r as f64 + g as f64 + b as f64;
    sum >= 30.0 && (2.0 * g as f64 - r as f64 - b as f64) / sum > FOLIAGE_EXCESS_GREEN
}

/// Calls each of `points` foliage or not with `classifier`. With
/// `min_share`, first a survey of every `SURVEY_STRIDE`th cube: when
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
            if classifier.first_chance(f) > SURVEY_THRESHOLD {
                leaf += voxels.counts[v];
            }
        }
        if (leaf as f64) < min * all as f64 {
            return None;
        }
    }
    let (features, neighbours) = features_and_neighbours_with(&grids, &coarse, up);
    let chances = classifier.chances(&grids, (&features, &neighbours), usize::MAX);
    let smoothed: Vec<f64> = voxels
        .centres
        .par_iter()
        .map(|c| {
            let near = grids
                .fine_index
                .near(c, SMOOTHING_NEIGHBOURS, SMOOTHING_RADIUS);
            mean_chance(&near, &chances, &voxels.counts)
        })
        .collect();
    let chance: Vec<f64> = voxels.of_point.iter().map(|&v| smoothed[v]).collect();
    let foliage: Vec<bool> = chance.iter().map(|&c| c > THRESHOLD).collect();
    let share = foliage.iter().filter(|&&f| f).count() as f64 / points.len().max(1) as f64;
    Some(FoliageCall {
        foliage,
        chance,
        share,
    })
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

    /// A 20-node tree of generator seed `tree_seed` (not the training
    /// split's) seen leafy from one viewpoint at 3 mm.
    fn leafy_scan(tree_seed: u64, scan_seed: u64) -> (crate::tree::Tree, crate::scan::Scan) {
        let tree = generate(20, tree_seed, &ScaParams::default()).unwrap();
        let scanned = scan(
            &tree,
            &ScanParams {
                viewpoints: 1,
                noise: 0.003,
                leaves_per_twig: 8,
                seed: scan_seed,
                ..ScanParams::default()
            },
        )
        .unwrap();
        (tree, scanned)
    }

    /// On a leafy scan of a tree the classifier never saw (another seed
    /// than the training split's), most leaf points are called foliage
    /// and few bark points are.
    #[test]
    fn leaves_are_told_from_bark_by_shape() {
        let (_, scanned) = leafy_scan(4242, 5);
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

    /// The context stage gives back the twigs shape alone takes with
    /// their leaves: on a leafy scan of a tree no stage saw, the terminal
    /// twigs' bark cubes called leaf (chance over one half) are fewer after
    /// every stage than after the first alone, and the leaf found no less.
    #[test]
    fn the_context_stage_gives_back_twigs_among_leaves() {
        let classifier = FoliageClassifier::shipped();
        assert!(classifier.stages.len() >= 2, "no context stage shipped");
        let (tree, scanned) = leafy_scan(4343, 6);
        let grids = Grids::new(&scanned.cloud.points);
        let (f, near) = features_and_neighbours(&grids, &Vector3::z());
        let first = classifier.chances(&grids, (&f, &near), 1);
        let all = classifier.chances(&grids, (&f, &near), usize::MAX);
        let mut has_child = vec![false; tree.len()];
        for j in 0..tree.len() {
            if let Some(p) = tree.parent(j) {
                has_child[p] = true;
            }
        }
        // [twig bark, leaf] points: all, called leaf by the first stage,
        // by every stage.
        let mut count = [[0usize; 3]; 2];
        for (o, &v) in scanned.origins.iter().zip(&grids.fine.of_point) {
            let k = match o {
                Origin::Branch(j) if !has_child[*j] => 0,
                Origin::Leaf => 1,
                _ => continue,
            };
            count[k][0] += 1;
            count[k][1] += usize::from(first[v] > 0.5);
            count[k][2] += usize::from(all[v] > 0.5);
        }
        let share = |k: usize, s: usize| count[k][s] as f64 / count[k][0].max(1) as f64;
        assert!(count[0][0] > 300 && count[1][0] > 1000, "{count:?}");
        assert!(
            share(0, 2) < 0.8 * share(0, 1),
            "twig bark called leaf: first stage {:.3}, all {:.3}",
            share(0, 1),
            share(0, 2)
        );
        assert!(
            share(1, 2) > share(1, 1) - 0.01,
            "leaf found: first stage {:.3}, all {:.3}",
            share(1, 1),
            share(1, 2)
        );
    }
}
