//! The textbook RRT* (every edge checked as it is added), and the entry
//! point that hands lazy planning to [`crate::robot::motion::rrt::lazy`].

use std::time::Instant;

use crate::robot::motion::rrt::lazy;
use crate::robot::motion::rrt::problem::{
    Config, MotionValidator, RrtError, RrtPath, RrtStarOptions, RrtStats, Sampler,
    cost_lower_bound, direct_link, distance, neighbour_radius, sample, steer,
};

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
    let clock = Instant::now();
    let sampler = Sampler::new(start, goals, validator, options)?;
    if options.lazy {
        return lazy::rrt_star(start, sampler, validator, options, clock);
    }
    let Sampler {
        goals,
        mut rng,
        bounds,
    } = sampler;
    let mut nodes = vec![Node {
        q: *start,
        parent: None,
        cost: 0.0,
        children: Vec::new(),
    }];
    // (node, index into `goals`): a free edge from the node to that goal.
    let mut goal_links: Vec<(usize, usize)> = Vec::new();
    let mut stats = RrtStats::start();
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
