//! Training the scan's foliage classifier
//! ([`crate::scan::foliage::FoliageClassifier`]) on synthetic scans.
//!
//! Examples: 4 mm cubes of scans of train-split trees (SCA, one per size
//! 10-30; orchard trees of 40-120 nodes, whose trunks are thicker), leafy
//! from one viewpoint at 1, 2, 3 and 5 mm noise and from three at 2 and
//! 5 mm, and bare from one viewpoint at 1, 3 and 5 mm and from three at 2
//! and 5 mm (so that bark seen without leaves, however noisy, is called
//! bark too); a cube is leaf
//! when most of its points came from a leaf. Adam on the binary
//! cross-entropy of the logit. The card records the share of leaf and
//! bark points called foliage on the test split's leafy one-view scans
//! (3 mm), trees the training never saw.
//!
//! Stages after the first ([`crate::scan::foliage::context`]) are trained
//! the same way, one after another, on the same scans' cubes with their
//! context under the stages trained before them.

use burn::optim::{AdamConfig, GradientsParams};
use burn::tensor::Device;
use burn::tensor::activation::relu;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;

use super::device::tensor;
use super::modules::TrainMlp;
use crate::dataset::Split;
use crate::model::mlp::Mlp;
use crate::scan::foliage::{
    FEATURES, FoliageCard, FoliageClassifier, Grids, STAGE_INPUTS, Stage, call_foliage,
    context_features, features_and_neighbours, features_of, stage_inputs,
};
use crate::scan::{Origin, ScanParams, scan};
use crate::seed::derive_seed;
use crate::tree::Tree;
use crate::tree::collection::{TreeShape, tree_set};

/// How to train it.
#[derive(Debug, Clone)]
pub struct FoliageConfig {
    pub seed: u64,
    pub epochs: usize,
    pub hidden: usize,
    /// Stages after the first, each reading the one before's calls of
    /// the cubes around.
    pub context_stages: usize,
    /// At most this many cubes from each scan.
    pub per_scan: usize,
    pub batch: usize,
    pub learning_rate: f64,
    /// The command line, for the card.
    pub command: String,
}

/// (viewpoints, noise σ (m), leaves per twig) of the training scans.
const CONDITIONS: [(usize, f64, usize); 11] = [
    (1, 0.001, 8),
    (1, 0.002, 8),
    (1, 0.003, 8),
    (1, 0.005, 8),
    (3, 0.002, 8),
    (3, 0.005, 8),
    (1, 0.001, 0),
    (1, 0.003, 0),
    (1, 0.005, 0),
    (3, 0.002, 0),
    (3, 0.005, 0),
];

/// Orchard tree sizes trained on beside the SCA trees: their trunks and
/// scaffolds (2-5 cm) are thicker than any SCA branch, and bark that
/// thick must not look like leaf.
const ORCHARD_SIZES: [usize; 5] = [40, 60, 80, 100, 120];

/// One SCA tree of every size 10-30 of `split`, then one orchard tree of
/// each of [`ORCHARD_SIZES`].
fn trees(split: Split, seed: u64) -> anyhow::Result<Vec<Tree>> {
    let base = derive_seed(seed, &[split.seed_part()]);
    let mut out = Vec::new();
    let sizes = (10..=30)
        .map(|n| (n, TreeShape::Sca))
        .chain(ORCHARD_SIZES.iter().map(|&n| (n, TreeShape::Orchard)));
    for (n, shape) in sizes {
        let set = tree_set(
            n,
            1,
            base,
            &crate::tree::ScaParams::default(),
            shape,
            true,
            |_, _| {},
        )?;
        out.extend(set.into_iter().map(|(_, t)| t));
    }
    Ok(out)
}

fn scan_of(
    tree: &Tree,
    (views, noise, leaves): (usize, f64, usize),
    seed: u64,
) -> crate::scan::Scan {
    scan(
        tree,
        &ScanParams {
            viewpoints: views,
            noise,
            leaves_per_twig: leaves,
            seed,
            ..ScanParams::default()
        },
    )
    .unwrap_or_else(|e| panic!("the training scans' parameters are valid: {e}"))
}

/// The training cubes' inputs to stage `stage` (row after row, each
/// [`FEATURES`] long for the first stage, [`STAGE_INPUTS`] for the later
/// ones, whose context comes from `classifier`'s stages so far) and
/// their labels (1: leaf). The same cubes for every stage.
pub fn examples(
    config: &FoliageConfig,
    classifier: &FoliageClassifier,
    stage: usize,
) -> anyhow::Result<(Vec<f32>, Vec<f32>)> {
    let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(config.seed, &[0xf011]));
    let (mut xs, mut ys) = (Vec::new(), Vec::new());
    for (i, tree) in trees(Split::Train, config.seed)?.iter().enumerate() {
        for (k, &condition) in CONDITIONS.iter().enumerate() {
            let scanned = scan_of(
                tree,
                condition,
                derive_seed(config.seed, &[i as u64, k as u64]),
            );
            let grids = Grids::new(&scanned.cloud.points);
            let voxels = &grids.fine;
            let mut leaf = vec![0usize; voxels.centres.len()];
            for (&v, o) in voxels.of_point.iter().zip(&scanned.origins) {
                leaf[v] += usize::from(*o == Origin::Leaf);
            }
            let mut ids: Vec<usize> = (0..voxels.centres.len()).collect();
            ids.shuffle(&mut rng);
            ids.truncate(config.per_scan);
            let up = nalgebra::Vector3::z();
            if stage == 0 {
                for f in features_of(&grids, &up, &ids) {
                    xs.extend_from_slice(&f);
                }
            } else {
                let (all, near) = features_and_neighbours(&grids, &up);
                let chances = classifier.chances(&grids, (&all, &near), stage);
                let context = context_features(&grids, &near, &chances);
                for &v in &ids {
                    xs.extend_from_slice(&stage_inputs(&all[v], &context[v]));
                }
            }
            ys.extend(ids.iter().map(|&v| {
                if 2 * leaf[v] > voxels.counts[v] {
                    1.0
                } else {
                    0.0
                }
            }));
        }
    }
    Ok((xs, ys))
}

/// Trains one stage on rows of `width` inputs; `on_epoch(epoch, mean
/// loss)` after each epoch.
fn fit_stage(
    config: &FoliageConfig,
    (xs, ys): (&[f32], &[f32]),
    width: usize,
    rng: &mut ChaCha8Rng,
    on_epoch: &mut impl FnMut(usize, f64),
) -> Stage {
    // Normalisation from the training cubes.
    let n = ys.len() as f64;
    let mut mean = vec![0.0f32; width];
    let mut std = vec![0.0f32; width];
    for k in 0..width {
        let column = || xs.iter().skip(k).step_by(width).map(|&x| x as f64);
        let m = column().sum::<f64>() / n;
        let v = column().map(|x| (x - m).powi(2)).sum::<f64>() / n;
        mean[k] = m as f32;
        std[k] = v.sqrt().max(1e-6) as f32;
    }
    let mut stage = Stage {
        mean,
        std,
        mlp: Mlp::random(width, config.hidden, 1, rng),
    };
    let normalised: Vec<f32> = xs.chunks(width).flat_map(|x| stage.normalise(x)).collect();
    let device = Device::flex().autodiff();
    let mut model = TrainMlp::new(&stage.mlp, &device);
    let mut optimizer = AdamConfig::new().init();
    let mut ids: Vec<usize> = (0..ys.len()).collect();
    for epoch in 0..config.epochs {
        ids.shuffle(rng);
        let (mut sum, mut count) = (0.0, 0usize);
        for chunk in ids.chunks(config.batch) {
            let b = chunk.len();
            let x: Vec<f32> = chunk
                .iter()
                .flat_map(|&i| normalised[i * width..(i + 1) * width].iter().copied())
                .collect();
            let y: Vec<f32> = chunk.iter().map(|&i| ys[i]).collect();
            let z = model.forward(tensor(x, [b, width], &device));
            let y = tensor(y, [b, 1], &device);
            // Binary cross-entropy of the logit z, written stably:
            // max(z, 0) − y z + ln(1 + e^−|z|).
            let loss = (relu(z.clone()) - y * z.clone() + z.abs().neg().exp().log1p()).mean();
            sum += loss.clone().into_scalar::<f32>() as f64 * b as f64;
            count += b;
            let grads = GradientsParams::from_grads(loss.backward(), &model);
            model = optimizer.step(config.learning_rate, model, grads);
        }
        on_epoch(epoch, sum / count as f64);
    }
    stage.mlp = model.weights();
    stage
}

/// Trains the classifier, its first stage and then each context stage;
/// `on_epoch(stage, epoch, mean loss)` after each epoch.
pub fn train_foliage(
    config: &FoliageConfig,
    mut on_epoch: impl FnMut(usize, usize, f64),
) -> anyhow::Result<FoliageClassifier> {
    anyhow::ensure!(config.epochs > 0 && config.batch > 0 && config.hidden > 0);
    let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(config.seed, &[0xf012]));
    let mut classifier = FoliageClassifier {
        stages: Vec::new(),
        card: FoliageCard {
            command: config.command.clone(),
            seed: config.seed,
            data: format!(
                "scans of train-split trees (SCA, one per size 10-30; orchard, sizes {:?}), conditions (views, noise m, leaves per twig) {:?}, at most {} cubes each; {} stage(s) after the first, each on the same cubes with their context",
                ORCHARD_SIZES, CONDITIONS, config.per_scan, config.context_stages
            ),
            examples: 0,
            held_out_leaf_found: 0.0,
            held_out_bark_lost: 0.0,
        },
    };
    for stage in 0..=config.context_stages {
        let (xs, ys) = examples(config, &classifier, stage)?;
        anyhow::ensure!(!ys.is_empty(), "no training cubes");
        classifier.card.examples = ys.len();
        let width = if stage == 0 { FEATURES } else { STAGE_INPUTS };
        let fitted = fit_stage(config, (&xs, &ys), width, &mut rng, &mut |e, l| {
            on_epoch(stage, e, l)
        });
        classifier.stages.push(fitted);
    }
    let (found, lost) = held_out(&classifier, config.seed)?;
    classifier.card.held_out_leaf_found = found;
    classifier.card.held_out_bark_lost = lost;
    Ok(classifier)
}

/// On the test split's leafy one-view scans (3 mm): the share of leaf
/// points and of bark points called foliage.
pub fn held_out(classifier: &FoliageClassifier, seed: u64) -> anyhow::Result<(f64, f64)> {
    let (mut leaf, mut found, mut bark, mut lost) = (0usize, 0usize, 0usize, 0usize);
    for (i, tree) in trees(Split::Test, seed)?.iter().enumerate() {
        let scanned = scan_of(tree, (1, 0.003, 8), derive_seed(seed, &[0x7e57, i as u64]));
        let call = call_foliage(
            &scanned.cloud.points,
            &nalgebra::Vector3::z(),
            classifier,
            None,
        )
        .expect("without a minimum share every cloud is called");
        for (o, &f) in scanned.origins.iter().zip(&call.foliage) {
            match o {
                Origin::Leaf => {
                    leaf += 1;
                    found += usize::from(f);
                }
                Origin::Branch(_) => {
                    bark += 1;
                    lost += usize::from(f);
                }
                _ => {}
            }
        }
    }
    Ok((
        found as f64 / leaf.max(1) as f64,
        lost as f64 / bark.max(1) as f64,
    ))
}
