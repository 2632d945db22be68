//! `treemanip sim …`

use anyhow::Context;
use clap::{Args, Subcommand};
use serde::Serialize;
use treemanip::sim::{ContactModel, Push, SimConfig, SolverReport, simulate};

use treemanip::api::types::TreeJson;

use crate::args::TreePush;

#[derive(Subcommand)]
pub enum SimCommand {
    /// Push one node of a tree and print where the tree settles.
    Push(PushArgs),
}

#[derive(Args)]
pub struct PushArgs {
    #[command(flatten)]
    target: TreePush,
    /// Contact model: `slot` (the branch slides in the gripper's slot) or
    /// `pinned` (the node moves exactly by the push).
    #[arg(long, default_value = "slot")]
    contact: ContactModel,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    json: bool,
}

pub fn run(cmd: SimCommand) -> anyhow::Result<()> {
    match cmd {
        SimCommand::Push(args) => push(args),
    }
}

#[derive(Serialize)]
struct PushJson {
    /// The tree in the HTTP API's format (positions, parents, radius, stiffness).
    #[serde(flatten)]
    tree: TreeJson,
    contact_node: usize,
    push: [f64; 3],
    contact_model: ContactModel,
    final_positions: Vec<[f64; 3]>,
    joint_rotations: Vec<[f64; 3]>,
    solver: SolverReport,
}

fn push(args: PushArgs) -> anyhow::Result<()> {
    let tree = args.target.load_tree()?;
    let push = Push {
        node: args.target.node,
        vector: args.target.push,
    };
    let config = SimConfig {
        contact: args.contact,
        ..SimConfig::default()
    };
    let outcome = simulate(&tree, &push, &config).context("the push cannot be simulated")?;
    let xyz = |p: &nalgebra::Point3<f64>| [p.x, p.y, p.z];
    if args.json {
        let json = PushJson {
            tree: TreeJson::from_tree(&tree),
            contact_node: push.node,
            push: [push.vector.x, push.vector.y, push.vector.z],
            contact_model: args.contact,
            final_positions: outcome.final_positions.iter().map(xyz).collect(),
            joint_rotations: outcome
                .joint_rotations
                .iter()
                .map(|r| [r.x, r.y, r.z])
                .collect(),
            solver: outcome.report,
        };
        println!("{}", serde_json::to_string_pretty(&json)?);
        return Ok(());
    }
    let r = &outcome.report;
    println!(
        "push node {} by ({:.4}, {:.4}, {:.4}) m, {:?} contact: {} iterations, constraint residual {:.1e} m, KKT residual {:.1e}",
        push.node,
        push.vector.x,
        push.vector.y,
        push.vector.z,
        args.contact,
        r.iterations,
        r.constraint_residual,
        r.kkt_residual
    );
    println!(
        "energy {:.4} J, contact force ({:.2}, {:.2}, {:.2}) N, largest joint rotation {:.1}°, hold {:?}{}",
        r.energy,
        r.contact_force[0],
        r.contact_force[1],
        r.contact_force[2],
        r.max_joint_angle.to_degrees(),
        r.hold,
        r.slide
            .map_or(String::new(), |s| format!(" at {s:.4} m along the branch"))
    );
    println!(
        "\n  {:>4} {:>27} {:>27} {:>10}",
        "node", "initial (m)", "final (m)", "moved (m)"
    );
    for (j, (a, b)) in tree
        .positions()
        .iter()
        .zip(&outcome.final_positions)
        .enumerate()
    {
        println!(
            "  {j:>4} ({:>7.4}, {:>7.4}, {:>7.4}) ({:>7.4}, {:>7.4}, {:>7.4}) {:>10.4}",
            a.x,
            a.y,
            a.z,
            b.x,
            b.y,
            b.z,
            (b - a).norm()
        );
    }
    Ok(())
}
