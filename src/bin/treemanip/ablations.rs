//! `treemanip eval ablations`: the paper's Table I, trained and scored
//! under one budget ([`treemanip::eval::ablations`]).

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::Context;
use clap::Args;
use treemanip::eval::ablations::{
    StudyConfig, StudyEvent, run_study, to_csv, to_markdown, write_figure,
};
use treemanip::graph::Task;
use treemanip::nn::model::Arch;
use treemanip::nn::train::{TrainConfig, TrainEvent};

use crate::progress;
use crate::trees::{NodeSizes, parse_sizes};

#[derive(Args)]
pub struct EvalAblationsArgs {
    /// Dataset directory with `train_N<n>.npz` and `test_N<n>.npz` (`<n>`
    /// the tree size).
    #[arg(long)]
    data: PathBuf,
    /// Checkpoints of the runs (committed: the chosen weights of finished
    /// runs, the resumable state of the one in progress).
    #[arg(long, default_value = "training/ablations")]
    runs: PathBuf,
    /// Where ablations.{md,csv,svg} go.
    #[arg(long, default_value = "docs/results")]
    out: PathBuf,
    /// Epochs of every run (the equal budget; see docs/learning.md for why
    /// 5 fits the study into about 8 hours on 2 cores).
    #[arg(long, default_value_t = 5)]
    epochs: usize,
    /// Wall-clock budget of this invocation: stops with a resumable
    /// checkpoint; run the same command again to go on.
    #[arg(long)]
    minutes: Option<f64>,
    /// Use at most this many training episodes per size.
    #[arg(long)]
    limit_per_size: Option<usize>,
    /// Training tree sizes (the paper: 11,13,15,17,19).
    #[arg(long, value_parser = parse_sizes, default_value = "11,13,15,17,19")]
    sizes: NodeSizes,
    /// Test sizes scored.
    #[arg(long, value_parser = parse_sizes, default_value = "10..=30")]
    test_sizes: NodeSizes,
    /// Test episodes per size.
    #[arg(long, default_value_t = 1000)]
    per_size: usize,
    /// GNN embedding width of every variant.
    #[arg(long, default_value_t = 128)]
    hidden: usize,
    #[arg(long, default_value_t = 128)]
    batch_size: usize,
    /// Seed of the first pass (the seed check uses the next one).
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

pub fn eval_ablations(args: EvalAblationsArgs) -> anyhow::Result<()> {
    anyhow::ensure!(args.epochs > 0, "--epochs must be positive");
    treemanip::nn::train::keep_freed_pages();
    let mut template = TrainConfig::paper(Task::Forward, Arch::Gnn, args.data.clone());
    template.epochs = args.epochs;
    template.sizes = args.sizes.0.clone();
    template.limit_per_size = args.limit_per_size;
    template.hidden = args.hidden;
    template.batch_size = args.batch_size;
    template.seed = args.seed;
    template.command = std::env::args().collect::<Vec<_>>().join(" ");
    let config = StudyConfig {
        template,
        dir: args.runs.clone(),
        test_sizes: args.test_sizes.0.clone(),
        per_size: args.per_size,
        eval_batch: 32,
    };
    let deadline = args
        .minutes
        .map(|m| Instant::now() + Duration::from_secs_f64(m.max(0.0) * 60.0));
    let mut bar = progress::bar(0, "batches");
    let mut prefix = String::new();
    let mut on_event = |event: StudyEvent| match event {
        StudyEvent::RunStart { run, index, total } => {
            prefix = format!(
                "run {}/{total} {} seed {}",
                index + 1,
                run.variant.key,
                run.seed
            );
            eprintln!("{prefix}: {}", run.variant.label());
        }
        StudyEvent::Train(TrainEvent::EpochStart {
            epoch,
            batches,
            done,
        }) => {
            bar = progress::bar(batches as u64, "batches");
            bar.set_prefix(format!("{prefix} epoch {epoch}"));
            bar.set_position(done as u64);
        }
        StudyEvent::Train(TrainEvent::Step { loss }) => {
            bar.inc(1);
            bar.set_message(format!("loss {loss:.4}"));
        }
        StudyEvent::Train(TrainEvent::EpochEnd(r)) => {
            bar.finish_and_clear();
            eprintln!(
                "  epoch {:>2}: validation error {:.2} cm ({:.0} samples/s)",
                r.epoch,
                100.0 * r.validation_error,
                r.samples_per_second
            );
        }
        StudyEvent::Evaluated(r) => {
            let cm = |x: Option<f64>| x.map_or("–".to_owned(), |x| format!("{:.2}", 100.0 * x));
            eprintln!(
                "  test e_N {:.2} cm (trained sizes {}, zero-shot {})",
                100.0 * r.mean,
                cm(r.mean_trained),
                cm(r.mean_zero_shot)
            )
        }
    };
    let status = run_study(&config, deadline, &mut on_event)?;
    bar.finish_and_clear();
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let markdown = format!(
        "# Ablations (the paper's Table I)\n\nRegenerate: `{}`\n\n{}\n![Table I: ours beside the paper's](ablations.svg)\n",
        regenerate_command(&config.template.command),
        to_markdown(&status, args.seed)
    );
    std::fs::write(args.out.join("ablations.md"), &markdown)?;
    std::fs::write(args.out.join("ablations.csv"), to_csv(&status))?;
    write_figure(&status, args.seed, &args.out.join("ablations.svg"))
        .map_err(|e| anyhow::anyhow!("drawing the figure: {e}"))?;
    print!("{}", to_markdown(&status, args.seed));
    if status.remaining.is_empty() {
        eprintln!(
            "the study is complete; wrote {}/ablations.{{md,csv,svg}}",
            args.out.display()
        );
    } else {
        eprintln!(
            "{} runs to go; run the same command again to continue (wrote the partial table to {}/ablations.md)",
            status.remaining.len(),
            args.out.display()
        );
    }
    Ok(())
}

/// The study's command as the table shows it: the binary as `treemanip`
/// and without this invocation's `--minutes` (a session's share, not part
/// of the study).
fn regenerate_command(command: &str) -> String {
    let mut words = command.split_whitespace();
    let mut out = vec!["treemanip".to_owned()];
    words.next();
    while let Some(word) = words.next() {
        if word == "--minutes" {
            words.next();
        } else if !word.starts_with("--minutes=") {
            out.push(word.to_owned());
        }
    }
    out.join(" ")
}

#[cfg(test)]
mod tests {
    use super::regenerate_command;

    #[test]
    fn the_shown_command_drops_the_session_budget() {
        assert_eq!(
            regenerate_command(
                "target/release/treemanip eval ablations --data data --minutes 150 --epochs 5"
            ),
            "treemanip eval ablations --data data --epochs 5"
        );
        assert_eq!(
            regenerate_command("./treemanip eval ablations --minutes=30 --data d"),
            "treemanip eval ablations --data d"
        );
    }
}
