//! `treemanip trees …`

use std::io::Write;
use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::{Args, Subcommand};
use rayon::prelude::*;
use serde::Serialize;
use treemanip::tree::collection::{TreeOrigin, TreeShape, tree_set};
use treemanip::tree::{self, ScaParams, Tree, render, urdf};

#[derive(Subcommand)]
pub enum TreesCommand {
    /// Grow trees with the Space Colonization Algorithm and write them as URDF
    /// files plus an index.json (file, N, seed, height).
    Generate(GenerateArgs),
    /// Print a summary of a tree URDF file.
    Show(ShowArgs),
    /// Draw a tree URDF file as SVG: front (x–z) and side (y–z) views.
    Render(RenderArgs),
    /// What a camera at K viewpoints would see of a tree: a point cloud
    /// (binary PLY) with occlusion, depth noise, optional leaves, fruit and
    /// outliers.
    Scan(crate::scans::ScanArgs),
    /// A tree from a point cloud file (PLY, PCD, LAS/LAZ, XYZ): the JSON
    /// `POST /v1/trees/from-points` answers, and an SVG of cloud and tree.
    FromPoints(crate::scans::FromPointsArgs),
}

#[derive(Args)]
pub struct GenerateArgs {
    /// Node counts to generate, root included: `10..=30`, `10..31`, `15` or
    /// `11,13,15`.
    #[arg(long, default_value = "10..=30", value_parser = parse_sizes)]
    nodes: NodeSizes,
    /// Trees per node count.
    #[arg(long, default_value_t = 100)]
    per_size: usize,
    /// Base seed; tree k of size N uses seed `tree_seed(seed, N, candidate)`.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Output directory (created if missing).
    #[arg(long)]
    out: PathBuf,
    /// Keep trees whose topology repeats an earlier tree of the same size.
    /// By default every tree of a size has a distinct topology, as in the
    /// paper (100 unique topologies per size).
    #[arg(long)]
    allow_duplicate_topologies: bool,
    /// Tree shape: `sca` (Space Colonization, the paper's 10-30 node
    /// trees), `orchard` (a central leader with scaffolds and laterals at
    /// the paper's node spacing, for 50-500 nodes), `mixed` (both), `crop`
    /// (cut around one deep path of a 100-500-node orchard tree) or `all`.
    #[arg(long, default_value = "sca")]
    shape: TreeShape,
}

#[derive(Args)]
pub struct ShowArgs {
    /// A tree URDF file.
    file: PathBuf,
    /// Print the tree as JSON (positions, parents, radius, length,
    /// stiffness, damping per node; the root's branch entries are null).
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
pub struct RenderArgs {
    /// A tree URDF file.
    file: PathBuf,
    /// Where to write the SVG.
    #[arg(long)]
    out: PathBuf,
    /// Title above the drawing (default: file name, N and height).
    #[arg(long)]
    title: Option<String>,
}

#[derive(Clone, Debug)]
pub struct NodeSizes(pub Vec<usize>);

pub fn parse_sizes(s: &str) -> Result<NodeSizes, String> {
    let parse = |t: &str| {
        t.trim()
            .parse::<usize>()
            .map_err(|_| format!("`{t}` is not a node count"))
    };
    let sizes: Vec<usize> = if let Some((a, b)) = s.split_once("..=") {
        RangeInclusive::new(parse(a)?, parse(b)?).collect()
    } else if let Some((a, b)) = s.split_once("..") {
        (parse(a)?..parse(b)?).collect()
    } else {
        s.split(',').map(parse).collect::<Result<_, _>>()?
    };
    if sizes.is_empty() {
        return Err(format!("`{s}` names no node count"));
    }
    Ok(NodeSizes(sizes))
}

pub fn run(cmd: TreesCommand) -> anyhow::Result<()> {
    match cmd {
        TreesCommand::Generate(args) => generate(args),
        TreesCommand::Show(args) => show(args),
        TreesCommand::Render(args) => render_file(args),
        TreesCommand::Scan(args) => crate::scans::scan_cmd(args),
        TreesCommand::FromPoints(args) => crate::scans::from_points_cmd(args),
    }
}

#[derive(Serialize)]
struct Index {
    generator: &'static str,
    shape: TreeShape,
    base_seed: u64,
    params: ScaParams,
    trees: Vec<IndexEntry>,
}

#[derive(Serialize)]
struct IndexEntry {
    file: String,
    #[serde(flatten)]
    origin: TreeOrigin,
    height: f64,
}

fn generate(args: GenerateArgs) -> anyhow::Result<()> {
    let params = ScaParams::default();
    for &n in &args.nodes.0 {
        if !(tree::sca::MIN_GENERATED_NODES..=tree::MAX_NODES).contains(&n) {
            bail!(
                "--nodes: {n} is outside the generator's range {}..={}",
                tree::sca::MIN_GENERATED_NODES,
                tree::MAX_NODES
            );
        }
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let total = (args.nodes.0.len() * args.per_size) as u64;
    let bar = crate::progress::bar(total, "trees");
    let start = std::time::Instant::now();
    // Sizes run in parallel; within a size, candidates run in order so the
    // uniqueness filter keeps the same trees every time.
    let per_size: Vec<anyhow::Result<Vec<IndexEntry>>> = args
        .nodes
        .0
        .par_iter()
        .map(|&n| {
            let dir = format!("N{n}");
            std::fs::create_dir_all(args.out.join(&dir))?;
            let mut entries = Vec::with_capacity(args.per_size);
            let mut write_error = None;
            tree_set(
                n,
                args.per_size,
                args.seed,
                &params,
                args.shape,
                !args.allow_duplicate_topologies,
                |origin, tree| {
                    let file = format!("{dir}/tree_{:03}.urdf", origin.index);
                    let name = format!("tree_N{n}_{:03}", origin.index);
                    if let Err(e) =
                        urdf::write_file(tree, &name, &params.wood, &args.out.join(&file))
                    {
                        write_error.get_or_insert(
                            anyhow::Error::new(e).context(format!("cannot write {file}")),
                        );
                    }
                    entries.push(IndexEntry {
                        file,
                        origin: *origin,
                        height: tree.height(),
                    });
                    bar.inc(1);
                },
            )?;
            match write_error {
                Some(e) => Err(e),
                None => Ok(entries),
            }
        })
        .collect();
    bar.finish_and_clear();
    let mut entries = Vec::new();
    for result in per_size {
        entries.extend(result?);
    }
    let index = Index {
        generator: concat!("treemanip ", env!("CARGO_PKG_VERSION")),
        shape: args.shape,
        base_seed: args.seed,
        params,
        trees: entries,
    };
    let index_path = args.out.join("index.json");
    std::fs::write(&index_path, serde_json::to_string_pretty(&index)?)
        .with_context(|| format!("cannot write {}", index_path.display()))?;
    println!(
        "wrote {} trees ({} sizes) to {} in {:.2} s; index: {}",
        index.trees.len(),
        args.nodes.0.len(),
        args.out.display(),
        start.elapsed().as_secs_f64(),
        index_path.display()
    );
    Ok(())
}

fn load(path: &Path) -> anyhow::Result<Tree> {
    urdf::read_file(path).with_context(|| format!("cannot load tree {}", path.display()))
}

#[derive(Serialize)]
struct TreeJson {
    positions: Vec<[f64; 3]>,
    parents: Vec<Option<usize>>,
    radius: Vec<Option<f64>>,
    length: Vec<Option<f64>>,
    stiffness: Vec<Option<f64>>,
    damping: Vec<Option<f64>>,
}

fn show(args: ShowArgs) -> anyhow::Result<()> {
    let tree = load(&args.file)?;
    let mut out = std::io::stdout().lock();
    if args.json {
        let per_node = |f: fn(&tree::Branch) -> f64| -> Vec<Option<f64>> {
            tree.branches().iter().map(|b| b.as_ref().map(f)).collect()
        };
        let json = TreeJson {
            positions: tree.positions().iter().map(|p| [p.x, p.y, p.z]).collect(),
            parents: tree.parents().to_vec(),
            radius: per_node(|b| b.radius),
            length: per_node(|b| b.length),
            stiffness: per_node(|b| b.stiffness),
            damping: per_node(|b| b.damping),
        };
        writeln!(out, "{}", serde_json::to_string_pretty(&json)?)?;
        return Ok(());
    }
    let n = tree.len();
    let leaves = (0..n).filter(|&j| tree.is_leaf(j)).count();
    let forks = (0..n).filter(|&j| tree.children(j).len() >= 2).count();
    let max_depth = (0..n).map(|j| tree.depth(j)).max().unwrap_or(0);
    writeln!(out, "{}", args.file.display())?;
    writeln!(
        out,
        "  nodes {n} (leaves {leaves}, forks {forks}), height {:.3} m, max depth {max_depth}, closest nodes {:.3} m apart",
        tree.height(),
        tree.min_node_spacing()
    )?;
    let range = |f: fn(&tree::Branch) -> f64| {
        let values: Vec<f64> = tree.branches_iter().map(|(_, b)| f(b)).collect();
        (
            values.iter().copied().fold(f64::INFINITY, f64::min),
            values.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        )
    };
    let (r0, r1) = range(|b| b.radius);
    let (l0, l1) = range(|b| b.length);
    let (k0, k1) = range(|b| b.stiffness);
    writeln!(
        out,
        "  radius {:.4}–{:.4} m, length {:.3}–{:.3} m, K_s {:.3e}–{:.3e} N·m/rad",
        r0, r1, l0, l1, k0, k1
    )?;
    writeln!(
        out,
        "\n  {:>4} {:>6} {:>5} {:>9} {:>9} {:>9} {:>8} {:>8} {:>10} {:>10}",
        "node", "parent", "depth", "x (m)", "y (m)", "z (m)", "r (m)", "ℓ (m)", "K_s", "K_d"
    )?;
    for j in 0..n {
        let p = tree.position(j);
        let parent = tree.parent(j).map_or("-".to_owned(), |p| p.to_string());
        match tree.branch(j) {
            Some(b) => writeln!(
                out,
                "  {j:>4} {parent:>6} {:>5} {:>9.4} {:>9.4} {:>9.4} {:>8.4} {:>8.4} {:>10.3e} {:>10.3e}",
                tree.depth(j),
                p.x,
                p.y,
                p.z,
                b.radius,
                b.length,
                b.stiffness,
                b.damping
            ),
            None => writeln!(
                out,
                "  {j:>4} {parent:>6} {:>5} {:>9.4} {:>9.4} {:>9.4}   (fixed root)",
                tree.depth(j),
                p.x,
                p.y,
                p.z
            ),
        }?;
    }
    Ok(())
}

fn render_file(args: RenderArgs) -> anyhow::Result<()> {
    let tree = load(&args.file)?;
    let title = args.title.unwrap_or_else(|| {
        format!(
            "{} — N = {}, height {:.2} m",
            args.file
                .file_name()
                .map_or_else(String::new, |f| f.to_string_lossy().into_owned()),
            tree.len(),
            tree.height()
        )
    });
    std::fs::write(&args.out, render::tree_svg(&tree, &title))
        .with_context(|| format!("cannot write {}", args.out.display()))?;
    println!("wrote {}", args.out.display());
    Ok(())
}
