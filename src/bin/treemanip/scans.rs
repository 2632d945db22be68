//! `treemanip trees scan` (a synthetic scan of a tree) and `treemanip trees
//! from-points` (a tree from a point cloud file).

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use treemanip::api::types::{FromPointsQuery, FromPointsResponse};
use treemanip::scan::io::{self, ply};
use treemanip::scan::skeleton::cloud_svg;
use treemanip::scan::{ExtractParams, ScanParams, Skeleton, extract, scan};

#[derive(Args)]
pub struct ScanArgs {
    /// A tree URDF file (as `trees generate` writes them).
    tree: PathBuf,
    /// Where to write the cloud (binary PLY).
    #[arg(long)]
    out: PathBuf,
    /// Viewpoints around the tree (1-16).
    #[arg(long, default_value_t = 3)]
    views: usize,
    /// Horizontal range from the trunk to each viewpoint (m).
    #[arg(long, default_value_t = 1.5)]
    distance: f64,
    /// Depth noise σ at that range (m); it grows with the square of range.
    #[arg(long, default_value_t = 0.002)]
    noise: f64,
    /// Surface samples per viewpoint before occlusion.
    #[arg(long, default_value_t = 40_000)]
    samples: usize,
    /// Leaves (5 cm discs) per twig.
    #[arg(long, default_value_t = 0)]
    leaves: usize,
    /// Fruit (7 cm spheres) beside the branches.
    #[arg(long, default_value_t = 0)]
    fruit: usize,
    /// Share of outliers among the points (0-0.5).
    #[arg(long, default_value_t = 0.0)]
    outliers: f64,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Also draw the cloud and the tree as SVG here.
    #[arg(long)]
    svg: Option<PathBuf>,
}

pub fn scan_cmd(args: ScanArgs) -> anyhow::Result<()> {
    let tree = treemanip::tree::urdf::read_file(&args.tree)
        .with_context(|| format!("cannot read {}", args.tree.display()))?;
    let params = ScanParams {
        viewpoints: args.views,
        distance: args.distance,
        noise: args.noise,
        samples_per_view: args.samples,
        leaves_per_twig: args.leaves,
        fruit: args.fruit,
        outliers: args.outliers,
        seed: args.seed,
    };
    let scan = scan(&tree, &params).map_err(anyhow::Error::msg)?;
    let mut file = std::io::BufWriter::new(
        std::fs::File::create(&args.out)
            .with_context(|| format!("cannot create {}", args.out.display()))?,
    );
    ply::write(&scan.cloud, &mut file)?;
    println!(
        "{} points from {} viewpoints written to {}",
        scan.cloud.len(),
        scan.viewpoints.len(),
        args.out.display()
    );
    // What `trees from-points` is told of where the scanner stood.
    println!(
        "viewpoints: {}",
        scan.viewpoints
            .iter()
            .map(|v| format!("--viewpoint={:.4},{:.4},{:.4}", v.x, v.y, v.z))
            .collect::<Vec<_>>()
            .join(" ")
    );
    if let Some(svg) = args.svg {
        let truth = Skeleton::of_tree(&tree);
        let title = format!("{}: {} points", args.tree.display(), scan.cloud.len());
        std::fs::write(&svg, cloud_svg(&scan.cloud.points, &truth, None, &title))?;
    }
    Ok(())
}

#[derive(Args)]
pub struct FromPointsArgs {
    /// A point cloud: .ply, .pcd, .las, .laz or .xyz.
    file: PathBuf,
    /// Where to write the tree (JSON, as `POST /v1/trees/from-points`
    /// answers); standard output if absent.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Also draw the cloud and the tree as SVG here.
    #[arg(long)]
    svg: Option<PathBuf>,
    /// Largest distance between joints along a branch (m).
    #[arg(long, default_value_t = treemanip::scan::extract::DEFAULT_SPACING)]
    spacing: f64,
    /// The trunk's base, `x,y,z` (m).
    #[arg(long, allow_hyphen_values = true)]
    root: Option<String>,
    /// Which way is up, `x,y,z` (default `0,0,1`).
    #[arg(long, allow_hyphen_values = true)]
    up: Option<String>,
    /// Only points in this box: `min_x,min_y,min_z,max_x,max_y,max_z` (m).
    #[arg(long, allow_hyphen_values = true)]
    crop: Option<String>,
    /// Largest cloud read (points).
    #[arg(long, default_value_t = treemanip::scan::extract::DEFAULT_MAX_POINTS)]
    max_points: usize,
    /// How leaves are found: `auto` (by colour when the file has colours,
    /// else by shape when the cloud looks leafy), `shape` or `off`.
    #[arg(long, default_value = "auto")]
    foliage: String,
    /// What made the cloud: `unknown`; `camera` (returns on the surface
    /// facing it: a one-sided cloud's axes are moved back from the near
    /// surface; not for a laser scanner whose beam is wider than the
    /// twigs); or `laser` with its `--beam-radius` (a one-sided cloud's
    /// radii and axes from the silhouettes less the beam's spread).
    #[arg(long, default_value = "unknown")]
    sensor: String,
    /// With `--sensor laser`: how far past a branch's edge its pulse still
    /// returns (m): about half the beam's footprint at the tree.
    #[arg(long)]
    beam_radius: Option<f64>,
    /// Where the sensor stood, `x,y,z` (m), once per view (`0,0,0` for a
    /// camera's own cloud, in its frame): gaps hidden behind what it saw
    /// are then bridged as gaps under leaves are.
    #[arg(long = "viewpoint", allow_hyphen_values = true)]
    viewpoints: Vec<String>,
    /// Also the viewpoint the file records (PCD's `VIEWPOINT`): only when
    /// it is where the sensor stood in the points' frame (a cloud moved
    /// into a world frame often keeps the default `0 0 0`; one among the
    /// points is refused).
    #[arg(long)]
    viewpoint_from_file: bool,
}

pub fn from_points_cmd(args: FromPointsArgs) -> anyhow::Result<()> {
    let start = std::time::Instant::now();
    let cloud = io::read_path(&args.file, args.max_points)?;
    let mut viewpoints = args.viewpoints;
    if args.viewpoint_from_file {
        let v = io::recorded_viewpoint(&args.file)?.ok_or_else(|| {
            anyhow::anyhow!(
                "{} records no viewpoint (only PCD files do); give --viewpoint x,y,z",
                args.file.display()
            )
        })?;
        viewpoints.push(format!("{},{},{}", v.x, v.y, v.z));
    }
    let read = start.elapsed();
    // The options as the endpoint's query reads them: one parser.
    let query = FromPointsQuery {
        root: args.root,
        up: args.up,
        spacing: Some(args.spacing),
        crop: args.crop,
        foliage: Some(
            serde_json::from_value(serde_json::Value::String(args.foliage.clone())).map_err(
                |_| anyhow::anyhow!("--foliage must be auto, shape or off, not {}", args.foliage),
            )?,
        ),
        sensor: Some(
            serde_json::from_value(serde_json::Value::String(args.sensor.clone())).map_err(
                |_| {
                    anyhow::anyhow!(
                        "--sensor must be unknown, camera or laser, not {}",
                        args.sensor
                    )
                },
            )?,
        ),
        beam_radius: args.beam_radius,
        viewpoints: (!viewpoints.is_empty()).then(|| viewpoints.join(",")),
    };
    let params = ExtractParams {
        max_points: args.max_points,
        ..query.params().map_err(|e| anyhow::anyhow!(e.message))?
    };
    let extraction = extract(&cloud, &params)?;
    eprintln!(
        "{} points read in {:.2} s; a tree of {} nodes from {} of them in {:.2} s",
        cloud.len(),
        read.as_secs_f64(),
        extraction.skeleton.len(),
        extraction.points_used,
        (start.elapsed() - read).as_secs_f64()
    );
    for w in &extraction.warnings {
        eprintln!("warning: {w}");
    }
    let answer = FromPointsResponse::from_extraction(&extraction, treemanip::tree::MAX_NODES);
    let json = serde_json::to_string_pretty(&answer)?;
    match &args.out {
        Some(path) => std::fs::write(path, json)
            .with_context(|| format!("cannot write {}", path.display()))?,
        None => println!("{json}"),
    }
    if let Some(svg) = args.svg {
        let title = format!(
            "{}: {} points, {} nodes",
            args.file.display(),
            cloud.len(),
            extraction.skeleton.len()
        );
        std::fs::write(
            &svg,
            cloud_svg(&cloud.points, &extraction.skeleton, None, &title),
        )?;
    }
    Ok(())
}
