//! Time-optimal timing of a joint path under per-joint velocity and
//! acceleration limits, for any number of joints: the path through the
//! waypoints is a clamped cubic spline in a chord-length parameter s (it
//! starts and ends at rest and does not stop at the waypoints between), and
//! its timing is TOPP-RA (Pham & Pham, "A New Approach to Time-Optimal Path
//! Parameterization Based on Reachability Analysis", IEEE T-RO 2018): on a
//! grid of s, a backward pass computes at every grid point the interval of
//! squared path speeds ṡ² from which the end can still be reached at rest,
//! and a forward pass takes the largest path acceleration that stays inside
//! them. With box limits each stage is a two-variable linear program, solved
//! here by enumerating its vertices; each stage holds the constraints of
//! both ends of its interval.

use nalgebra::DVector;

pub mod jerk;

/// A C² path through joint-space waypoints: per joint a cubic spline in s,
/// the cumulative chord length between waypoints, with zero slope at both
/// ends (so the path starts and ends at rest).
#[derive(Debug, Clone)]
pub struct SplinePath {
    /// Knots s_0 = 0 < s_1 < … (rad or m of joint-space chord).
    pub knots: Vec<f64>,
    /// Per knot, the waypoint.
    points: Vec<DVector<f64>>,
    /// Per knot, the second derivative d²q/ds².
    second: Vec<DVector<f64>>,
}

impl SplinePath {
    /// The spline through `waypoints` (consecutive duplicates dropped);
    /// `None` with fewer than two distinct waypoints.
    pub fn new(waypoints: &[Vec<f64>]) -> Option<Self> {
        let mut points: Vec<DVector<f64>> = Vec::new();
        for w in waypoints {
            let p = DVector::from_column_slice(w);
            if points.last().is_none_or(|q| (q - &p).norm() > 1e-12) {
                points.push(p);
            }
        }
        if points.len() < 2 {
            return None;
        }
        let mut knots = vec![0.0];
        for pair in points.windows(2) {
            knots.push(knots.last().unwrap() + (&pair[1] - &pair[0]).norm());
        }
        let n = points.len();
        let dim = points[0].len();
        // Clamped spline: solve the tridiagonal system for the second
        // derivatives M (Thomas algorithm), end slopes zero.
        let h: Vec<f64> = knots.windows(2).map(|k| k[1] - k[0]).collect();
        let mut diag = vec![0.0; n];
        let mut upper = vec![0.0; n];
        let mut lower = vec![0.0; n];
        let mut rhs: Vec<DVector<f64>> = vec![DVector::zeros(dim); n];
        diag[0] = 2.0 * h[0];
        upper[0] = h[0];
        rhs[0] = (&points[1] - &points[0]) * (6.0 / h[0]);
        for i in 1..n - 1 {
            lower[i] = h[i - 1];
            diag[i] = 2.0 * (h[i - 1] + h[i]);
            upper[i] = h[i];
            rhs[i] = (&points[i + 1] - &points[i]) * (6.0 / h[i])
                - (&points[i] - &points[i - 1]) * (6.0 / h[i - 1]);
        }
        lower[n - 1] = h[n - 2];
        diag[n - 1] = 2.0 * h[n - 2];
        rhs[n - 1] = -(&points[n - 1] - &points[n - 2]) * (6.0 / h[n - 2]);
        for i in 1..n {
            let m = lower[i] / diag[i - 1];
            diag[i] -= m * upper[i - 1];
            let previous = rhs[i - 1].clone();
            rhs[i] -= previous * m;
        }
        let mut second = vec![DVector::zeros(dim); n];
        second[n - 1] = &rhs[n - 1] / diag[n - 1];
        for i in (0..n - 1).rev() {
            second[i] = (&rhs[i] - &second[i + 1] * upper[i]) / diag[i];
        }
        Some(Self {
            knots,
            points,
            second,
        })
    }

    pub fn length(&self) -> f64 {
        *self.knots.last().unwrap()
    }

    /// The knot interval holding `s` (already clamped to the path).
    fn interval(&self, s: f64) -> usize {
        match self.knots.binary_search_by(|k| k.total_cmp(&s)) {
            Ok(i) => i.min(self.knots.len() - 2),
            Err(i) => i.saturating_sub(1).min(self.knots.len() - 2),
        }
    }

    /// q‴(s): constant on each knot interval (the path is a cubic there).
    pub fn third(&self, s: f64) -> DVector<f64> {
        let i = self.interval(s.clamp(0.0, self.length()));
        (&self.second[i + 1] - &self.second[i]) / (self.knots[i + 1] - self.knots[i])
    }

    /// q(s), q′(s), q″(s).
    pub fn eval(&self, s: f64) -> (DVector<f64>, DVector<f64>, DVector<f64>) {
        let s = s.clamp(0.0, self.length());
        let i = self.interval(s);
        let h = self.knots[i + 1] - self.knots[i];
        let (a, b) = (self.knots[i + 1] - s, s - self.knots[i]);
        let (m0, m1) = (&self.second[i], &self.second[i + 1]);
        let (p0, p1) = (&self.points[i], &self.points[i + 1]);
        // At a knot the waypoint itself, bit for bit (a trajectory begins
        // exactly at its start configuration).
        let q = if b == 0.0 {
            p0.clone()
        } else if a == 0.0 {
            p1.clone()
        } else {
            m0 * (a.powi(3) / (6.0 * h))
                + m1 * (b.powi(3) / (6.0 * h))
                + (p0 - m0 * (h * h / 6.0)) * (a / h)
                + (p1 - m1 * (h * h / 6.0)) * (b / h)
        };
        let dq = -m0 * (a * a / (2.0 * h)) + m1 * (b * b / (2.0 * h)) + (p1 - p0) / h
            - (m1 - m0) * (h / 6.0);
        let ddq = m0 * (a / h) + m1 * (b / h);
        (q, dq, ddq)
    }
}

/// A path timed by [`time_optimal`].
#[derive(Debug, Clone)]
pub struct TimedPath {
    pub path: SplinePath,
    /// Grid of s and, per grid point, the time and ṡ.
    pub s: Vec<f64>,
    pub t: Vec<f64>,
    pub speed: Vec<f64>,
}

impl TimedPath {
    pub fn duration(&self) -> f64 {
        *self.t.last().unwrap()
    }

    /// The grid interval holding time `t` (already clamped).
    fn interval(&self, t: f64) -> usize {
        match self.t.binary_search_by(|v| v.total_cmp(&t)) {
            Ok(k) => k.min(self.t.len() - 2),
            Err(k) => k.saturating_sub(1).min(self.t.len() - 2),
        }
    }

    /// Path acceleration s̈ on grid interval `k` (constant there).
    fn path_acceleration(&self, k: usize) -> f64 {
        let dt = self.t[k + 1] - self.t[k];
        if dt > 0.0 {
            (self.speed[k + 1] - self.speed[k]) / dt
        } else {
            0.0
        }
    }

    /// Path position, speed and acceleration (s, ṡ, s̈) at time `t`; at
    /// rest at the start before 0 and at the end after the duration.
    pub fn path_state(&self, t: f64) -> (f64, f64, f64) {
        if t <= 0.0 {
            return (0.0, 0.0, 0.0);
        }
        if t >= self.duration() {
            return (*self.s.last().unwrap(), 0.0, 0.0);
        }
        self.state_within(t)
    }

    /// (s, ṡ, s̈) at a time `t` within the trajectory, from its grid
    /// interval (the path acceleration constant there).
    fn state_within(&self, t: f64) -> (f64, f64, f64) {
        let k = self.interval(t);
        let u = self.path_acceleration(k);
        let tau = t - self.t[k];
        let s = (self.s[k] + self.speed[k] * tau + 0.5 * u * tau * tau).min(self.s[k + 1]);
        (s, self.speed[k] + u * tau, u)
    }

    /// Position, velocity and acceleration at time `t` (clamped to the
    /// trajectory): within a grid interval the path acceleration is
    /// constant, as the timing assumes.
    pub fn sample(&self, t: f64) -> (DVector<f64>, DVector<f64>, DVector<f64>) {
        let (s, speed, u) = self.state_within(t.clamp(0.0, self.duration()));
        let (q, dq, ddq) = self.path.eval(s);
        let v = &dq * speed;
        let a = &ddq * (speed * speed) + &dq * u;
        (q, v, a)
    }
}

/// The largest and smallest x over the polygon {(x, u) : a·x + b·u ≤ c for
/// every row}, or `None` when it is empty.
fn x_range(rows: &[(f64, f64, f64)]) -> Option<(f64, f64)> {
    let feasible = |x: f64, u: f64| rows.iter().all(|(a, b, c)| a * x + b * u <= c + 1e-9);
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (i, r1) in rows.iter().enumerate() {
        for r2 in &rows[i + 1..] {
            let det = r1.0 * r2.1 - r1.1 * r2.0;
            if det.abs() < 1e-14 {
                continue;
            }
            let x = (r1.2 * r2.1 - r1.1 * r2.2) / det;
            let u = (r1.0 * r2.2 - r1.2 * r2.0) / det;
            if feasible(x, u) {
                lo = lo.min(x);
                hi = hi.max(x);
            }
        }
    }
    (lo <= hi).then_some((lo, hi))
}

/// The constraint rows of grid point `i` in (x = ṡ², u = s̈):
/// |q′ⱼ|² x ≤ vⱼ², −aⱼ ≤ q′ⱼ u + q″ⱼ x ≤ aⱼ, x ≥ 0.
fn rows_at(
    dq: &DVector<f64>,
    ddq: &DVector<f64>,
    vmax: &[f64],
    amax: &[f64],
) -> Vec<(f64, f64, f64)> {
    let mut rows = vec![(-1.0, 0.0, 0.0)];
    for j in 0..dq.len() {
        rows.push((dq[j] * dq[j], 0.0, vmax[j] * vmax[j]));
        rows.push((ddq[j], dq[j], amax[j]));
        rows.push((-ddq[j], -dq[j], amax[j]));
    }
    rows
}

/// Share of each limit the timing plans to. Constraints hold at the grid
/// points; between them the joints' acceleration can exceed its value
/// there by a little (up to 0.27 % on 1000-interval grids of random 6- and
/// 7-joint paths, measured by finite differences), so the timing keeps 1 %
/// in hand and a trajectory is never over a limit.
pub const LIMIT_SHARE: f64 = 0.99;

/// TOPP-RA on `grid` intervals of `path`, from rest to rest, within
/// `vmax` and `amax` per joint (planned to [`LIMIT_SHARE`] of them); `None`
/// if the limits admit no motion.
pub fn time_optimal(
    path: SplinePath,
    vmax: &[f64],
    amax: &[f64],
    grid: usize,
) -> Option<TimedPath> {
    let vmax: Vec<f64> = vmax.iter().map(|v| v * LIMIT_SHARE).collect();
    let amax: Vec<f64> = amax.iter().map(|a| a * LIMIT_SHARE).collect();
    let (vmax, amax) = (vmax.as_slice(), amax.as_slice());
    let n = grid.max(2);
    let s: Vec<f64> = (0..=n)
        .map(|i| path.length() * i as f64 / n as f64)
        .collect();
    let at_points: Vec<Vec<(f64, f64, f64)>> = s
        .iter()
        .map(|&si| {
            let (_, dq, ddq) = path.eval(si);
            rows_at(&dq, &ddq, vmax, amax)
        })
        .collect();
    // Stage i's constraints on (x_i, u_i): grid point i's, and grid point
    // i + 1's with x_{i+1} = x_i + 2Δu_i (TOPP-RA's "interpolation"
    // discretization). Checking the end of every interval as well as its
    // start matters where the path's slope q′ vanishes (at rest, at the
    // ends): there a point constraint leaves the path acceleration free and
    // the joints would overshoot their acceleration inside the interval.
    let rows: Vec<Vec<(f64, f64, f64)>> = (0..=n)
        .map(|i| {
            let mut r = at_points[i].clone();
            if i < n {
                let delta = s[i + 1] - s[i];
                r.extend(
                    at_points[i + 1]
                        .iter()
                        .map(|&(a, b, c)| (a, 2.0 * delta * a + b, c)),
                );
            }
            r
        })
        .collect();
    // Backward: the controllable interval of x at every grid point.
    let mut reach = vec![(0.0, 0.0); n + 1];
    for i in (0..n).rev() {
        let delta = s[i + 1] - s[i];
        let (lo, hi) = reach[i + 1];
        let mut r = rows[i].clone();
        r.push((1.0, 2.0 * delta, hi));
        r.push((-1.0, -2.0 * delta, -lo));
        reach[i] = x_range(&r)?;
    }
    if reach[0].0 > 1e-12 {
        return None;
    }
    // Forward: the greatest path acceleration that stays controllable.
    let mut x = vec![0.0; n + 1];
    for i in 0..n {
        let delta = s[i + 1] - s[i];
        let (mut u_lo, mut u_hi) = (f64::NEG_INFINITY, f64::INFINITY);
        for &(a, b, c) in &rows[i] {
            let rest = c - a * x[i];
            if b > 1e-14 {
                u_hi = u_hi.min(rest / b);
            } else if b < -1e-14 {
                u_lo = u_lo.max(rest / b);
            }
        }
        let (lo, hi) = reach[i + 1];
        u_hi = u_hi.min((hi - x[i]) / (2.0 * delta));
        u_lo = u_lo.max((lo - x[i]) / (2.0 * delta));
        let u = if u_hi >= u_lo { u_hi } else { u_lo };
        x[i + 1] = (x[i] + 2.0 * delta * u).clamp(lo.max(0.0), hi.max(0.0));
    }
    let speed: Vec<f64> = x.iter().map(|v| v.max(0.0).sqrt()).collect();
    let mut t = vec![0.0; n + 1];
    for i in 0..n {
        let mean = speed[i] + speed[i + 1];
        if mean <= 0.0 {
            return None;
        }
        t[i + 1] = t[i] + 2.0 * (s[i + 1] - s[i]) / mean;
    }
    Some(TimedPath { path, s, t, speed })
}
