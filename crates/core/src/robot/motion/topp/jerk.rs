//! Jerk limits on a TOPP-RA timing. TOPP-RA's path acceleration s̈ is
//! piecewise constant, so the joints' acceleration jumps wherever it
//! switches (from accelerating to cruising, say): the jerk is unbounded,
//! and a controller that limits jerk (Franka's) rejects the motion.
//!
//! The fix here is a moving average of the path parameter over a window
//! T, the FIR filter of CNC interpolators:
//! s_T(t) = (1/T) ∫_{t−T}^{t} s(τ) dτ. Its derivatives are differences of
//! the original's, ṡ_T = (s(t) − s(t−T))/T, s̈_T = (ṡ(t) − ṡ(t−T))/T and
//! s⃛_T = (s̈(t) − s̈(t−T))/T, so the path is unchanged, the acceleration
//! becomes continuous and the jerk bounded by 2·max|s̈|/T, at the price of
//! T more seconds. T is chosen so the largest acceleration swing of any
//! joint, 2aⱼ, is spread over aⱼ's ramp time at its jerk limit (2aⱼ/jⱼ).
//! Averaging keeps ṡ and s̈ within the ranges they had, but the joints'
//! limits vary along the path and the path's own curvature adds jerk, so
//! the result is checked at every switching time (both sides) and between
//! them; if anything is over, the whole motion is slowed by a factor k
//! (velocities /k, accelerations /k², jerks /k³) until it is not.

use nalgebra::DVector;

use crate::robot::motion::topp::{LIMIT_SHARE, TimedPath};

/// A [`TimedPath`] with its path parameter averaged over a window (or as
/// it is, when no jerk limit is given) and stretched in time.
#[derive(Debug, Clone)]
pub struct JerkLimited {
    timed: TimedPath,
    /// Averaging window T (s); 0 when the timing has no jerk limit.
    window: f64,
    /// Time stretch k ≥ 1.
    stretch: f64,
    /// ∫₀^{t_k} s dτ at every grid time t_k of `timed`.
    integral: Vec<f64>,
}

impl JerkLimited {
    /// `timed` as it is: TOPP-RA's motion, its jerk unbounded.
    pub fn unlimited(timed: TimedPath) -> Self {
        Self {
            timed,
            window: 0.0,
            stretch: 1.0,
            integral: Vec::new(),
        }
    }

    /// `timed` made jerk-limited: averaged, then slowed until every joint
    /// keeps `vmax`, `amax` and `jmax` (planned to [`LIMIT_SHARE`]).
    pub fn new(timed: TimedPath, vmax: &[f64], amax: &[f64], jmax: &[f64]) -> Self {
        let window = amax
            .iter()
            .zip(jmax)
            .map(|(a, j)| 2.0 * a / j)
            .fold(0.0, f64::max);
        let mut integral = vec![0.0; timed.t.len()];
        for k in 0..timed.t.len() - 1 {
            let dt = timed.t[k + 1] - timed.t[k];
            let u = timed.path_acceleration(k);
            integral[k + 1] = integral[k]
                + timed.s[k] * dt
                + timed.speed[k] * dt * dt / 2.0
                + u * dt * dt * dt / 6.0;
        }
        let mut out = Self {
            timed,
            window,
            stretch: 1.0,
            integral,
        };
        let (v, a, j) = out.peak_ratios(vmax, amax, jmax);
        out.stretch = [
            1.0,
            v / LIMIT_SHARE,
            (a / LIMIT_SHARE).sqrt(),
            (j / LIMIT_SHARE).cbrt(),
        ]
        .into_iter()
        .fold(f64::NAN, f64::max);
        out
    }

    pub fn duration(&self) -> f64 {
        (self.timed.duration() + self.window) * self.stretch
    }

    /// ∫₀^τ s of the unaveraged timing (s = 0 before it starts, its length
    /// after it ends).
    fn integral_at(&self, tau: f64) -> f64 {
        let timed = &self.timed;
        if tau <= 0.0 {
            return 0.0;
        }
        let end = timed.duration();
        if tau >= end {
            return self.integral.last().unwrap() + timed.path.length() * (tau - end);
        }
        let k = timed.interval(tau);
        let d = tau - timed.t[k];
        let u = timed.path_acceleration(k);
        self.integral[k] + timed.s[k] * d + timed.speed[k] * d * d / 2.0 + u * d * d * d / 6.0
    }

    /// (s, ṡ, s̈, s⃛) at time `t` of this motion.
    fn path_state(&self, t: f64) -> [f64; 4] {
        let k = self.stretch;
        let tau = t / k;
        if self.window == 0.0 {
            let (s, v, a) = self.timed.path_state(tau);
            return [s, v, a, 0.0];
        }
        let w = self.window;
        let length = self.timed.path.length();
        if tau >= self.timed.duration() + w {
            return [length, 0.0, 0.0, 0.0];
        }
        let (now, before) = (self.timed.path_state(tau), self.timed.path_state(tau - w));
        let s = ((self.integral_at(tau) - self.integral_at(tau - w)) / w).clamp(0.0, length);
        [
            s,
            (now.0 - before.0) / w / k,
            (now.1 - before.1) / w / (k * k),
            (now.2 - before.2) / w / (k * k * k),
        ]
    }

    /// Position, velocity and acceleration at time `t` (clamped to the
    /// motion).
    pub fn sample(&self, t: f64) -> (DVector<f64>, DVector<f64>, DVector<f64>) {
        if self.window == 0.0 && self.stretch == 1.0 {
            return self.timed.sample(t);
        }
        let [s, v, a, _] = self.path_state(t.clamp(0.0, self.duration()));
        let (q, dq, ddq) = self.timed.path.eval(s);
        let velocity = &dq * v;
        let acceleration = &ddq * (v * v) + &dq * a;
        (q, velocity, acceleration)
    }

    /// The joints' velocity, acceleration and jerk at time `t`.
    pub fn derivatives(&self, t: f64) -> [DVector<f64>; 3] {
        let [s, v, a, j] = self.path_state(t.clamp(0.0, self.duration()));
        let (_, dq, ddq) = self.timed.path.eval(s);
        let dddq = self.timed.path.third(s);
        [
            &dq * v,
            &ddq * (v * v) + &dq * a,
            &dddq * (v * v * v) + &ddq * (3.0 * v * a) + &dq * j,
        ]
    }

    /// The largest share of the velocity, acceleration and jerk limits any
    /// joint reaches: checked on both sides of every time where s̈ of the
    /// original or of its delayed copy switches, and halfway between.
    fn peak_ratios(&self, vmax: &[f64], amax: &[f64], jmax: &[f64]) -> (f64, f64, f64) {
        let grid = &self.timed.t;
        let mut times: Vec<f64> = grid
            .iter()
            .copied()
            .chain(grid.iter().map(|t| t + self.window))
            .collect();
        times.sort_by(f64::total_cmp);
        times.dedup();
        let epsilon = 1e-9;
        let mut probes = Vec::with_capacity(times.len() * 3);
        for pair in times.windows(2) {
            probes.extend([
                pair[0] + epsilon,
                (pair[0] + pair[1]) / 2.0,
                pair[1] - epsilon,
            ]);
        }
        let scale = self.stretch;
        let (mut v, mut a, mut j): (f64, f64, f64) = (0.0, 0.0, 0.0);
        for tau in probes {
            let [dv, da, dj] = self.derivatives(tau * scale);
            for i in 0..dv.len() {
                v = v.max(dv[i].abs() / vmax[i]);
                a = a.max(da[i].abs() / amax[i]);
                j = j.max(dj[i].abs() / jmax[i]);
            }
        }
        (v, a, j)
    }
}
