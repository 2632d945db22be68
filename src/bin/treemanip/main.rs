//! `treemanip`: the offline tool. Generates trees, (later) simulates pushes,
//! collects data, trains, exports and evaluates models.

#[cfg(feature = "train")]
mod ablations;
mod args;
mod dataset;
mod identify;
#[cfg(feature = "train")]
mod identify_eval;
#[cfg(feature = "train")]
mod learn;
#[cfg(feature = "train")]
mod plan;
mod progress;
#[cfg(feature = "train")]
mod ranks;
mod robot;
mod scans;
#[cfg(feature = "train")]
mod scans_eval;
mod sim;
#[cfg(feature = "train")]
mod sizes_eval;
#[cfg(feature = "train")]
mod tasks;
mod trees;

use clap::{Parser, Subcommand};

/// mimalloc keeps freed pages for reuse: glibc malloc mmaps and zeroes every
/// large tensor of a training step afresh, a fifth of the step's time.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

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
    #[cfg(feature = "train")]
    /// Train a forward model or contact policy (GNN or PointNet) with burn.
    Train(learn::TrainArgs),
    #[cfg(feature = "train")]
    /// Write trained checkpoints as ONNX models with metadata.
    Export(learn::ExportArgs),
    #[cfg(feature = "train")]
    /// Train the scan's foliage classifier (leaves told from bark by shape,
    /// for clouds without colours) on synthetic scans; writes
    /// models/foliage.json, which the library embeds.
    TrainFoliage(learn::TrainFoliageArgs),
    #[cfg(feature = "train")]
    /// Record (or refresh) each model's domain in its metadata, computed from
    /// its training split; the weights are left as they are.
    Domain(learn::DomainArgs),
    #[cfg(feature = "train")]
    /// Plan the UR5's motion for a push (the paper's Algorithm 1).
    Plan(plan::PlanArgs),
    #[cfg(feature = "train")]
    /// Evaluate components the way the paper does.
    #[command(subcommand)]
    Eval(EvalCommand),
    /// Identify a tree's branch stiffness from observed probe pushes (as
    /// `POST /v1/identify` does).
    Identify(identify::IdentifyArgs),
    /// Run the HTTP service (the same as `treemanip-server`; the container
    /// image's entry point).
    Serve(treemanip::api::server::ServeArgs),
    /// Inspect an arm's URDF (collision shapes, fitted meshes).
    #[command(subcommand)]
    Robot(robot::RobotCommand),
}

#[cfg(feature = "train")]
#[derive(Subcommand)]
enum EvalCommand {
    /// Algorithm 1 on test episodes of every size: success rate, planned
    /// rank histogram (the paper's Fig. 10), planning times.
    Plan(plan::EvalPlanArgs),
    /// Every rank of the contact policy executed (arm ignored): error and
    /// affordance by rank (the paper's Fig. 8).
    Ranks(ranks::EvalRanksArgs),
    /// Forward models (GNN, PointNet, No Action) on the test split: e_N per
    /// tree size (the paper's Fig. 7, left).
    Forward(learn::EvalLearnedArgs),
    /// Contact policies executed in the simulator, with Greedy, Random and
    /// No Action: e_N per tree size (the paper's Fig. 7, right).
    Policy(learn::EvalLearnedArgs),
    /// The paper's Table I: every edge-attribute and connectivity variant
    /// of the forward GNN trained under one budget and scored on the test
    /// split (resumable across sessions).
    Ablations(ablations::EvalAblationsArgs),
    /// Stiffness identification on test trees with hidden perturbed
    /// stiffness: accuracy, interval coverage, held-out pushes, chosen
    /// against random probes.
    Identify(identify_eval::EvalIdentifyArgs),
    /// The forward model on perturbed-stiffness test trees, given the true
    /// and the radius formula's stiffness, and under a global factor.
    Stiffness(identify_eval::EvalStiffnessArgs),
    /// Orchard objectives (`clear` a fruit, `reach` a region, a masked
    /// `shape`) on test trees under load limits, per strategy, with the
    /// arm-free oracle; loads read from predictions against the simulator.
    Tasks(tasks::EvalTasksArgs),
    /// Trees from synthetic scans of test-split trees (1 and 3 viewpoints,
    /// 1-5 mm noise, with and without leaves) scored against the true
    /// trees, and `clear` tasks planned on the extracted tree carried out
    /// on the true one.
    Scans(scans_eval::EvalScansArgs),
    /// Forward models against the tree's size: e_N of each model and No
    /// Action on held-out SCA and orchard trees of 10-500 nodes, the
    /// models' time for one push and for 64, the simulator's per push.
    Sizes(sizes_eval::EvalSizesArgs),
}

fn main() -> std::process::ExitCode {
    let result = match Cli::parse().command {
        Command::Trees(cmd) => trees::run(cmd),
        Command::Sim(cmd) => sim::run(cmd),
        Command::Dataset(cmd) => dataset::run(cmd),
        #[cfg(feature = "train")]
        Command::Train(args) => learn::train_cmd(args),
        #[cfg(feature = "train")]
        Command::Export(args) => learn::export_cmd(args),
        #[cfg(feature = "train")]
        Command::TrainFoliage(args) => learn::train_foliage_cmd(args),
        #[cfg(feature = "train")]
        Command::Domain(args) => learn::domain_cmd(args),
        #[cfg(feature = "train")]
        Command::Plan(args) => plan::plan(args),
        Command::Serve(args) => treemanip::api::server::run(args),
        Command::Identify(args) => identify::identify_cmd(args),
        Command::Robot(cmd) => robot::run(cmd),
        #[cfg(feature = "train")]
        Command::Eval(EvalCommand::Identify(args)) => identify_eval::eval_identify(args),
        #[cfg(feature = "train")]
        Command::Eval(EvalCommand::Stiffness(args)) => identify_eval::eval_stiffness(args),
        #[cfg(feature = "train")]
        Command::Eval(EvalCommand::Plan(args)) => plan::eval_plan(args),
        #[cfg(feature = "train")]
        Command::Eval(EvalCommand::Scans(args)) => scans_eval::eval_scans(args),
        Command::Eval(EvalCommand::Sizes(args)) => sizes_eval::eval_sizes(args),
        #[cfg(feature = "train")]
        Command::Eval(EvalCommand::Tasks(args)) => tasks::eval_tasks(args),
        #[cfg(feature = "train")]
        Command::Eval(EvalCommand::Ranks(args)) => ranks::eval_ranks(args),
        #[cfg(feature = "train")]
        Command::Eval(EvalCommand::Forward(args)) => {
            learn::eval_learned(treemanip::graph::Task::Forward, args)
        }
        #[cfg(feature = "train")]
        Command::Eval(EvalCommand::Ablations(args)) => ablations::eval_ablations(args),
        #[cfg(feature = "train")]
        Command::Eval(EvalCommand::Policy(args)) => {
            learn::eval_learned(treemanip::graph::Task::Policy, args)
        }
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
