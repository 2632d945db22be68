//! Training with burn: the burn networks compute what the reference passes
//! and the exported ONNX graphs compute; a short run learns; checkpoints
//! save, load and resume exactly.

use std::path::Path;

use nalgebra::Vector3;
use treemanip::dataset::Split;
use treemanip::graph::contract::ModelOutput;
use treemanip::graph::stats::StatsBuilder;
use treemanip::graph::{Batch, GraphInput, Task, batch, encode_forward, encode_policy};
use treemanip::infer::{Backend, OnnxModel, init_backend};
use treemanip::nn::gnn::{Connectivity, EdgeAttributes, GnnConfig, GnnWeights};
use treemanip::nn::model::{Arch, ModelWeights};
use treemanip::nn::pointnet::{PointNetConfig, PointNetWeights, position_stats};
use treemanip::nn::train::data::Targets;
use treemanip::nn::train::step::descend;
use treemanip::nn::train::{
    EdgeLayout, ResumeOptions, StopReason, TrainConfig, burn_forward, current_weights, read_best,
    read_state, resume, train,
};
use treemanip::tree::{ScaParams, generate};

fn graphs(task: Task) -> Vec<GraphInput> {
    [(6usize, 11u64), (9, 12), (14, 13)]
        .iter()
        .enumerate()
        .map(|(k, &(n, seed))| {
            let tree = generate(n, seed, &ScaParams::default()).unwrap();
            match task {
                Task::Forward => encode_forward(
                    &tree,
                    n - 1 - k,
                    &Vector3::new(0.04, 0.07, -0.02 * k as f64),
                )
                .unwrap(),
                Task::Policy => {
                    let targets: Vec<_> = tree
                        .positions()
                        .iter()
                        .enumerate()
                        .map(|(j, p)| p + Vector3::new(0.003 * j as f64, -0.01, 0.02))
                        .collect();
                    encode_policy(&tree, &targets).unwrap()
                }
            }
        })
        .collect()
}

fn random_model(task: Task, arch: Arch, config: Option<GnnConfig>) -> ModelWeights {
    let gs = graphs(task);
    let mut stats = StatsBuilder::new(task);
    gs.iter().for_each(|g| stats.add(g));
    let mut w = match arch {
        Arch::Gnn => ModelWeights::Gnn(GnnWeights::random(
            config.unwrap_or(GnnConfig {
                hidden: 12,
                layers: 2,
                ..GnnConfig::paper(task)
            }),
            stats.finish(),
            5,
        )),
        Arch::PointNet => ModelWeights::PointNet(PointNetWeights::random(
            PointNetConfig {
                local: 16,
                global: 32,
                ..PointNetConfig::paper(task)
            },
            stats.finish(),
            position_stats(&gs),
            6,
        )),
    };
    w.set_output_scale([0.01, -0.02, 0.0], [0.05, 0.08, 0.03]);
    w
}

fn assert_close(a: &ModelOutput, b: &ModelOutput, batch: &Batch, tolerance: f32, what: &str) {
    let scale = a.vectors.iter().fold(1e-3f32, |m, v| m.max(v.abs()));
    for (k, m) in batch.mask.iter().enumerate() {
        if *m == 0.0 {
            continue;
        }
        for c in 0..3 {
            let (x, y) = (a.vectors[k * 3 + c], b.vectors[k * 3 + c]);
            assert!(
                (x - y).abs() <= tolerance * scale,
                "{what}: node {k} component {c}: {x} vs {y}"
            );
        }
        if let (Some(p), Some(q)) = (&a.affordance, &b.affordance) {
            assert!((p[k] - q[k]).abs() <= tolerance, "{what}: affordance {k}");
        }
    }
    assert_eq!(a.affordance.is_some(), b.affordance.is_some(), "{what}");
}

/// Every architecture, task and GNN ablation variant: burn = reference = ONNX.
#[test]
fn burn_reference_and_onnx_agree_for_every_model() {
    let backend = init_backend(Some(Path::new("/nonexistent/libonnxruntime.so"))).unwrap();
    assert_eq!(backend, Backend::Tract);
    let mut models = Vec::new();
    for task in [Task::Forward, Task::Policy] {
        models.push(random_model(task, Arch::Gnn, None));
        models.push(random_model(task, Arch::PointNet, None));
    }
    models.extend([Task::Forward, Task::Policy].map(branches_model));
    for model in &models {
        let task = model.task();
        let padded = batch(&graphs(task)).unwrap();
        let reference = model.forward(&padded);
        let trained = burn_forward(model, &padded);
        assert_close(&reference, &trained, &padded, 1e-4, &model.describe());
        let mut onnx = OnnxModel::from_bytes(&model.to_onnx(&[]), Vec::new()).unwrap();
        let exported = onnx.run(&padded).unwrap();
        assert_close(&trained, &exported, &padded, 1e-4, &model.describe());
        if let Some(a) = &exported.affordance {
            for g in 0..padded.batch {
                let sum: f32 = a[g * padded.n..(g + 1) * padded.n].iter().sum();
                assert!((sum - 1.0).abs() < 1e-5);
            }
        }
    }
}

#[test]
fn dropping_edge_attributes_changes_the_answer_and_branch_connectivity_ignores_far_pairs() {
    let full = random_model(Task::Forward, Arch::Gnn, None);
    let ModelWeights::Gnn(w) = &full else {
        unreachable!()
    };
    let padded = batch(&graphs(Task::Forward)).unwrap();
    let mut no_dp = w.clone();
    no_dp.config.edge_attributes = EdgeAttributes {
        delta_p: false,
        ..EdgeAttributes::default()
    };
    let a = treemanip::nn::gnn::forward(w, &padded);
    let b = treemanip::nn::gnn::forward(&no_dp, &padded);
    let scale = a.vectors.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    let change = a
        .vectors
        .iter()
        .zip(&b.vectors)
        .fold(0.0f32, |m, (x, y)| m.max((x - y).abs()));
    assert!(change > 1e-3 * scale, "change {change} at scale {scale}");

    // Under branch connectivity, changing Δp on a non-branch pair changes
    // nothing downstream of the message passing... except that pair's own
    // edge embedding, which is never read. So outputs are identical.
    let mut branches = w.clone();
    branches.config.connectivity = Connectivity::Branches;
    let before = treemanip::nn::gnn::forward(&branches, &padded);
    let mut edited = padded.clone();
    let n = edited.n;
    // Nodes 0 and the last real node of graph 0 are not parent and child
    // in a 6-node tree whose last node hangs deeper than the root's children.
    let (i, j) = (0usize, 5usize);
    let k = (i * n + j) * 5;
    assert_eq!(edited.edges[k + 4], 0.0, "pick a non-branch pair");
    edited.edges[k] += 0.3;
    let after = treemanip::nn::gnn::forward(&branches, &edited);
    assert_eq!(before.vectors, after.vectors);
}

fn tiny_dataset(dir: &Path) {
    crate::common::tiny_dataset(dir, &[Split::Train]);
}

fn tiny_config(task: Task, arch: Arch, data: &Path, epochs: usize) -> TrainConfig {
    TrainConfig {
        sizes: vec![6, 8],
        epochs,
        batch_size: 16,
        layers: 2,
        hidden: 16,
        seed: 9,
        ..TrainConfig::paper(task, arch, data.to_path_buf())
    }
}

#[test]
fn a_short_run_learns_and_the_best_weights_export() {
    let tmp = crate::common::temp_dir("train-learns");
    tiny_dataset(&tmp);
    for (task, arch, epochs) in [
        (Task::Forward, Arch::Gnn, 30),
        (Task::Policy, Arch::Gnn, 30),
        (Task::Forward, Arch::PointNet, 15),
    ] {
        let out = tmp.join(format!("{}-{}", task.name(), arch.name()));
        let mut steps = 0;
        let (state, reason) = train(
            tiny_config(task, arch, &tmp, epochs),
            &out,
            None,
            &mut |e| {
                if let treemanip::nn::train::TrainEvent::Step { loss } = e {
                    assert!(loss.is_finite());
                    steps += 1;
                }
            },
        )
        .unwrap();
        assert_eq!(reason, StopReason::Finished);
        assert!(steps > 0);
        let first = &state.history[0];
        let last = state.history.last().unwrap();
        eprintln!(
            "{task:?} {arch:?}: train loss {:.4} → {:.4}, validation {:.4} → {:.4}",
            first.train_loss, last.train_loss, first.validation_loss, last.validation_loss
        );
        let factor = if arch == Arch::Gnn { 0.5 } else { 0.8 };
        assert!(
            last.train_loss < factor * first.train_loss,
            "{task:?} {arch:?}: loss {} → {}",
            first.train_loss,
            last.train_loss
        );
        // The best weights are a model of the right kind that runs.
        let best = read_best(&out).unwrap();
        assert_eq!((best.task(), best.arch()), (task, arch));
        let padded = batch(&graphs(task)).unwrap();
        let reference = best.forward(&padded);
        assert!(reference.vectors.iter().all(|v| v.is_finite()));
        // JSON round trip of the weights is exact.
        let text = serde_json::to_string(&best).unwrap();
        let back: ModelWeights = serde_json::from_str(&text).unwrap();
        assert_eq!(back.forward(&padded), reference);
    }
}

#[test]
fn resuming_a_checkpoint_continues_exactly() {
    let tmp = crate::common::temp_dir("train-resume");
    tiny_dataset(&tmp);
    let straight = tmp.join("straight");
    let config = |epochs| TrainConfig {
        limit_per_size: Some(96),
        ..tiny_config(Task::Forward, Arch::Gnn, &tmp, epochs)
    };
    train(config(3), &straight, None, &mut |_| {}).unwrap();

    // Stopped by a deadline before the first step, resumed; stopped again
    // somewhere in the middle (wherever 0.3 s ends), resumed to the end of
    // the stored plan (cosine schedule and rotation angles included).
    let split = tmp.join("split");
    let (state, reason) = train(
        config(3),
        &split,
        Some(std::time::Instant::now()),
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(reason, StopReason::TimeBudget);
    assert_eq!((state.epoch, state.batch), (0, 0));
    let err = train(config(3), &split, None, &mut |_| {}).unwrap_err();
    assert!(err.to_string().contains("--resume"), "{err}");
    let again = || ResumeOptions {
        command: "resume".into(),
        ..ResumeOptions::default()
    };
    let soon = std::time::Instant::now() + std::time::Duration::from_millis(300);
    resume(&split, again(), Some(soon), &mut |_| {}).unwrap();
    let (state, reason) = resume(&split, again(), None, &mut |_| {}).unwrap();
    assert_eq!(reason, StopReason::Finished);
    assert_eq!(state.epoch, 3);
    assert_eq!(state.commands.len(), 3);

    let (a, b) = (
        current_weights(&straight).unwrap(),
        current_weights(&split).unwrap(),
    );
    let padded = batch(&graphs(Task::Forward)).unwrap();
    let (ya, yb) = (a.forward(&padded), b.forward(&padded));
    for (x, y) in ya.vectors.iter().zip(&yb.vectors) {
        assert!((x - y).abs() < 1e-6, "{x} vs {y}");
    }
    let (sa, sb) = (read_state(&straight).unwrap(), read_state(&split).unwrap());
    assert_eq!(sa.samples, sb.samples);
    for (ra, rb) in sa.history.iter().zip(&sb.history) {
        assert!((ra.validation_loss - rb.validation_loss).abs() < 1e-6);
    }
}

/// Targets for `graphs(task)` padded to `n`: made-up displacements, the
/// last real node contacted, a made-up push.
/// A small branch-connectivity GNN (trained on an edge list).
fn branches_model(task: Task) -> ModelWeights {
    random_model(
        task,
        Arch::Gnn,
        Some(GnnConfig {
            hidden: 8,
            layers: 3,
            edge_attributes: "dp+ks".parse().unwrap(),
            connectivity: Connectivity::Branches,
            ..GnnConfig::paper(task)
        }),
    )
}

fn made_up_targets(padded: &Batch) -> Targets {
    let (b, n) = (padded.batch, padded.n);
    Targets {
        displacement: (0..b * n * 3)
            .map(|k| ((k % 7) as f32 - 3.0) * 0.01)
            .collect(),
        contact: (0..b)
            .map(|g| {
                padded.mask[g * n..(g + 1) * n]
                    .iter()
                    .filter(|&&m| m > 0.0)
                    .count()
                    - 1
            })
            .collect(),
        push: (0..b * 3).map(|k| ((k % 5) as f32 - 2.0) * 0.02).collect(),
        weight: padded.mask.clone(),
    }
}

/// Training cuts each batch into one shard per core. The step must be the
/// whole batch's step: the three graphs have 6, 9 and 14 real nodes, so
/// shards weighted equally instead of by their share of the loss would
/// move the outputs differently.
#[test]
fn sharded_steps_equal_the_whole_batch_step() {
    for task in [Task::Forward, Task::Policy] {
        for model in [
            random_model(task, Arch::Gnn, None),
            random_model(task, Arch::PointNet, None),
            branches_model(task),
        ] {
            let padded = batch(&graphs(task)).unwrap();
            let targets = made_up_targets(&padded);
            let before = model.forward(&padded).vectors;
            let layout = EdgeLayout::of(&model);
            let (loss_whole, whole) = descend(&model, &padded, &targets, (1, layout), 0.05);
            let moved = whole.forward(&padded).vectors;
            let largest = before
                .iter()
                .zip(&moved)
                .fold(0f32, |m, (a, b)| m.max((a - b).abs()));
            assert!(
                largest > 1e-3,
                "{}: the step moves the outputs",
                model.describe()
            );
            for count in [2, 3, 7] {
                let (loss, sharded) = descend(&model, &padded, &targets, (count, layout), 0.05);
                assert!(
                    (loss - loss_whole).abs() <= 1e-5 * loss_whole.abs(),
                    "{} in {count} shards: loss {loss} vs {loss_whole}",
                    model.describe()
                );
                let out = sharded.forward(&padded).vectors;
                for (k, (a, b)) in moved.iter().zip(&out).enumerate() {
                    assert!(
                        (a - b).abs() <= 1e-3 * largest,
                        "{} in {count} shards: output {k}: {a} vs {b}",
                        model.describe()
                    );
                }
            }
        }
    }
}

/// Branch-connectivity models train on a list of the parent–child pairs
/// instead of the masked N × N pairs; the step (loss and gradients) must
/// be the same.
#[test]
fn edge_list_steps_equal_the_dense_step() {
    for task in [Task::Forward, Task::Policy] {
        let model = branches_model(task);
        assert_eq!(EdgeLayout::of(&model), EdgeLayout::List);
        let padded = batch(&graphs(task)).unwrap();
        let targets = made_up_targets(&padded);
        let before = model.forward(&padded).vectors;
        let (loss_dense, dense) = descend(&model, &padded, &targets, (2, EdgeLayout::Dense), 0.05);
        let (loss_list, list) = descend(&model, &padded, &targets, (2, EdgeLayout::List), 0.05);
        assert!(
            (loss_list - loss_dense).abs() <= 1e-5 * loss_dense.abs(),
            "{task:?}: loss {loss_list} vs {loss_dense}"
        );
        let (a, b) = (
            dense.forward(&padded).vectors,
            list.forward(&padded).vectors,
        );
        let moved = before
            .iter()
            .zip(&a)
            .fold(0f32, |m, (x, y)| m.max((x - y).abs()));
        assert!(moved > 1e-3, "{task:?}: the step moves the outputs");
        for (k, (x, y)) in a.iter().zip(&b).enumerate() {
            assert!(
                (x - y).abs() <= 1e-3 * moved,
                "{task:?}: output {k}: {x} (dense) vs {y} (list)"
            );
        }
    }
}

/// `--init-from`: the new run starts from the source's best weights, with
/// the source's normalisation where the features are shared, and its own
/// edge attributes (an ablation that drops κ must not see it).
#[test]
fn a_run_started_from_another_keeps_its_weights_and_takes_its_own_attributes() {
    let tmp = crate::common::temp_dir("train-init-from");
    tiny_dataset(&tmp);
    let source = tmp.join("source");
    train(
        tiny_config(Task::Forward, Arch::Gnn, &tmp, 2),
        &source,
        None,
        &mut |_| {},
    )
    .unwrap();
    let best = treemanip::nn::train::read_best(&source).unwrap();
    let mut config = tiny_config(Task::Forward, Arch::Gnn, &tmp, 1);
    config.init_from = Some(source.clone());
    config.edge_attributes = "dp+v".parse().unwrap();
    let examples = treemanip::nn::train::data::Examples::load(
        &tmp,
        &config.sizes,
        None,
        treemanip::graph::path::Encoding::Full,
    )
    .unwrap();
    let norm = treemanip::nn::train::Normalisation::of(&examples, &config).unwrap();
    let state = read_state(&source).unwrap();
    assert_eq!(
        norm, state.normalisation,
        "same layout: the source's statistics"
    );
    let start = treemanip::nn::train::checkpoint::initial_weights(&config, &norm).unwrap();
    let (ModelWeights::Gnn(start), ModelWeights::Gnn(best)) = (start, best) else {
        panic!("GNN weights expected")
    };
    assert_eq!(start.edge_encoder, best.edge_encoder);
    assert_eq!(start.blocks, best.blocks);
    assert!(
        !start.config.edge_attributes.stiffness,
        "the run's own attributes"
    );
    assert!(best.config.edge_attributes.stiffness);
}

/// `--turn-weight`: a path rotation model's loss weighs each path
/// branch's squared turn error by its reach (or radius) squared over the
/// mean square in training, and nothing else: the root's and the side
/// nodes' rows (never read by the decoder) and the padding weigh 0; a
/// uniform weight is the mask. A run with it trains.
#[test]
fn turn_weights_square_each_path_branchs_reach_over_its_mean() {
    use treemanip::graph::path::{Encoding, encode_forward_path};
    use treemanip::nn::train::TurnWeight;
    use treemanip::nn::train::data::Examples;
    let tmp = crate::common::temp_dir("train-turn-weight");
    tiny_dataset(&tmp);
    let mut examples = Examples::load(&tmp, &[6, 8], None, Encoding::PathRotation).unwrap();
    let ids: Vec<(usize, usize)> = examples.train.iter().step_by(10).copied().collect();
    let (plain, uniform) = examples.batch(Task::Forward, &ids);
    assert_eq!(uniform.weight, plain.mask);
    for kind in [TurnWeight::Reach, TurnWeight::Radius] {
        examples.weigh_turns(kind);
        let (padded, targets) = examples.batch(Task::Forward, &ids);
        let n = padded.n;
        let (mut sum, mut rows) = (0.0f64, 0usize);
        for (g, &id) in ids.iter().enumerate() {
            let data = &examples.sizes[id.0];
            let episode = &data.episodes[id.1];
            let tree = data.tree_of(episode);
            let graph = encode_forward_path(tree, episode.push.node, &episode.push.vector).unwrap();
            let reach = graph.turn_reach(tree);
            let w = &targets.weight[g * n..(g + 1) * n];
            assert_eq!(w[0], 0.0, "the root's row");
            assert!(
                w[graph.path_len..].iter().all(|&v| v == 0.0),
                "side nodes and padding"
            );
            for k in 1..graph.path_len {
                assert!(w[k] > 0.0);
                sum += w[k] as f64;
                rows += 1;
                if kind == TurnWeight::Reach {
                    // Rows weigh in proportion to their reach squared.
                    let ratio = w[k] as f64 / (reach[k] * reach[k]);
                    let first = w[1] as f64 / (reach[1] * reach[1]);
                    assert!((ratio / first - 1.0).abs() < 1e-4, "{kind:?} row {k}");
                }
            }
        }
        // The scale is the mean square over these very rows.
        assert!(
            (sum / rows as f64 - 1.0).abs() < 1e-4,
            "{kind:?}: {}",
            sum / rows as f64
        );
    }
    let mut config = tiny_config(Task::Forward, Arch::Gnn, &tmp, 2);
    config.encoding = Encoding::PathRotation;
    config.turn_weight = TurnWeight::Reach;
    let (state, reason) = train(config, &tmp.join("reach"), None, &mut |_| {}).unwrap();
    assert_eq!(reason, StopReason::Finished);
    assert!(
        state
            .history
            .iter()
            .all(|e| e.train_loss.is_finite() && e.validation_error.is_finite())
    );
    assert_eq!(
        read_state(&tmp.join("reach")).unwrap().config.turn_weight,
        TurnWeight::Reach
    );
}
