//! Where an arm should stand for a straight push: the stand-offs and
//! heights a mobile base tries, found from the arm's own kinematics.
//!
//! The paper's UR5 pushes well from 0.5-0.65 m behind the grip point at
//! most heights, and other arms used to get those distances scaled by their
//! reach. A 7-joint arm with a spherical shoulder and wrist (KUKA's iiwa,
//! Franka's Panda) is different: its elbow angle is fixed by the
//! shoulder-to-wrist distance, so standing close folds the elbow against
//! its limit partway through the push. From its UR5-scaled stance, 0.47 m
//! behind and 0.28 m below the grip, the iiwa carries out none of the test
//! pushes below; every stance it keeps carries out at least two thirds.
//!
//! So each arm scores a grid of stances ([`STAND_OFFS`] × [`HEIGHTS`],
//! scaled by its reach) by the share of [`PROBE_PUSHES`] test pushes (the
//! tool level, tilted up or down, turned left or right, its slot upright or
//! level, either way round) whose pre-contact pose has an IK solution from which the
//! straight push stays on one branch, as the planner's push check asks (no
//! tree: kinematics only), and keeps the best [`STANCES`], then more while
//! they carry out test pushes none kept does ([`keep_stances`]). Ties keep
//! the UR5's own stances first, so arms that reach everywhere (the URs)
//! stand where the UR5 always has. The scores are computed once per arm, on the
//! first base-region plan (about 0.2 s for a 7-joint arm).

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

use crate::robot::arm::Arm;
use crate::robot::arm::base::BaseStance;
use crate::robot::arm::tool_line::{APPROACH_OFFSET, either_way_round, push_line};
use crate::robot::model::joint_vector::JointVector;

/// The built-in UR5's [`Arm::reach`] (m): the distances below are for it,
/// and other arms scale them by their reach.
pub const UR5_REACH: f64 = 1.079_103_269_666_350_5;
/// Stand-offs tried (m, UR5 scale). The UR5's own are 0.5 and 0.65.
pub const STAND_OFFS: [f64; 4] = [0.5, 0.65, 0.35, 0.8];
/// Grip heights above the base tried (m, UR5 scale). The UR5's own are 0.3,
/// 0.05 and −0.2 (the last, a base above the grip reaching down, serves
/// 7-joint arms).
pub const HEIGHTS: [f64; 4] = [0.3, 0.05, -0.2, 0.55];
/// Stances kept per arm.
pub const STANCES: usize = 6;
/// Test pushes per stance: 3 tilts × 3 turns × 2 slot orientations.
pub const PROBE_PUSHES: usize = 18;
/// How far each test push goes past contact (m): a typical push.
const PROBE_PUSH: f64 = 0.15;

/// The grid in the order ties are broken: the UR5's six stances first
/// (heights outermost, as it always tried them), then the rest.
fn candidates(scale: f64) -> Vec<BaseStance> {
    let mut out = Vec::new();
    for own in [true, false] {
        for (h, &height) in HEIGHTS.iter().enumerate() {
            for (s, &stand_off) in STAND_OFFS.iter().enumerate() {
                if (h < 3 && s < 2) == own {
                    out.push(BaseStance {
                        stand_off: stand_off * scale,
                        height: height * scale,
                    });
                }
            }
        }
    }
    out
}

/// The test pushes' tool orientations for a grip straight ahead (+x):
/// tool z along the push, x along the branch.
fn probe_rotations() -> Vec<UnitQuaternion<f64>> {
    let mut out = Vec::with_capacity(PROBE_PUSHES);
    for tilt in [-0.5f64, 0.0, 0.5] {
        for turn in [-0.4f64, 0.0, 0.4] {
            for roll in [0.0, std::f64::consts::FRAC_PI_2] {
                let z = Vector3::new(tilt.cos() * turn.cos(), tilt.cos() * turn.sin(), tilt.sin());
                let up = (Vector3::z() - z * z.z).normalize();
                let side = z.cross(&up);
                let x = up * f64::cos(roll) + side * f64::sin(roll);
                let y = z.cross(&x);
                out.push(UnitQuaternion::from_rotation_matrix(
                    &Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z])),
                ));
            }
        }
    }
    out
}

impl Arm {
    /// The stances a mobile base tries for this arm, best first (see the
    /// module's documentation); computed on the first call.
    pub fn stances(&self) -> &[BaseStance] {
        &self.kept_stances().0
    }

    /// How many of the [`PROBE_PUSHES`] test pushes one of
    /// [`Self::stances`] carries out: all of them for an arm that pushes
    /// every way from where it stands (every 6-7 joint arm of
    /// `example-robot-data` and `pybullet_data` but the Unitree Z1, whose
    /// narrow wrist leaves 4).
    pub fn stance_coverage(&self) -> usize {
        self.kept_stances().1.count_ones() as usize
    }

    fn kept_stances(&self) -> &(Vec<BaseStance>, u32) {
        self.stances.get_or_init(|| {
            let scale = self.reach() / UR5_REACH;
            let candidates: Vec<(u32, BaseStance)> = candidates(scale)
                .into_iter()
                .map(|s| (self.push_mask(&s), s))
                .collect();
            keep_stances(candidates)
        })
    }

    /// How many of the [`PROBE_PUSHES`] test pushes this arm can carry
    /// out from `stance` (base upright at its own pose, facing +x).
    pub fn push_score(&self, stance: &BaseStance) -> usize {
        self.push_mask(stance).count_ones() as usize
    }

    /// As [`Self::push_score`], with every configuration of the push (the
    /// pre-contact one included) also passing `valid` (a collision check,
    /// say).
    pub fn push_score_with(
        &self,
        stance: &BaseStance,
        valid: &dyn Fn(&JointVector, &JointVector, f64) -> bool,
    ) -> usize {
        self.push_mask_with(stance, valid).count_ones() as usize
    }

    /// Which of the test pushes (bit k: the k-th of [`PROBE_PUSHES`])
    /// the arm carries out from `stance`, kinematically.
    pub fn push_mask(&self, stance: &BaseStance) -> u32 {
        self.push_mask_with(stance, &|_: &JointVector, _: &JointVector, _: f64| true)
    }

    /// As [`Self::push_mask`], each configuration also passing `valid`.
    fn push_mask_with(
        &self,
        stance: &BaseStance,
        valid: &dyn Fn(&JointVector, &JointVector, f64) -> bool,
    ) -> u32 {
        let home = self.home();
        let grip = Vector3::new(stance.stand_off, 0.0, stance.height);
        let mut mask = 0;
        for (k, rotation) in probe_rotations().iter().enumerate() {
            let z = rotation * Vector3::z();
            let start = self.base
                * Isometry3::from_parts(Translation3::from(grip - z * APPROACH_OFFSET), *rotation);
            let direction = self.base.rotation * z;
            let carried = either_way_round(start).iter().any(|pose| {
                self.ik_solutions(pose, &home).any(|q| {
                    valid(&q, &q, 0.0)
                        && push_line(self, valid, &q, &direction, PROBE_PUSH + APPROACH_OFFSET)
                            .is_some()
                })
            });
            if carried {
                mask |= 1 << k;
            }
        }
        mask
    }
}

/// The best [`STANCES`] by score (ties in the candidates' order), then,
/// while some test push that a candidate carries out is carried out by
/// none kept, the candidate adding most of them: an arm that pushes in
/// every direction from one stance (a UR) keeps the six best, and an arm
/// with a narrow workspace (the Unitree Z1 pushes level from one height
/// and up or down from others) also keeps a stance for each direction.
/// Returns the stances kept and the test pushes they carry out.
fn keep_stances(mut scored: Vec<(u32, BaseStance)>) -> (Vec<BaseStance>, u32) {
    // Stable: equal scores keep the candidates' order.
    scored.sort_by_key(|s| std::cmp::Reverse(s.0.count_ones()));
    let mut rest = scored.split_off(STANCES.min(scored.len()));
    let mut covered = scored.iter().fold(0, |m, s| m | s.0);
    loop {
        let best = rest
            .iter()
            .enumerate()
            .map(|(i, s)| (i, (s.0 & !covered).count_ones()))
            .filter(|(_, gain)| *gain > 0)
            .max_by_key(|&(i, gain)| (gain, std::cmp::Reverse(i)));
        let Some((i, _)) = best else {
            break;
        };
        let s = rest.remove(i);
        covered |= s.0;
        scored.push(s);
    }
    (scored.into_iter().map(|(_, s)| s).collect(), covered)
}
