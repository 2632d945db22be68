//! `eval ablations` (the paper's Table I) on a tiny dataset: every variant
//! trained under the same budget, scored, reported; the two closest run
//! again with a second seed; finished runs keep only their chosen weights.

use std::time::Instant;

use treemanip::dataset::Split;
use treemanip::eval::ablations::{
    StudyConfig, run_study, seed_check, status, table_i, to_csv, to_markdown, write_figure,
};
use treemanip::graph::Task;
use treemanip::nn::model::Arch;
use treemanip::nn::train::TrainConfig;

#[test]
fn the_study_trains_every_variant_under_one_budget_and_checks_the_closest_pair() {
    let tmp = crate::common::temp_dir("ablations");
    crate::common::tiny_dataset(&tmp, &[Split::Train, Split::Test]);
    let config = StudyConfig {
        template: TrainConfig {
            sizes: vec![6],
            epochs: 2,
            batch_size: 32,
            hidden: 8,
            seed: 4,
            ..TrainConfig::paper(Task::Forward, Arch::Gnn, tmp.clone())
        },
        dir: tmp.join("runs"),
        test_sizes: vec![6, 8],
        per_size: 40,
        eval_batch: 16,
    };
    // A deadline already passed: nothing trains, the plan is the 9 variants.
    let before = run_study(&config, Some(Instant::now()), &mut |_| {}).unwrap();
    assert!(before.results.is_empty());
    assert_eq!(before.remaining.len(), table_i().len());
    assert_eq!(table_i().len(), 9);

    let mut evaluated = 0;
    let done = run_study(&config, None, &mut |e| {
        if let treemanip::eval::ablations::StudyEvent::Evaluated(_) = e {
            evaluated += 1;
        }
    })
    .unwrap();
    assert!(done.remaining.is_empty(), "{:?}", done.remaining);
    assert_eq!(done.results.len(), 11, "9 variants and 2 second-seed runs");
    assert_eq!(evaluated, 11);
    // The same budget for every run: epochs and samples seen.
    for r in &done.results {
        assert_eq!(
            (r.epochs, r.samples),
            (done.results[0].epochs, done.results[0].samples)
        );
        assert!(r.mean.is_finite() && r.mean > 0.0, "{r:?}");
        assert_eq!(
            r.per_size.iter().map(|p| p.0).collect::<Vec<_>>(),
            vec![6, 8]
        );
    }
    // The second seed went to the two closest first-seed variants.
    let pair = seed_check(&done.results, &table_i(), 4).unwrap();
    let second: Vec<&str> = done
        .results
        .iter()
        .filter(|r| r.seed == 5)
        .map(|r| r.key.as_str())
        .collect();
    assert_eq!(second.len(), 2);
    assert!(pair.iter().all(|k| second.contains(&k.as_str())));
    let first: Vec<f64> = done
        .results
        .iter()
        .filter(|r| r.seed == 4)
        .map(|r| r.mean)
        .collect();
    let gap = |k: &str| {
        done.results
            .iter()
            .find(|r| r.key == k && r.seed == 4)
            .unwrap()
            .mean
    };
    let closest = (gap(&pair[0]) - gap(&pair[1])).abs();
    for (i, a) in first.iter().enumerate() {
        for b in &first[i + 1..] {
            assert!((a - b).abs() >= closest);
        }
    }
    // Finished runs keep the chosen weights and the record, not the
    // resumable state.
    for r in &done.results {
        let dir = config.dir.join(format!("{}-seed{}", r.key, r.seed));
        for kept in ["best.bpk", "state.json", "result.json"] {
            assert!(dir.join(kept).exists(), "{} lacks {kept}", dir.display());
        }
        for dropped in ["model.bpk", "optimizer.bpk"] {
            assert!(
                !dir.join(dropped).exists(),
                "{} keeps {dropped}",
                dir.display()
            );
        }
    }
    // Nothing left: a second invocation trains nothing and reports the same.
    let again = status(&config);
    assert_eq!(again.results.len(), 11);
    let table = to_markdown(&done, 4);
    for v in table_i() {
        assert!(table.contains(&v.label()), "{table}");
        assert!(table.contains(&format!("{:.1} |", v.paper_cm)), "{table}");
    }
    assert!(
        table.contains("Seed check") && !table.contains("pending"),
        "{table}"
    );
    // The budget in the caption: epochs and samples seen, as counted.
    let samples = indicatif::HumanCount(done.results[0].samples).to_string();
    assert!(
        table.contains(&format!("2 epochs, {samples} samples seen")),
        "{table}"
    );
    assert_eq!(
        table.matches(": holds\n").count() + table.matches(": does not hold\n").count(),
        3,
        "the paper's three orderings, each judged: {table}"
    );
    assert_eq!(to_csv(&done).lines().count(), 12);
    let svg = tmp.join("ablations.svg");
    write_figure(&done, 4, &svg).unwrap();
    assert!(std::fs::read_to_string(&svg).unwrap().contains("<svg"));
    // A run in progress under another budget is refused, not mixed in.
    let other = StudyConfig {
        dir: tmp.join("other"),
        ..config.clone()
    };
    let first = &status(&other).remaining[0];
    let started = TrainConfig {
        epochs: 3,
        edge_attributes: first.variant.edge_attributes,
        ..other.template.clone()
    };
    let (_, reason) = treemanip::nn::train::train(
        started,
        &first.dir(&other.dir),
        Some(Instant::now()),
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(reason, treemanip::nn::train::StopReason::TimeBudget);
    let refused = run_study(&other, None, &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(refused.contains("another budget"), "{refused}");
    let _ = std::fs::remove_dir_all(&tmp);
}
