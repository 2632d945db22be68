//! `treemanip`: the offline tool. Generates trees, (later) simulates pushes,
//! collects data, trains, exports and evaluates models.

mod args;
mod dataset;
mod plan;
mod progress;
mod sim;
mod trees;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "treemanip", version, about = "Offline tools for learning robotic tree manipulation", long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Generate, inspect and draw trees (Space Colonization Algorithm, URDF).
    #[command(subcommand)]
    Trees(trees::TreesCommand),
    /// Simulate pushes on a tree (quasi-static spring-joint model).
    #[command(subcommand)]
    Sim(sim::SimCommand),
    /// Collect and inspect push-episode datasets (.npz).
    #[command(subcommand)]
    Dataset(dataset::DatasetCommand),
    /// Plan the UR5's motion for a push (the paper's Algorithm 1).
    Plan(plan::PlanArgs),
    /// Evaluate components the way the paper does.
    #[command(subcommand)]
    Eval(EvalCommand),
}

#[derive(Subcommand)]
enum EvalCommand {
    /// Algorithm 1 on test episodes of every size: success rate, planned
    /// rank histogram (the paper's Fig. 10), planning times.
    Plan(plan::EvalPlanArgs),
}

fn main() -> std::process::ExitCode {
    let result = match Cli::parse().command {
        Command::Trees(cmd) => trees::run(cmd),
        Command::Sim(cmd) => sim::run(cmd),
        Command::Dataset(cmd) => dataset::run(cmd),
        Command::Plan(args) => plan::plan(args),
        Command::Eval(EvalCommand::Plan(args)) => plan::eval_plan(args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        // A closed pipe (`treemanip trees show … | head`) is not a failure.
        Err(e) if is_broken_pipe(&e) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|cause| {
        cause
            .downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}
