//! Shortcut smoothing of a planned path.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::robot::motion::rrt::problem::{Config, MotionValidator};

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
