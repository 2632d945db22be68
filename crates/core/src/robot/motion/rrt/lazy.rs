//! Lazy RRT*: the same tree growth, choose-parent and rewiring as the
//! textbook algorithm, but an edge joins the tree unchecked. Edges are
//! checked only when a path through them is about to matter:
//!
//! - before the tree grows from a node, the path from the root to it;
//! - before a goal edge is tried, the path to its node, and only when it
//!   would beat the best path found;
//! - before a path is returned or recorded as the best, all of it.
//!
//! Most edges RRT* adds are never on such a path (they lead to nodes later
//! rewired or never extended), so most are never checked. A blocked edge
//! moves its child to the cheapest neighbour it can reach by a free edge,
//! or, when there is none, drops the child's subtree. Every returned edge
//! has been checked, and the best path is kept as found (geometry does not
//! change during a query), so the best cost never grows.

use std::time::Instant;

use crate::robot::motion::rrt::problem::{
    Config, MotionValidator, RrtError, RrtPath, RrtStarOptions, RrtStats, Sampler,
    cost_lower_bound, direct_link, distance, neighbour_radius, path_cost, sample, steer,
};

/// Neighbours tried, cheapest first, when a blocked edge's child is moved.
const REPARENT_TRIES: usize = 4;

struct Node {
    q: Config,
    parent: Option<usize>,
    cost: f64,
    children: Vec<usize>,
    /// The edge from the parent has been checked and is free.
    checked: bool,
    /// Still in the tree (a dropped subtree stays in the arena).
    alive: bool,
}

struct Tree<'a> {
    nodes: Vec<Node>,
    validator: &'a dyn MotionValidator,
    max_step: f64,
}

impl Tree<'_> {
    /// Checks the unchecked edges from the root to `n`, root side first.
    /// On a blocked edge, repairs the tree and answers false.
    fn verify_path(&mut self, n: usize) -> bool {
        let mut unchecked = Vec::new();
        let mut k = n;
        while let Some(p) = self.nodes[k].parent {
            if !self.nodes[k].checked {
                unchecked.push(k);
            }
            k = p;
        }
        for &k in unchecked.iter().rev() {
            let p = self.nodes[k].parent.expect("unchecked nodes have parents");
            if self
                .validator
                .edge_valid(&self.nodes[p].q, &self.nodes[k].q)
            {
                self.nodes[k].checked = true;
            } else {
                self.repair(k);
                return false;
            }
        }
        true
    }

    /// The edge into `k` is blocked: moves `k` to the cheapest neighbour
    /// outside its subtree with a free edge, or drops its subtree.
    fn repair(&mut self, k: usize) {
        let old = self.nodes[k].parent.expect("a blocked edge has a parent");
        self.nodes[old].children.retain(|&c| c != k);
        let subtree = self.subtree(k);
        let mut inside = vec![false; self.nodes.len()];
        for &s in &subtree {
            inside[s] = true;
        }
        let q = self.nodes[k].q;
        let mut candidates: Vec<(usize, f64)> = (0..self.nodes.len())
            .filter(|&i| i != old && self.nodes[i].alive && !inside[i])
            .map(|i| (i, distance(&self.nodes[i].q, &q)))
            .filter(|&(_, d)| d <= self.max_step)
            .collect();
        candidates
            .sort_by(|a, b| (self.nodes[a.0].cost + a.1).total_cmp(&(self.nodes[b.0].cost + b.1)));
        for &(p, d) in candidates.iter().take(REPARENT_TRIES) {
            if self.validator.edge_valid(&self.nodes[p].q, &q) {
                self.attach(k, p, d, true);
                return;
            }
        }
        for s in subtree {
            self.nodes[s].alive = false;
        }
        self.nodes[k].parent = None;
    }

    fn subtree(&self, k: usize) -> Vec<usize> {
        let mut out = vec![k];
        let mut i = 0;
        while i < out.len() {
            out.extend(self.nodes[out[i]].children.iter().copied());
            i += 1;
        }
        out
    }

    /// Makes `p` the parent of `k` (edge length `d`) and shifts the costs
    /// of `k`'s subtree.
    fn attach(&mut self, k: usize, p: usize, d: f64, checked: bool) {
        if let Some(old) = self.nodes[k].parent {
            self.nodes[old].children.retain(|&c| c != k);
        }
        self.nodes[k].parent = Some(p);
        self.nodes[k].checked = checked;
        self.nodes[p].children.push(k);
        let delta = self.nodes[p].cost + d - self.nodes[k].cost;
        for s in self.subtree(k) {
            self.nodes[s].cost += delta;
        }
    }

    fn path_to(&self, n: usize) -> Vec<Config> {
        let mut path = Vec::new();
        let mut k = Some(n);
        while let Some(i) = k {
            path.push(self.nodes[i].q);
            k = self.nodes[i].parent;
        }
        path.reverse();
        path
    }
}

/// See the module documentation; same inputs, outputs and budgets as the
/// textbook [`crate::robot::motion::rrt::rrt_star`].
/// The caller has started the `clock` and drawn the `sampler` (the goals
/// checked, the sampling box found).
pub(super) fn rrt_star(
    start: &Config,
    sampler: Sampler,
    validator: &dyn MotionValidator,
    options: &RrtStarOptions,
    clock: Instant,
) -> Result<RrtPath, RrtError> {
    let Sampler {
        goals,
        mut rng,
        bounds,
    } = sampler;
    let mut tree = Tree {
        nodes: vec![Node {
            q: *start,
            parent: None,
            cost: 0.0,
            children: Vec::new(),
            checked: true,
            alive: true,
        }],
        validator,
        max_step: options.max_step,
    };
    // (node, goal index): a checked, free edge from the node to the goal.
    let mut goal_links: Vec<(usize, usize)> = Vec::new();
    // The best verified path: (cost, waypoints ending at the goal, goal).
    let mut best: Option<(f64, Vec<Config>, usize)> = None;
    let mut stats = RrtStats::start();
    goal_links.extend(direct_link(start, &goals, validator).map(|g| (0, g)));
    let lower_bound = cost_lower_bound(start, &goals);
    loop {
        // The cheapest goal link whose path is still free becomes the best.
        let mut links: Vec<(f64, usize, usize)> = goal_links
            .iter()
            .filter(|&&(n, _)| tree.nodes[n].alive)
            .map(|&(n, g)| {
                (
                    tree.nodes[n].cost + distance(&tree.nodes[n].q, &goals[g].1),
                    n,
                    g,
                )
            })
            .collect();
        links.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (cost, n, g) in links {
            if best.as_ref().is_some_and(|b| b.0 <= cost) {
                break;
            }
            if tree.verify_path(n) {
                // Its cost may have changed in an earlier repair.
                let mut path = tree.path_to(n);
                path.push(goals[g].1);
                let cost = path_cost(&path);
                if best.as_ref().is_none_or(|b| cost < b.0) {
                    best = Some((cost, path, g));
                    stats.first_solution.get_or_insert(stats.iterations);
                    stats.cost_history.push((stats.iterations, cost));
                }
                break;
            }
        }
        if best.as_ref().is_some_and(|b| b.0 <= lower_bound)
            || stats
                .first_solution
                .is_some_and(|f| stats.iterations >= f + options.refine_iterations)
            || stats.iterations >= options.max_iterations
            || options.time_budget.is_some_and(|b| clock.elapsed() >= b)
        {
            break;
        }
        stats.iterations += 1;
        let target = sample(&mut rng, &goals, &bounds, options.goal_bias);
        let nearest = (0..tree.nodes.len())
            .filter(|&i| tree.nodes[i].alive)
            .min_by(|&a, &b| {
                distance(&tree.nodes[a].q, &target).total_cmp(&distance(&tree.nodes[b].q, &target))
            })
            .expect("the root is never dropped");
        let new_q = steer(&tree.nodes[nearest].q, &target, options.max_step);
        if !validator.config_valid(&new_q) || !tree.verify_path(nearest) {
            continue;
        }
        let radius = neighbour_radius(options, tree.nodes.len(), start.len());
        let near: Vec<(usize, f64)> = (0..tree.nodes.len())
            .filter(|&i| tree.nodes[i].alive)
            .map(|i| (i, distance(&tree.nodes[i].q, &new_q)))
            .filter(|&(i, d)| d <= radius || i == nearest)
            .collect();
        // The nearest node's edge is checked now (its path is verified), so
        // the node is usable at once; a cheaper parent joins unchecked.
        let &(parent, d) = near
            .iter()
            .min_by(|a, b| (tree.nodes[a.0].cost + a.1).total_cmp(&(tree.nodes[b.0].cost + b.1)))
            .expect("the nearest node is near");
        let new = tree.nodes.len();
        tree.nodes.push(Node {
            q: new_q,
            parent: None,
            cost: 0.0,
            children: Vec::new(),
            checked: false,
            alive: true,
        });
        tree.attach(new, parent, d, false);
        for &(m, d) in &near {
            if m != parent && m != 0 && tree.nodes[new].cost + d < tree.nodes[m].cost {
                tree.attach(m, new, d, false);
            }
        }
        let best_cost = best.as_ref().map_or(f64::INFINITY, |b| b.0);
        for (g, (_, goal)) in goals.iter().enumerate() {
            let d = distance(&new_q, goal);
            if d <= options.max_step
                && tree.nodes[new].cost + d < best_cost
                && tree.nodes[new].alive
                && tree.verify_path(new)
                && validator.edge_valid(&new_q, goal)
            {
                goal_links.push((new, g));
            }
        }
    }
    stats.nodes = tree.nodes.iter().filter(|n| n.alive).count();
    stats.elapsed_ms = clock.elapsed().as_secs_f64() * 1e3;
    let Some((cost, waypoints, g)) = best else {
        return Err(RrtError::NoPath {
            iterations: stats.iterations,
            elapsed_ms: stats.elapsed_ms,
        });
    };
    Ok(RrtPath {
        waypoints,
        goal: goals[g].0,
        cost,
        stats,
    })
}
