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
    FEATURES, Features, FoliageCard, FoliageClassifier, Grids, call_foliage, features_of,
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

/// The cubes' features and labels (1: leaf) of the training scans.
pub fn examples(config: &FoliageConfig) -> anyhow::Result<(Vec<Features>, Vec<f32>)> {
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
            xs.extend(features_of(&grids, &nalgebra::Vector3::z(), &ids));
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

/// Trains the classifier; `on_epoch(epoch, mean loss)` after each epoch.
pub fn train_foliage(
    config: &FoliageConfig,
    mut on_epoch: impl FnMut(usize, f64),
) -> anyhow::Result<FoliageClassifier> {
    anyhow::ensure!(config.epochs > 0 && config.batch > 0 && config.hidden > 0);
    let (xs, ys) = examples(config)?;
    anyhow::ensure!(!xs.is_empty(), "no training cubes");
    // Normalisation from the training cubes.
    let n = xs.len() as f64;
    let mut mean = vec![0.0f32; FEATURES];
    let mut std = vec![0.0f32; FEATURES];
    for k in 0..FEATURES {
        let m = xs.iter().map(|x| x[k] as f64).sum::<f64>() / n;
        let v = xs.iter().map(|x| (x[k] as f64 - m).powi(2)).sum::<f64>() / n;
        mean[k] = m as f32;
        std[k] = v.sqrt().max(1e-6) as f32;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(config.seed, &[0xf012]));
    let mut classifier = FoliageClassifier {
        mean,
        std,
        mlp: Mlp::random(FEATURES, config.hidden, 1, &mut rng),
        card: FoliageCard {
            command: config.command.clone(),
            seed: config.seed,
            data: format!(
                "scans of train-split trees (SCA, one per size 10-30; orchard, sizes {:?}), conditions (views, noise m, leaves per twig) {:?}, at most {} cubes each",
                ORCHARD_SIZES, CONDITIONS, config.per_scan
            ),
            examples: xs.len(),
            held_out_leaf_found: 0.0,
            held_out_bark_lost: 0.0,
        },
    };
    let normalised: Vec<Features> = xs.iter().map(|x| classifier.normalise(x)).collect();
    let device = Device::flex().autodiff();
    let mut model = TrainMlp::new(&classifier.mlp, &device);
    let mut optimizer = AdamConfig::new().init();
    let mut ids: Vec<usize> = (0..xs.len()).collect();
    for epoch in 0..config.epochs {
        ids.shuffle(&mut rng);
        let (mut sum, mut count) = (0.0, 0usize);
        for chunk in ids.chunks(config.batch) {
            let b = chunk.len();
            let x: Vec<f32> = chunk.iter().flat_map(|&i| normalised[i]).collect();
            let y: Vec<f32> = chunk.iter().map(|&i| ys[i]).collect();
            let z = model.forward(tensor(x, [b, FEATURES], &device));
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
    classifier.mlp = model.weights();
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
