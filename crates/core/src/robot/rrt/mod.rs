//! RRT* in joint space (Karaman & Frazzoli 2011), with several goal
//! configurations at once, then shortcut smoothing.
//!
//! - Samples uniformly inside a box around the start and the goals (each
//!   joint's range widened by `sampling_margin`, within the joint limits),
//!   or (with probability `goal_bias`) one of the goals. Sampling all of
//!   ±2π on six joints wastes nearly every sample on wrapped-around arm
//!   poses far from both ends.
//! - Steers at most `max_step` (rad, Euclidean in joint space) from the
//!   nearest node.
//! - Chooses the cheapest collision-free parent among the nodes within
//!   r_n = min(γ (ln n / n)^{1/6}, `max_step`), then rewires those
//!   neighbours through the new node when that is cheaper. Cost is joint-
//!   space path length, so the best cost never increases with iterations.
//! - Tries the direct edge to each goal first, nearest goal first, and
//!   stops at the iteration or time budget, `refine_iterations` after the
//!   first solution, or at once when a path is as short as the straight
//!   line to the nearest goal (nothing can beat it).
//!
//! - By default edges are evaluated lazily ([`lazy`]): checked only when a
//!   path through them is about to be used (`lazy: false` keeps the
//!   textbook algorithm, which checks every edge as it is added).
//!
//! The validity of configurations and edges is the caller's
//! [`MotionValidator`]; [`super::scene::PlanningScene`] is the one used for
//! the arm. The random stream is ChaCha8 from `seed`, so a plan with the
//! same inputs and seed (and no time budget hit) is reproduced exactly.

use std::time::{Duration, Instant};

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

mod lazy;

/// A joint configuration (one value per joint of the arm planned for).
pub type Config = super::joint_vector::JointVector;

/// Decides which configurations and straight joint-space edges are free.
pub trait MotionValidator {
    fn config_valid(&self, q: &Config) -> bool;
    /// The straight edge from `a` (known valid) to `b` is free.
    fn edge_valid(&self, a: &Config, b: &Config) -> bool;
    /// Each joint's position limits, which bound the sampling.
    fn joint_limits(&self) -> Vec<(f64, f64)>;
}

#[derive(Debug, Clone)]
pub struct RrtStarOptions {
    pub max_iterations: usize,
    pub time_budget: Option<Duration>,
    pub goal_bias: f64,
    /// Largest extension per iteration (rad, Euclidean).
    pub max_step: f64,
    /// γ of the shrinking neighbour radius (rad).
    pub gamma: f64,
    /// Iterations spent improving after the first solution.
    pub refine_iterations: usize,
    /// How far beyond the start and goals each joint is sampled (rad).
    pub sampling_margin: f64,
    /// Lazy edge evaluation ([`lazy`]): edges join the tree unchecked and
    /// are checked only when a path through them is about to be used.
    pub lazy: bool,
    pub seed: u64,
}

impl Default for RrtStarOptions {
    fn default() -> Self {
        Self {
            max_iterations: 5000,
            time_budget: Some(Duration::from_millis(500)),
            goal_bias: 0.1,
            max_step: 0.6,
            gamma: 6.0,
            // On the robot bench's fence, 20 and 40 give the same median
            // cost; the extra 20 are a quarter of the time.
            refine_iterations: 20,
            sampling_margin: 1.5,
            lazy: true,
            seed: 1,
        }
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct RrtStats {
    pub iterations: usize,
    pub nodes: usize,
    /// Iteration at which the first solution appeared.
    pub first_solution: Option<usize>,
    /// (iteration, best cost) each time the best cost improved.
    pub cost_history: Vec<(usize, f64)>,
    pub elapsed_ms: f64,
}

#[derive(Debug, Clone)]
pub struct RrtPath {
    /// Start … goal, each edge collision-free.
    pub waypoints: Vec<Config>,
    /// Which of the goals was reached.
    pub goal: usize,
    pub cost: f64,
    pub stats: RrtStats,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RrtError {
    #[error("the start configuration is in collision")]
    StartInvalid,
    #[error("no goal configuration is collision-free")]
    NoValidGoal,
    #[error("no path found within the budget ({iterations} iterations, {elapsed_ms:.1} ms)")]
    NoPath { iterations: usize, elapsed_ms: f64 },
}

pub fn distance(a: &Config, b: &Config) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}

fn steer(from: &Config, to: &Config, max_step: f64) -> Config {
    let d = distance(from, to);
    if d <= max_step {
        return *to;
    }
    from.lerp(to, max_step / d)
}

/// The valid goals (with their index among those given), the random
/// stream and the sampling box of one query.
struct Sampler {
    goals: Vec<(usize, Config)>,
    rng: ChaCha8Rng,
    bounds: Vec<(f64, f64)>,
}

impl Sampler {
    fn new(
        start: &Config,
        goals: &[Config],
        validator: &dyn MotionValidator,
        options: &RrtStarOptions,
    ) -> Result<Self, RrtError> {
        if !validator.config_valid(start) {
            return Err(RrtError::StartInvalid);
        }
        let goals: Vec<(usize, Config)> = goals
            .iter()
            .copied()
            .enumerate()
            .filter(|(_, g)| validator.config_valid(g))
            .collect();
        if goals.is_empty() {
            return Err(RrtError::NoValidGoal);
        }
        let limits = validator.joint_limits();
        let bounds: Vec<(f64, f64)> = (0..start.len())
            .map(|i| {
                let values = goals
                    .iter()
                    .map(|g| g.1[i])
                    .chain(std::iter::once(start[i]));
                let lo = values.clone().fold(f64::INFINITY, f64::min) - options.sampling_margin;
                let hi = values.fold(f64::NEG_INFINITY, f64::max) + options.sampling_margin;
                (lo.max(limits[i].0), hi.min(limits[i].1))
            })
            .collect();
        Ok(Self {
            goals,
            rng: ChaCha8Rng::seed_from_u64(options.seed),
            bounds,
        })
    }
}

/// A goal (with probability `goal_bias`) or a uniform sample of the box.
fn sample(
    rng: &mut ChaCha8Rng,
    goals: &[(usize, Config)],
    bounds: &[(f64, f64)],
    goal_bias: f64,
) -> Config {
    if rng.random::<f64>() < goal_bias {
        goals[rng.random_range(0..goals.len())].1
    } else {
        Config::from_fn(bounds.len(), |i| {
            rng.random_range(bounds[i].0..=bounds[i].1)
        })
    }
}

/// A direct edge is the shortest path to its goal: the direct edges are
/// checked nearest goal first, and the first free one is returned (a
/// farther goal's direct edge cannot beat it, so it is not checked).
fn direct_link(
    start: &Config,
    goals: &[(usize, Config)],
    validator: &dyn MotionValidator,
) -> Option<usize> {
    let mut order: Vec<(usize, f64)> = goals
        .iter()
        .enumerate()
        .map(|(g, (_, goal))| (g, distance(start, goal)))
        .collect();
    order.sort_by(|a, b| a.1.total_cmp(&b.1));
    order
        .into_iter()
        .map(|(g, _)| g)
        .find(|&g| validator.edge_valid(start, &goals[g].1))
}

/// No path is shorter than the straight line to the nearest goal; a path
/// of that cost ends the search.
fn cost_lower_bound(start: &Config, goals: &[(usize, Config)]) -> f64 {
    goals
        .iter()
        .map(|(_, g)| distance(start, g))
        .fold(f64::INFINITY, f64::min)
}

/// The neighbour radius of RRT* with `n` nodes, never above the step.
/// (The exponent is 1/dimension: 1/6 for the UR5, 1/7 for a 7-joint arm.)
fn neighbour_radius(options: &RrtStarOptions, n: usize, dof: usize) -> f64 {
    let n = n as f64 + 1.0;
    (options.gamma * (n.ln() / n).powf(1.0 / dof as f64)).min(options.max_step)
}

struct Node {
    q: Config,
    parent: Option<usize>,
    cost: f64,
    children: Vec<usize>,
}

/// Plans from `start` to any of `goals`.
pub fn rrt_star(
    start: &Config,
    goals: &[Config],
    validator: &dyn MotionValidator,
    options: &RrtStarOptions,
) -> Result<RrtPath, RrtError> {
    if options.lazy {
        return lazy::rrt_star(start, goals, validator, options);
    }
    let clock = Instant::now();
    let Sampler {
        goals,
        mut rng,
        bounds,
    } = Sampler::new(start, goals, validator, options)?;
    let mut nodes = vec![Node {
        q: *start,
        parent: None,
        cost: 0.0,
        children: Vec::new(),
    }];
    // (node, index into `goals`): a free edge from the node to that goal.
    let mut goal_links: Vec<(usize, usize)> = Vec::new();
    let mut stats = RrtStats {
        iterations: 0,
        nodes: 1,
        first_solution: None,
        cost_history: Vec::new(),
        elapsed_ms: 0.0,
    };
    let best = |nodes: &[Node], links: &[(usize, usize)]| {
        links
            .iter()
            .map(|&(n, g)| (nodes[n].cost + distance(&nodes[n].q, &goals[g].1), n, g))
            .min_by(|a, b| a.0.total_cmp(&b.0))
    };
    goal_links.extend(direct_link(start, &goals, validator).map(|g| (0, g)));
    let lower_bound = cost_lower_bound(start, &goals);
    if let Some((cost, _, _)) = best(&nodes, &goal_links) {
        stats.first_solution = Some(0);
        stats.cost_history.push((0, cost));
    }

    while stats.first_solution.is_none()
        || stats.iterations < stats.first_solution.unwrap_or(0) + options.refine_iterations
    {
        if best(&nodes, &goal_links).is_some_and(|b| b.0 <= lower_bound) {
            break; // nothing can be shorter
        }
        if stats.iterations >= options.max_iterations
            || options.time_budget.is_some_and(|b| clock.elapsed() >= b)
        {
            break;
        }
        stats.iterations += 1;
        let sample = sample(&mut rng, &goals, &bounds, options.goal_bias);
        let nearest = (0..nodes.len())
            .min_by(|&a, &b| {
                distance(&nodes[a].q, &sample).total_cmp(&distance(&nodes[b].q, &sample))
            })
            .expect("the tree has its root");
        let new_q = steer(&nodes[nearest].q, &sample, options.max_step);
        if !validator.config_valid(&new_q) {
            continue;
        }
        let radius = neighbour_radius(options, nodes.len(), start.len());
        let mut near: Vec<(usize, f64)> = (0..nodes.len())
            .map(|i| (i, distance(&nodes[i].q, &new_q)))
            .filter(|&(i, d)| d <= radius || i == nearest)
            .collect();
        // Cheapest parent first; the first free edge wins.
        near.sort_by(|a, b| (nodes[a.0].cost + a.1).total_cmp(&(nodes[b.0].cost + b.1)));
        let Some(&(parent, d)) = near
            .iter()
            .find(|(i, _)| validator.edge_valid(&nodes[*i].q, &new_q))
        else {
            continue;
        };
        let new = nodes.len();
        nodes.push(Node {
            q: new_q,
            parent: Some(parent),
            cost: nodes[parent].cost + d,
            children: Vec::new(),
        });
        nodes[parent].children.push(new);
        // Rewire neighbours through the new node where cheaper.
        for &(m, d) in &near {
            if m == parent || nodes[new].cost + d >= nodes[m].cost {
                continue;
            }
            if !validator.edge_valid(&new_q, &nodes[m].q) {
                continue;
            }
            if let Some(old) = nodes[m].parent {
                nodes[old].children.retain(|&c| c != m);
            }
            nodes[m].parent = Some(new);
            nodes[new].children.push(m);
            let delta = nodes[new].cost + d - nodes[m].cost;
            let mut stack = vec![m];
            while let Some(k) = stack.pop() {
                nodes[k].cost += delta;
                stack.extend(nodes[k].children.iter().copied());
            }
        }
        // A goal edge that cannot beat the best path found yet is not
        // checked (the edge check is most of an iteration's time).
        let best_cost = best(&nodes, &goal_links).map_or(f64::INFINITY, |b| b.0);
        for (g, (_, goal)) in goals.iter().enumerate() {
            let d = distance(&new_q, goal);
            if d <= options.max_step
                && nodes[new].cost + d < best_cost
                && validator.edge_valid(&new_q, goal)
            {
                goal_links.push((new, g));
            }
        }
        if let Some((cost, _, _)) = best(&nodes, &goal_links) {
            if stats.first_solution.is_none() {
                stats.first_solution = Some(stats.iterations);
            }
            if stats.cost_history.last().is_none_or(|&(_, c)| cost < c) {
                stats.cost_history.push((stats.iterations, cost));
            }
        }
    }
    stats.nodes = nodes.len();
    stats.elapsed_ms = clock.elapsed().as_secs_f64() * 1e3;
    let Some((cost, last, g)) = best(&nodes, &goal_links) else {
        return Err(RrtError::NoPath {
            iterations: stats.iterations,
            elapsed_ms: stats.elapsed_ms,
        });
    };
    let mut waypoints = vec![goals[g].1];
    let mut k = Some(last);
    while let Some(i) = k {
        waypoints.push(nodes[i].q);
        k = nodes[i].parent;
    }
    waypoints.reverse();
    Ok(RrtPath {
        waypoints,
        goal: goals[g].0,
        cost,
        stats,
    })
}

/// Path length in joint space.
pub fn path_cost(path: &[Config]) -> f64 {
    path.windows(2).map(|w| distance(&w[0], &w[1])).sum()
}

/// Random shortcutting: repeatedly joins two random waypoints directly when
/// that edge is free, dropping what lay between. Never lengthens the path.
///
/// A pair found blocked is not drawn again while the path is unchanged, and
/// the smoothing stops once every pair is known blocked: a three-waypoint
/// path has one pair, which would otherwise be checked `attempts` times.
pub fn shortcut(
    path: &[Config],
    validator: &dyn MotionValidator,
    attempts: usize,
    seed: u64,
) -> Vec<Config> {
    let mut path = path.to_vec();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // Pairs (i, j), j ≥ i + 2, of the current path whose edge is blocked.
    let mut blocked: Vec<(usize, usize)> = Vec::new();
    for _ in 0..attempts {
        let n = path.len();
        if n < 3 {
            break;
        }
        let open: Vec<(usize, usize)> = (0..n - 2)
            .flat_map(|i| (i + 2..n).map(move |j| (i, j)))
            .filter(|p| !blocked.contains(p))
            .collect();
        if open.is_empty() {
            break;
        }
        let (i, j) = open[rng.random_range(0..open.len())];
        if validator.edge_valid(&path[i], &path[j]) {
            path.drain(i + 1..j);
            blocked.clear();
        } else {
            blocked.push((i, j));
        }
    }
    path
}
