//! `treemanip`: the offline tool. Generates trees, (later) simulates pushes,
//! collects data, trains, exports and evaluates models.

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
}

fn main() -> anyhow::Result<()> {
    match Cli::parse().command {
        Command::Trees(cmd) => trees::run(cmd),
    }
}
