//! `treemanip plan` and `treemanip eval plan`: both call the one planner
//! ([`treemanip::planner::Planner`]) that `/v1/plan` calls.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::{Args, ValueEnum};
use nalgebra::{Isometry3, Vector3};
use rayon::prelude::*;
use treemanip::dataset::Split;
use treemanip::dataset::collect::{CollectConfig, collect_size};
use treemanip::eval::plan::{
    BaseArea, EpisodeResult, Setting, evaluation_region, plan_episode, policy_top_error, summarise,
    to_markdown,
};
use treemanip::eval::plots::rank_histogram_svg;
use treemanip::infer::models::{ModelSet, ServedModel, SessionLayout};
use treemanip::planner::{Objective, Planner, Query, Stance, Strategy};
use treemanip::robot::collision::CollisionModel;
use treemanip::robot::model::joint_vector::JointVector;

use treemanip::sim::{Push, SimConfig, simulate};

use crate::args::parse_vector;
use crate::trees::{NodeSizes, parse_sizes};

#[derive(Clone, Copy, ValueEnum)]
enum StrategyArg {
    Model,
    Physics,
    Paper,
}

impl From<StrategyArg> for Strategy {
    fn from(s: StrategyArg) -> Self {
        match s {
            StrategyArg::Model => Strategy::Model,
            StrategyArg::Physics => Strategy::Physics,
            StrategyArg::Paper => Strategy::Paper,
        }
    }
}

#[derive(Args)]
pub struct PlanArgs {
    /// A tree URDF file.
    #[arg(long)]
    tree: PathBuf,
    /// With `--push`: a node whose push's simulated result is the target
    /// shape (the paper's task).
    #[arg(long, requires = "push", required_unless_present = "objective")]
    node: Option<usize>,
    /// The gripper's displacement T (m) `DX,DY,DZ` of that push.
    #[arg(long, value_parser = parse_vector, allow_hyphen_values = true, requires = "node")]
    push: Option<Vector3<f64>>,
    /// Instead of `--node`/`--push`: a JSON file with the objective as
    /// `/v1/plan` takes it (`{"kind": "clear", "regions": [...]}`, `reach`
    /// or `shape`; see `docs/tasks.md`).
    #[arg(long, conflicts_with_all = ["node", "push"])]
    objective: Option<PathBuf>,
    /// Bending-stress limit (Pa); default 40 MPa (`docs/tasks.md`).
    #[arg(long)]
    max_stress: Option<f64>,
    /// Contact-force limit (N); default 50 N.
    #[arg(long)]
    max_contact_force: Option<f64>,
    /// Plan without load limits (as the paper did).
    #[arg(long, conflicts_with_all = ["max_stress", "max_contact_force"])]
    no_limits: bool,
    /// Start joint configuration (rad), one comma-separated value per joint.
    /// Default: the arm's home (for the UR5, the paper's).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    start: Option<Vec<f64>>,
    /// The arm: `ur5` (built in), a shipped description's name (`panda`:
    /// `robots/panda.toml`), a description or URDF path, or
    /// `NAME=PATH[,tip=LINK][,base=LINK]`.
    #[arg(long, default_value = "ur5")]
    robot: String,
    /// Arm base position `X,Y,Z` (m), identity orientation. Default: the
    /// paper's (−0.5, 0, 0.1).
    #[arg(long, value_parser = parse_vector, allow_hyphen_values = true, conflicts_with = "base_region")]
    base: Option<Vector3<f64>>,
    /// Let the planner place the base within ±0.5 m of the default in x and
    /// y and 0.1-1.0 m high.
    #[arg(long)]
    base_region: bool,
    #[arg(long, value_enum, default_value = "model")]
    strategy: StrategyArg,
    /// Directory of the ONNX models.
    #[arg(long, default_value = "models")]
    models_dir: PathBuf,
    /// Seed of the search and of RRT*.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Print the whole plan (trajectory included) as JSON.
    #[arg(long)]
    json: bool,
}

/// The test split's episodes, `per_size` of each size, as `dataset
/// collect` makes them with `seed`.
pub(crate) fn test_episodes(
    sizes: &[usize],
    per_size: usize,
    seed: u64,
) -> anyhow::Result<Vec<treemanip::dataset::SizeData>> {
    sizes
        .iter()
        .map(|&n| {
            // The paper's trees where Space Colonization grows them,
            // orchard trees above.
            let shape = if n > treemanip::tree::sca::MAX_SCA_NODES {
                treemanip::tree::collection::TreeShape::Orchard
            } else {
                treemanip::tree::collection::TreeShape::Sca
            };
            let config = CollectConfig {
                seed,
                shape,
                ..CollectConfig::default()
            };
            collect_size(Split::Test, n, per_size, &config, &|| {})
                .map(|(size, _)| size)
                .with_context(|| format!("simulating test episodes of {n} nodes"))
        })
        .collect()
}

/// The GNN policy and forward model from a models directory.
pub(crate) fn load_models(dir: &std::path::Path) -> anyhow::Result<ModelSet> {
    let set = ModelSet::load_dir(
        dir,
        None,
        SessionLayout::shared(rayon::current_num_threads()),
        false,
    )
    .with_context(|| format!("cannot load the models in {}", dir.display()))?;
    for name in ["policy_gnn", "forward_gnn"] {
        if set.get(name).is_none() {
            bail!("{} has no {name}.onnx", dir.display());
        }
    }
    Ok(set)
}

pub(crate) fn gnns(set: &ModelSet) -> (&ServedModel, &ServedModel) {
    (
        set.get("policy_gnn").expect("checked on load"),
        set.get("forward_gnn").expect("checked on load"),
    )
}

pub fn plan(args: PlanArgs) -> anyhow::Result<()> {
    let arm = resolve_robot(&args.robot)?;
    if let Some(q) = &args.start {
        if !arm.within_limits(q) {
            bail!(
                "--start needs {} values within the joints' limits of `{}`",
                arm.dof(),
                arm.name()
            );
        }
    }
    let tree = treemanip::tree::urdf::read_file(&args.tree)
        .with_context(|| format!("cannot load tree {}", args.tree.display()))?;
    let objective = match (&args.objective, args.node, args.push) {
        (Some(path), _, _) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read {}", path.display()))?;
            let json: treemanip::api::types::ObjectiveJson = serde_json::from_str(&text)
                .with_context(|| format!("{} is not an objective", path.display()))?;
            treemanip::api::objective::objective(Some(&json), None, &tree)
                .map_err(|e| anyhow::anyhow!("{}: {}", path.display(), e.message))?
        }
        (None, Some(node), Some(vector)) => {
            let outcome = simulate(&tree, &Push { node, vector }, &SimConfig::default())
                .context("the push that makes the target cannot be simulated")?;
            Objective::shape(outcome.final_positions)
        }
        _ => bail!("give `--objective FILE`, or `--node` and `--push` for a target shape"),
    };
    let limits = treemanip::api::objective::limits(Some(&treemanip::api::types::LimitsJson {
        max_stress: args.max_stress,
        max_contact_force: args.max_contact_force,
    }))
    .map_err(|e| anyhow::anyhow!("{}", e.message))?;
    let set = load_models(&args.models_dir)?;
    let (policy, forward) = gnns(&set);
    let mut query = Query::with_objective(tree, objective);
    query.limits = (!args.no_limits).then_some(limits);
    query.strategy = args.strategy.into();
    query.start = args.start.as_deref().map(JointVector::from_slice);
    query.seed = args.seed;
    query.stance = if args.base_region {
        Stance::Region(evaluation_region())
    } else {
        Stance::Fixed(args.base.map_or_else(
            || arm.default_base(),
            |b| Isometry3::translation(b.x, b.y, b.z),
        ))
    };
    let base = arm.default_base();
    let planner = Planner::new(CollisionModel::new(arm.with_base(base)));
    let plan = planner
        .plan(&query, policy, Some(forward))
        .context("cannot plan")?;
    if args.json {
        #[derive(serde::Serialize)]
        struct PlanJson<'a> {
            status: &'static str,
            robot: &'a str,
            joint_names: Vec<&'a str>,
            #[serde(flatten)]
            plan: &'a treemanip::planner::Plan,
        }
        let json = PlanJson {
            status: if plan.plan.is_some() {
                "planned"
            } else {
                "no_plan"
            },
            robot: planner.robot().name(),
            joint_names: planner.robot().joint_names().collect(),
            plan: &plan,
        };
        println!("{}", serde_json::to_string_pretty(&json)?);
        return Ok(());
    }
    for a in &plan.attempts {
        let predicted = a.predicted_error.map_or(String::new(), |e| {
            format!(", predicted residual {:.2} cm", 100.0 * e)
        });
        let loads = a
            .simulated_loads
            .or(a.predicted_loads)
            .map_or(String::new(), |l| {
                format!(
                    ", peak stress {:.1} MPa, force {:.1} N",
                    l.peak_stress / 1e6,
                    l.contact_force
                )
            });
        println!(
            "node {} (rank {}), push [{:.3}, {:.3}, {:.3}] m: {:?} in {:.1} ms{predicted}{loads}",
            a.node, a.rank, a.push[0], a.push[1], a.push[2], a.outcome, a.ms
        );
    }
    println!(
        "base at [{:.2}, {:.2}, {:.2}] m, yaw {:.2} rad; no action leaves a residual of {:.2} cm; {} predictions",
        plan.base.position[0],
        plan.base.position[1],
        plan.base.position[2],
        plan.base.yaw,
        100.0 * plan.no_action_error,
        plan.evaluations
    );
    match &plan.plan {
        Some(p) => {
            let e = &p.execution;
            let at = |k: usize| e.joint_trajectory.points[k].time_from_start.as_secs();
            let end = e
                .joint_trajectory
                .points
                .last()
                .map_or(0.0, |p| p.time_from_start.as_secs());
            println!(
                "planned node {}: {} trajectory points, approach {:.2} s, push {:.2} s, in all {:.2} s; planning {:.1} ms",
                p.node,
                e.joint_trajectory.points.len(),
                at(e.push_start_point),
                at(e.push_end_point) - at(e.push_start_point),
                end,
                plan.total_ms
            );
            if let Some(guard) = plan.guard_contact_force {
                println!("stop the push when the wrist reads {guard:.1} N (guard)");
            }
        }
        None => println!("no plan ({:.1} ms)", plan.total_ms),
    }
    Ok(())
}

#[derive(Args)]
pub struct EvalPlanArgs {
    /// Tree sizes.
    #[arg(long, default_value = "10..=30", value_parser = parse_sizes)]
    sizes: NodeSizes,
    /// Episodes per size (test split, as `dataset collect` makes them).
    #[arg(long, default_value_t = 10)]
    per_size: usize,
    #[command(flatten)]
    data: crate::args::EvalData,
    /// Where to write plan_eval.{md,json} and plan_fig10_*.svg
    /// (plan_eval_ROBOT.* and plan_fig10_ROBOT_* for another arm).
    #[arg(long, default_value = "docs/results")]
    out: PathBuf,
    /// The arm (as `treemanip plan --robot`).
    #[arg(long, default_value = "ur5")]
    robot: String,
    /// Only these settings (`model/region`, comma-separated; default:
    /// all six). For quick comparisons; write them with `--out` elsewhere.
    #[arg(long, value_delimiter = ',')]
    settings: Vec<String>,
    /// Let the `region` settings' base stand anywhere within this half
    /// width (m) of the trunk in x and y, a base that drives around the
    /// tree, instead of the paper's region beside it (sized for 10-30-node
    /// trees, under the crown of larger ones).
    #[arg(long)]
    around_tree: Option<f64>,
}

/// The base's area for `--around-tree` (none: the paper's region).
pub fn base_area(around_tree: Option<f64>) -> anyhow::Result<BaseArea> {
    match around_tree {
        None => Ok(BaseArea::Paper),
        Some(w) if w.is_finite() && w > 0.0 && w <= 20.0 => Ok(BaseArea::AroundTree(w)),
        Some(w) => {
            bail!("--around-tree must be a half width in metres, above 0 and at most 20 (got {w})")
        }
    }
}

/// The arm a `--robot` value names ([`treemanip::robot::catalog::resolve`]).
fn resolve_robot(text: &str) -> anyhow::Result<treemanip::robot::Arm> {
    let packages = treemanip::robot::model::link_geometry::package_path_from_env();
    Ok(treemanip::robot::catalog::resolve(text, &packages)?)
}

pub fn eval_plan(args: EvalPlanArgs) -> anyhow::Result<()> {
    if args.per_size == 0 {
        bail!("--per-size must be at least 1");
    }
    let area = base_area(args.around_tree)?;
    let started = Instant::now();
    let data = test_episodes(&args.sizes.0, args.per_size, args.data.seed)?;
    let episodes: Vec<_> = data
        .iter()
        .flat_map(|d| d.episodes.iter().map(move |e| (d.n, d.tree_of(e), e)))
        .collect();
    let set = load_models(&args.data.models_dir)?;
    let (policy, forward) = gnns(&set);
    let arm = resolve_robot(&args.robot)?;
    let suffix = if args.robot == treemanip::robot::catalog::BUILT_IN {
        String::new()
    } else {
        format!("_{}", arm.name())
    };
    let robot_note = format!(
        "Robot: `{}` ({} joints, {} IK).",
        arm.name(),
        arm.dof(),
        if arm.has_closed_form_ik() {
            "closed-form"
        } else {
            "numerical"
        }
    );
    let base = arm.default_base();
    let planner = Planner::new(CollisionModel::new(arm.with_base(base)));
    let mut rows = Vec::new();
    let mut per_setting: Vec<(String, Vec<EpisodeResult>)> = Vec::new();
    let settings: Vec<Setting> = Setting::all()
        .into_iter()
        .filter(|s| args.settings.is_empty() || args.settings.contains(&s.name()))
        .collect();
    if settings.is_empty() {
        let known: Vec<String> = Setting::all().iter().map(Setting::name).collect();
        bail!(
            "--settings: none of {:?} is one of {known:?}",
            args.settings
        );
    }
    for setting in settings {
        let name = setting.name();
        let bar = crate::progress::bar(episodes.len() as u64, &name);
        // One episode at a time: plan times are the latency one request sees.
        let results: Vec<EpisodeResult> = episodes
            .iter()
            .map(|&(n, tree, e)| {
                // The forward model the server answers this size with.
                let forward = set.forward_for(n).unwrap_or(forward);
                let r = plan_episode(&planner, policy, forward, n, tree, e, setting, area);
                bar.inc(1);
                r
            })
            .collect();
        bar.finish_and_clear();
        let summary = summarise(&name, &results);
        println!(
            "{name}: planned {:.1} %, helpful {:.1} %, executed error {:.2} cm, plan ms p50 {:.0} p95 {:.0}",
            100.0 * summary.planned,
            100.0 * summary.helpful,
            100.0 * summary.executed_error,
            summary.ms_p50,
            summary.ms_p95
        );
        rows.push(summary);
        per_setting.push((name, results));
    }
    let reference: Vec<EpisodeResult> = episodes
        .par_iter()
        .map(|&(n, tree, e)| {
            let none =
                treemanip::planner::predict::max_node_error(tree.positions(), &e.final_positions);
            EpisodeResult {
                n,
                planned: false,
                rank: None,
                executed_error: policy_top_error(policy, tree, e),
                no_action_error: none,
                ms: f64::NAN,
                outcomes: Vec::new(),
            }
        })
        .collect();
    let mut top = summarise("policy top (arm ignored)", &reference);
    top.planned = f64::NAN;
    let no_action: Vec<EpisodeResult> = reference
        .iter()
        .map(|r| EpisodeResult {
            executed_error: r.no_action_error,
            ..r.clone()
        })
        .collect();
    let mut none = summarise("no action", &no_action);
    none.planned = f64::NAN;
    rows.push(top);
    rows.push(none);
    std::fs::create_dir_all(&args.out)?;
    let table = to_markdown(&rows);
    let cpu = treemanip::nn::train::checkpoint::cpu_model();
    let md = format!(
        "# Planning evaluation\n\n`treemanip eval plan --per-size {} --seed {}{}{}` on the test split, N = {:?}, {} episodes per setting, one at a time; CPU: {cpu}, {} threads.\nThe target is the episode's final shape; the planner gets the tree and the target only and ranks with the contact policy. Executed error: the planned push run in the simulator, largest node distance to the target; an episode with no plan counts as No Action. Base region: {}. {robot_note}\n\n{table}",
        args.per_size,
        args.data.seed,
        if suffix.is_empty() {
            String::new()
        } else {
            format!(" --robot {}", args.robot)
        },
        args.around_tree
            .map_or(String::new(), |w| format!(" --around-tree {w}")),
        args.sizes.0,
        episodes.len(),
        rayon::current_num_threads(),
        area.describe()
    );
    std::fs::write(args.out.join(format!("plan_eval{suffix}.md")), &md)?;
    std::fs::write(
        args.out.join(format!("plan_eval{suffix}.json")),
        serde_json::to_string_pretty(
            &serde_json::json!({ "rows": rows, "episodes": per_setting }),
        )?,
    )?;
    for (row, (name, _)) in rows.iter().zip(&per_setting) {
        let figure = args
            .out
            .join(format!("plan_fig10{suffix}_{}.svg", name.replace('/', "_")));
        rank_histogram_svg(
            &row.rank_histogram,
            row.episodes,
            &format!(
                "{name}: planned policy rank, {} episodes, {:.1} % planned",
                row.episodes,
                100.0 * row.planned
            ),
            &figure,
            15,
        )
        .map_err(|e| anyhow::anyhow!("cannot draw {}: {e}", figure.display()))?;
    }
    println!("{table}");
    println!(
        "wrote {}/plan_eval{suffix}.{{md,json}} and plan_fig10{suffix}_*.svg in {:.1} s",
        args.out.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}
