//! The closed-form fast path for any arm with Universal Robots kinematics
//! (UR3, UR5, UR10, their e-series), its DH lengths derived from the URDF.
//!
//! A UR's URDF places its frames its own way, so the chain is matched to
//! UR's DH model rather than read off it: tip(q) = B · DH(s ⊙ q + o) · F,
//! with the DH lengths that vary between models (d1, a2, a3, d4, d5, d6;
//! the twists are the same for all), each joint's direction s (±1) and
//! zero offset o (quarter turns), and the base and flange offsets B and F.
//! 1. (s, o) is chosen first from orientations alone: the rotation angle
//!    of the tip's motion from its zero pose depends on neither the lengths
//!    nor F, so every candidate is ranked by how well it explains those
//!    angles at a few random configurations;
//! 2. F's rotation follows from the motions' axes (Kabsch), B from the
//!    zero pose, and the lengths and both offsets are fitted by
//!    Levenberg–Marquardt to the chain's forward kinematics, starting from
//!    the UR5's lengths, for each tied candidate until one fits.
//!
//! The match is accepted only when it reproduces the chain to 1e-9 m and
//! rad at configurations it was not fitted on; any other arm gets `None`
//! and the numerical IK. Detection runs once, when a robot is loaded
//! (about 0.1–0.5 s).
//!
//! d1 and d6 slide along the first and last axes and trade off with B and
//! F, so the fit keeps them near the UR5's: any value reproduces the
//! chain, and the closed form only needs d6 ≠ 0.

use nalgebra::{DMatrix, DVector, Isometry3, Matrix4, Translation3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::robot::kinematics::ur_closed_form::{UR5_DH, UrDh, forward_with, solve_with, wrap};
use crate::robot::model::urdf_chain::random_configuration;
use crate::robot::model::urdf_chain::{Chain, JointKind};

/// A chain with UR kinematics: its DH lengths and the fixed offsets.
#[derive(Debug, Clone, PartialEq)]
pub struct UrKinematics {
    pub dh: UrDh,
    /// The DH base frame in the chain's base frame.
    pub base: Isometry3<f64>,
    /// The chain's tip in the DH flange frame.
    pub flange: Isometry3<f64>,
    /// DH angle = sign × joint value + offset: URDFs often put their zero
    /// pose elsewhere than DH's (a multiple of π/2 on joints 2 to 5) and
    /// turn some joints the other way.
    pub signs: [f64; 6],
    pub offsets: [f64; 6],
    limits: Vec<(f64, f64)>,
}

/// Largest position (m) or angle (rad) error accepted.
const MATCH: f64 = 1e-9;
/// Configurations fitted on, and checked on.
const FITTED: usize = 12;
const CHECKED: usize = 24;
/// Joint maps fitted at most.
const MAX_FITS: usize = 128;

fn to_iso(m: &Matrix4<f64>) -> Isometry3<f64> {
    let r = nalgebra::Rotation3::from_matrix_unchecked(m.fixed_view::<3, 3>(0, 0).into_owned());
    Isometry3::from_parts(
        Translation3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]),
        UnitQuaternion::from_rotation_matrix(&r),
    )
}

/// Pose error of `a` against `b`: translation and rotation vector.
fn pose_error(a: &Isometry3<f64>, b: &Isometry3<f64>) -> [f64; 6] {
    let t = a.translation.vector - b.translation.vector;
    let r = (b.rotation.inverse() * a.rotation).scaled_axis();
    [t.x, t.y, t.z, r.x, r.y, r.z]
}

/// Parameters: d (6), a2, a3, B (translation, rotation vector), F (same).
fn unpack(x: &DVector<f64>) -> (UrDh, Isometry3<f64>, Isometry3<f64>) {
    let mut dh = UR5_DH;
    dh.d.copy_from_slice(&x.as_slice()[0..6]);
    // Axes 2, 3 and 4 are parallel: only d2 + d3 + d4 shows, and the
    // closed form takes it all in d4.
    dh.d[1] = 0.0;
    dh.d[2] = 0.0;
    dh.a[1] = x[6];
    dh.a[2] = x[7];
    let iso = |k: usize| {
        Isometry3::from_parts(
            Translation3::new(x[k], x[k + 1], x[k + 2]),
            UnitQuaternion::from_scaled_axis(Vector3::new(x[k + 3], x[k + 4], x[k + 5])),
        )
    };
    (dh, iso(8), iso(14))
}

/// How joint values map to DH angles: (signs, offsets).
type JointMap = ([f64; 6], [f64; 6]);

fn model(x: &DVector<f64>, map: &JointMap, q: &[f64]) -> Isometry3<f64> {
    let (dh, b, f) = unpack(x);
    let q6: [f64; 6] = std::array::from_fn(|i| map.0[i] * q[i] + map.1[i]);
    b * to_iso(&forward_with(&dh, &q6)) * f
}

fn residuals(
    x: &DVector<f64>,
    map: &JointMap,
    samples: &[(Vec<f64>, Isometry3<f64>)],
) -> DVector<f64> {
    let mut r = Vec::with_capacity(samples.len() * 6 + 4);
    for (q, tip) in samples {
        r.extend(pose_error(&model(x, map, q), tip));
    }
    // Keep d1 and d6 near the UR5's: they trade off with B and F (and
    // the unused d2, d3 at zero).
    r.push(1e-3 * (x[0] - UR5_DH.d[0]));
    r.push(1e-3 * (x[5] - UR5_DH.d[5]));
    r.push(1e-3 * x[1]);
    r.push(1e-3 * x[2]);
    DVector::from_vec(r)
}

/// The chain's fitting samples with their motions: each tip's rotation
/// relative to the zero pose's (computed once, for every candidate map).
struct Samples {
    poses: Vec<(Vec<f64>, Isometry3<f64>)>,
    motions: Vec<UnitQuaternion<f64>>,
}

impl Samples {
    fn new(chain: &Chain, poses: Vec<(Vec<f64>, Isometry3<f64>)>) -> Self {
        let zero = chain.tip_pose(&[0.0; 6]).rotation.inverse();
        let motions = poses.iter().map(|(_, tip)| zero * tip.rotation).collect();
        Self { poses, motions }
    }
}

/// The DH model's tip rotation at joint values `q` under `map`.
fn model_rotation(map: &JointMap, q: &[f64]) -> UnitQuaternion<f64> {
    let q6: [f64; 6] = std::array::from_fn(|i| map.0[i] * q[i] + map.1[i]);
    to_iso(&forward_with(&UR5_DH, &q6)).rotation
}

/// The DH model's motions under `map` at the samples' joint values, each
/// relative to its zero pose (the lengths do not change rotations, so the
/// UR5's stand in).
fn model_motions<'a>(
    map: &'a JointMap,
    samples: &'a Samples,
) -> impl Iterator<Item = UnitQuaternion<f64>> + 'a {
    let zero = model_rotation(map, &[0.0; 6]).inverse();
    samples
        .poses
        .iter()
        .map(move |(q, _)| zero * model_rotation(map, q))
}

/// How far `map` is from explaining the chain's orientations: the
/// rotation angle of a motion does not depend on the lengths or on the
/// flange offset F (it conjugates the motion), so candidates are ranked
/// before anything is fitted.
fn orientation_mismatch(map: &JointMap, samples: &Samples) -> f64 {
    samples
        .motions
        .iter()
        .zip(model_motions(map, samples))
        .map(|(c, a)| (c.angle() - a.angle()).powi(2))
        .sum()
}

/// The UR5's lengths, F's rotation from the motions' axes (the chain's
/// motion is F's rotation conjugating the model's: axis_chain = R_Fᵀ
/// axis_model, solved as Kabsch's problem), B matching the zero pose.
fn start(chain: &Chain, map: &JointMap, samples: &Samples) -> DVector<f64> {
    let mut h = nalgebra::Matrix3::zeros();
    for (c, a) in samples.motions.iter().zip(model_motions(map, samples)) {
        let (Some(ca), Some(aa)) = (c.axis(), a.axis()) else {
            continue;
        };
        let w = c.angle().sin().abs();
        h += aa.into_inner() * ca.into_inner().transpose() * w;
    }
    let svd = h.svd(true, true);
    let (u, v_t) = (svd.u.unwrap_or_default(), svd.v_t.unwrap_or_default());
    let mut d = nalgebra::Matrix3::identity();
    d[(2, 2)] = (u * v_t).determinant().signum();
    // R_F maps the chain's axes onto the model's.
    let r_f = UnitQuaternion::from_matrix(&(u * d * v_t));
    let zero = [0.0; 6];
    let dh0 = to_iso(&forward_with(&UR5_DH, &map.1));
    let f0 = Isometry3::from_parts(Translation3::identity(), r_f.inverse());
    let b0 = chain.tip_pose(&zero) * (dh0 * f0).inverse();
    let mut x = DVector::zeros(20);
    x.as_mut_slice()[0..6].copy_from_slice(&UR5_DH.d);
    x[6] = UR5_DH.a[1];
    x[7] = UR5_DH.a[2];
    let (rb, tb, rf) = (
        b0.rotation.scaled_axis(),
        b0.translation.vector,
        f0.rotation.scaled_axis(),
    );
    x.as_mut_slice()[8..14].copy_from_slice(&[tb.x, tb.y, tb.z, rb.x, rb.y, rb.z]);
    x.as_mut_slice()[14..20].copy_from_slice(&[0.0, 0.0, 0.0, rf.x, rf.y, rf.z]);
    x
}

/// Levenberg–Marquardt on the pose residuals (forward-difference
/// Jacobian).
fn fit(
    mut x: DVector<f64>,
    map: &JointMap,
    samples: &[(Vec<f64>, Isometry3<f64>)],
) -> DVector<f64> {
    let mut lambda = 1e-3;
    let mut r = residuals(&x, map, samples);
    for _ in 0..200 {
        let cost = r.norm_squared();
        if cost < 1e-26 {
            break;
        }
        let h = 1e-7;
        let mut jac = DMatrix::zeros(r.len(), x.len());
        for k in 0..x.len() {
            let mut xk = x.clone();
            xk[k] += h;
            jac.set_column(k, &((residuals(&xk, map, samples) - &r) / h));
        }
        let jt = jac.transpose();
        let a = &jt * &jac;
        let g = &jt * &r;
        let mut improved = false;
        for _ in 0..10 {
            let damped = &a + DMatrix::from_diagonal(&a.diagonal().map(|v| lambda * (v + 1e-9)));
            let Some(step) = damped.lu().solve(&(-&g)) else {
                lambda *= 10.0;
                continue;
            };
            let candidate = &x + step;
            let rc = residuals(&candidate, map, samples);
            if rc.norm_squared() < cost {
                x = candidate;
                r = rc;
                lambda = (lambda / 10.0).max(1e-12);
                improved = true;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    x
}

impl UrKinematics {
    /// UR kinematics for `chain`, when it has them (see the module's
    /// documentation).
    pub fn detect(chain: &Chain) -> Option<Self> {
        let variables: Vec<_> = chain.variables().collect();
        if variables.len() != 6
            || chain.joints.iter().any(|j| j.mimic.is_some())
            || variables
                .iter()
                .any(|j| !matches!(j.kind, JointKind::Revolute | JointKind::Continuous))
        {
            return None;
        }
        let mut rng = ChaCha8Rng::seed_from_u64(0x5552);
        let mut draw = |n: usize| -> Vec<(Vec<f64>, Isometry3<f64>)> {
            (0..n)
                .map(|_| {
                    let q = random_configuration(chain, &mut rng);
                    let tip = chain.tip_pose(&q);
                    (q, tip)
                })
                .collect()
        };
        let fit_on = Samples::new(chain, draw(FITTED));
        let check_on = draw(CHECKED);
        // Offsets of joints 2 to 5 in quarter turns and the directions of
        // joints 2 to 6; joint 1's offset and the last's are absorbed by B
        // and F. The candidates are ranked by how well they explain the
        // chain's rotations (`orientation_mismatch`).
        let quarter = std::f64::consts::FRAC_PI_2;
        let mut candidates: Vec<(JointMap, f64)> = (0..256 * 32)
            .map(|code: usize| {
                let mut map: JointMap = ([1.0; 6], [0.0; 6]);
                for (k, o) in map.1[1..5].iter_mut().enumerate() {
                    *o = ((code >> (2 * k)) & 3) as f64 * quarter;
                }
                for (k, s) in map.0[1..6].iter_mut().enumerate() {
                    if (code >> (8 + k)) & 1 == 1 {
                        *s = -1.0;
                    }
                }
                let cost = orientation_mismatch(&map, &fit_on);
                (map, cost)
            })
            .collect();
        candidates.sort_by(|a, b| a.1.total_cmp(&b.1));
        // Orientation sees only θ2 + θ3 + θ4 of the parallel joints, so the
        // maps that explain it tie; each of those is fitted until one
        // reproduces the chain.
        let best = candidates.first().map_or(0.0, |c| c.1);
        candidates
            .into_iter()
            .take_while(|c| c.1 <= best + 1e-9)
            .take(MAX_FITS)
            .find_map(|(map, _)| {
                let x = fit(start(chain, &map, &fit_on), &map, &fit_on.poses);
                let worst = check_on
                    .iter()
                    .flat_map(|(q, tip)| pose_error(&model(&x, &map, q), tip))
                    .fold(0.0f64, |m, e| m.max(e.abs()));
                let (dh, base, flange) = unpack(&x);
                (worst < MATCH && dh.d[5].abs() > 1e-3).then(|| Self {
                    dh,
                    base,
                    flange,
                    signs: map.0,
                    offsets: map.1,
                    limits: chain.limits(),
                })
            })
    }

    /// The tip's pose in the chain's base frame.
    pub fn forward(&self, q: &[f64; 6]) -> Isometry3<f64> {
        let q: [f64; 6] = std::array::from_fn(|i| self.signs[i] * q[i] + self.offsets[i]);
        self.base * to_iso(&forward_with(&self.dh, &q)) * self.flange
    }

    /// Every solution for the tip pose `goal` (chain base frame) inside the
    /// joint limits, each joint the 2π-equivalent nearest `reference`,
    /// nearest `reference` first.
    pub fn solve(&self, goal: &Isometry3<f64>, reference: &[f64; 6]) -> Vec<[f64; 6]> {
        let t06 = (self.base.inverse() * goal * self.flange.inverse()).to_homogeneous();
        let dh_reference: [f64; 6] =
            std::array::from_fn(|i| self.signs[i] * reference[i] + self.offsets[i]);
        let mut out: Vec<[f64; 6]> = solve_with(&self.dh, &t06, &dh_reference)
            .iter()
            .map(|q| -> [f64; 6] {
                std::array::from_fn(|i| self.signs[i] * (q[i] - self.offsets[i]))
            })
            .filter_map(|q| {
                let mut near = [0.0; 6];
                for i in 0..6 {
                    let (lo, hi) = self.limits[i];
                    let base = reference[i] + wrap(q[i] - reference[i]);
                    let pick = [
                        base,
                        base - std::f64::consts::TAU,
                        base + std::f64::consts::TAU,
                    ]
                    .into_iter()
                    .filter(|c| *c >= lo && *c <= hi)
                    .min_by(|a, b| {
                        (a - reference[i])
                            .abs()
                            .total_cmp(&(b - reference[i]).abs())
                    })?;
                    near[i] = pick;
                }
                Some(near)
            })
            .collect();
        let distance = |q: &[f64; 6]| {
            q.iter()
                .zip(reference)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
        };
        out.sort_by(|a, b| distance(a).total_cmp(&distance(b)));
        out
    }
}
