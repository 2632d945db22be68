//! `treemanip robot`: inspect an arm's URDF, import it, check it.

use std::path::PathBuf;

use anyhow::Context;
use clap::{Args, Subcommand};
use treemanip::geometry::shape::Shape;
use treemanip::robot::model::link_geometry::{link_geometry, package_path_from_env};
use treemanip::robot::model::self_pairs::{DisableReason, disabled_pairs};
use treemanip::robot::model::urdf_chain::{Chain, parse_urdf};

#[derive(Subcommand)]
pub enum RobotCommand {
    /// Each link's collision shapes as the planner will use them: URDF
    /// primitives as they are, meshes replaced by the capsules that enclose
    /// them, with how snugly (capsule volume over the mesh's convex hull).
    Shapes(ShapesArgs),
    /// Write a self-contained robot description (chain, limits, fitted
    /// collision shapes, self-collision pairs) from a robot configuration
    /// (TOML naming the URDF; see docs/robot.md): it loads without the
    /// URDF or its meshes.
    Import(ImportArgs),
    /// Check an arm before planning with it: its chain, tool frame, reach
    /// and limits, the share of random configurations free of
    /// self-collision (and the pairs that block the rest), IK on random
    /// reachable poses, and how many stance test pushes it carries out;
    /// exits 1 when it cannot plan at all.
    Check(CheckArgs),
}

#[derive(Args)]
pub struct CheckArgs {
    /// The arm, as `--robot` takes it: `ur5`, a shipped name (`panda`), a
    /// description or URDF path, or `NAME=PATH[,tip=LINK][,base=LINK]`.
    spec: String,
    /// Directories that contain package folders, for `package://` meshes.
    #[arg(long = "package-path", value_delimiter = ':')]
    package_path: Vec<PathBuf>,
    /// Random configurations sampled for self-collision.
    #[arg(long, default_value_t = treemanip::robot::check::SAMPLES)]
    samples: usize,
    /// Seed of the samples.
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

#[derive(Args)]
pub struct ImportArgs {
    /// The robot configuration (TOML).
    config: PathBuf,
    /// Where to write the description (e.g. robots/panda.toml).
    #[arg(long)]
    out: PathBuf,
    /// Directories that contain package folders, for `package://` meshes.
    #[arg(long = "package-path", value_delimiter = ':')]
    package_path: Vec<PathBuf>,
}

#[derive(Args)]
pub struct ShapesArgs {
    /// The URDF.
    urdf: PathBuf,
    /// Directories that contain package folders, for `package://` meshes
    /// (before `TREEMANIP_PACKAGE_PATH` and the URDF's own ancestors).
    #[arg(long = "package-path", value_delimiter = ':')]
    package_path: Vec<PathBuf>,
    /// First link of the planning chain (default: the URDF's root).
    #[arg(long)]
    base: Option<String>,
    /// Last link of the planning chain (default: the end of its only
    /// serial chain).
    #[arg(long)]
    tip: Option<String>,
    /// Random configurations sampled for the self-collision pairs that
    /// need no check (0: skip).
    #[arg(long, default_value_t = 1000)]
    samples: usize,
}

pub fn run(command: RobotCommand) -> anyhow::Result<()> {
    match command {
        RobotCommand::Shapes(args) => shapes(args),
        RobotCommand::Import(args) => import(args),
        RobotCommand::Check(args) => check(args),
    }
}

fn check(args: CheckArgs) -> anyhow::Result<()> {
    let packages = package_path(&args.package_path);
    use treemanip::robot::catalog;
    let arm = if args.spec == catalog::BUILT_IN {
        treemanip::robot::Arm::ur5(Default::default())
    } else {
        let spec = catalog::spec_of(&args.spec)?;
        let (arm, free) = catalog::load_as_described(&spec, &packages)
            .with_context(|| format!("loading {}", args.spec))?;
        if !free {
            println!(
                "warning: no collision-free home found at the default mount (the server refuses this arm): see the home and pairs below"
            );
        }
        arm
    };
    let report = treemanip::robot::check::check(&arm, args.samples, args.seed);
    print!("{report}");
    match report.fatal() {
        Some(why) => anyhow::bail!("{} cannot plan: {why}", report.name),
        None => Ok(()),
    }
}

/// The directories given, then `TREEMANIP_PACKAGE_PATH`'s.
fn package_path(given: &[PathBuf]) -> Vec<PathBuf> {
    let mut packages = given.to_vec();
    packages.extend(package_path_from_env());
    packages
}

fn import(args: ImportArgs) -> anyhow::Result<()> {
    let packages = package_path(&args.package_path);
    let command = format!(
        "treemanip robot import {} --out {}",
        args.config.display(),
        args.out.display()
    );
    let description =
        treemanip::robot::model::description::import(&args.config, &packages, &command)?;
    let text = description.to_toml().map_err(|e| anyhow::anyhow!(e))?;
    // What is written must load.
    treemanip::robot::model::description::RobotDescription::from_toml_str(&text, &args.out)?;
    if let Some(dir) = args.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)?;
    }
    let header = format!(
        "# {} ({} joints, {} → {}): written by `{command}`; do not edit, re-import.\n",
        description.name, description.dof, description.base_link, description.tip_link
    );
    std::fs::write(&args.out, header + &text)
        .with_context(|| format!("writing {}", args.out.display()))?;
    eprintln!(
        "wrote {}: {} joints, {} links with shapes, {} self-collision pairs unchecked",
        args.out.display(),
        description.dof,
        description.links.len(),
        description.disabled_pairs.len()
    );
    Ok(())
}

fn shapes(args: ShapesArgs) -> anyhow::Result<()> {
    let text = std::fs::read_to_string(&args.urdf)
        .with_context(|| format!("reading {}", args.urdf.display()))?;
    let robot = parse_urdf(&text).with_context(|| format!("{}", args.urdf.display()))?;
    let links = link_geometry(
        &robot,
        args.urdf.parent(),
        &package_path(&args.package_path),
    )
    .with_context(|| format!("collision geometry of {}", args.urdf.display()))?;
    println!(
        "link                 shapes                              meshes (triangles, capsules, volume / hull)"
    );
    for link in &links {
        let mut kinds: Vec<String> = Vec::new();
        for s in &link.shapes {
            kinds.push(match s {
                Shape::Box { half_extents, .. } => format!(
                    "box {:.3}×{:.3}×{:.3}",
                    2.0 * half_extents.x,
                    2.0 * half_extents.y,
                    2.0 * half_extents.z
                ),
                Shape::Cylinder {
                    radius,
                    half_length,
                    ..
                } => format!("cylinder r {radius:.3} l {:.3}", 2.0 * half_length),
                Shape::Sphere { radius, .. } => format!("sphere r {radius:.3}"),
                Shape::Capsule { a, b, radius } => {
                    format!("capsule r {radius:.3} l {:.3}", (b - a).norm())
                }
            });
        }
        let meshes: Vec<String> = link
            .meshes
            .iter()
            .map(|m| {
                format!(
                    "{} ({}, {}, {})",
                    m.file.file_name().map_or_else(
                        || m.file.display().to_string(),
                        |n| n.to_string_lossy().into_owned()
                    ),
                    m.triangles,
                    m.capsules,
                    m.volume_ratio
                        .map_or_else(|| "flat".to_owned(), |r| format!("{r:.2}"))
                )
            })
            .collect();
        println!(
            "{:<20} {:<35} {}",
            link.link,
            kinds.join(", "),
            meshes.join(", ")
        );
    }
    if args.samples > 0 {
        let chain = Chain::from_robot(&robot, args.base.as_deref(), args.tip.as_deref())?;
        let pairs = disabled_pairs(&robot, &chain, &links, args.samples, 0);
        println!(
            "\nself-collision pairs left unchecked ({} random configurations of the {}-joint chain {} → {}):",
            args.samples,
            chain.dof(),
            chain.base_link,
            chain.tip_link
        );
        for reason in [
            DisableReason::Adjacent,
            DisableReason::Never,
            DisableReason::Always,
        ] {
            let names: Vec<String> = pairs
                .iter()
                .filter(|p| p.reason == reason)
                .map(|p| format!("{}–{}", p.a, p.b))
                .collect();
            println!("{reason:?} ({}): {}", names.len(), names.join(", "));
        }
    }
    Ok(())
}
