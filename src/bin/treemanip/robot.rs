//! `treemanip robot`: inspect an arm's URDF.

use std::path::PathBuf;

use anyhow::Context;
use clap::{Args, Subcommand};
use treemanip::robot::link_geometry::{LinkShape, link_geometry_of_file, package_path_from_env};

#[derive(Subcommand)]
pub enum RobotCommand {
    /// Each link's collision shapes as the planner will use them: URDF
    /// primitives as they are, meshes replaced by the capsules that enclose
    /// them, with how snugly (capsule volume over the mesh's convex hull).
    Shapes(ShapesArgs),
}

#[derive(Args)]
pub struct ShapesArgs {
    /// The URDF.
    urdf: PathBuf,
    /// Directories that contain package folders, for `package://` meshes
    /// (before `TREEMANIP_PACKAGE_PATH` and the URDF's own ancestors).
    #[arg(long = "package-path", value_delimiter = ':')]
    package_path: Vec<PathBuf>,
}

pub fn run(command: RobotCommand) -> anyhow::Result<()> {
    match command {
        RobotCommand::Shapes(args) => shapes(args),
    }
}

fn shapes(args: ShapesArgs) -> anyhow::Result<()> {
    let mut packages = args.package_path.clone();
    packages.extend(package_path_from_env());
    let links = link_geometry_of_file(&args.urdf, &packages)
        .with_context(|| format!("collision geometry of {}", args.urdf.display()))?;
    println!(
        "link                 shapes                              meshes (triangles, capsules, volume / hull)"
    );
    for link in &links {
        let mut kinds: Vec<String> = Vec::new();
        for s in &link.shapes {
            kinds.push(match s {
                LinkShape::Box { half_extents, .. } => format!(
                    "box {:.3}×{:.3}×{:.3}",
                    2.0 * half_extents.x,
                    2.0 * half_extents.y,
                    2.0 * half_extents.z
                ),
                LinkShape::Cylinder {
                    radius,
                    half_length,
                    ..
                } => format!("cylinder r {radius:.3} l {:.3}", 2.0 * half_length),
                LinkShape::Sphere { radius, .. } => format!("sphere r {radius:.3}"),
                LinkShape::Capsule(c) => format!("capsule r {:.3} l {:.3}", c.radius, c.height()),
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
    Ok(())
}
