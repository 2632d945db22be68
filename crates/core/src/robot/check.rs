//! `check`: what a user should know of an arm before planning with it
//! (`treemanip robot check SPEC`): its chain, its tool frame, its reach and
//! limits, how much of its joint space is free of self-collision (and which
//! pairs block the rest), whether IK finds reachable poses, and how many of
//! the stance test pushes its best stance carries out, kinematically and
//! with a collision-free arm. Plain warnings name what will stop it from
//! pushing; [`CheckReport::fatal`] says when it cannot plan at all.

use std::collections::BTreeMap;
use std::fmt;

use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::robot::arm::{Arm, BaseStance, PROBE_PUSHES};
use crate::robot::collision::{Allowed, CollisionModel, TreeObstacles};
use crate::robot::model::joint_vector::JointVector;
use crate::robot::model::urdf_chain::random_configuration;

/// Random configurations sampled for the self-collision share.
pub const SAMPLES: usize = 2000;
/// Random reachable tool poses tried for IK.
pub const IK_POSES: usize = 200;
/// A pair in contact in more than this share of the samples is named.
const NAMED_PAIR_SHARE: f64 = 0.05;

/// What [`check`] found.
#[derive(Debug, Clone)]
pub struct CheckReport {
    pub name: String,
    pub dof: usize,
    pub base_link: String,
    pub tip_link: String,
    /// Per joint: name, kind, lower, upper, velocity (rad or m, per s).
    pub joints: Vec<(String, &'static str, f64, f64, f64)>,
    /// The tool frame in the tip link's frame, and how it was chosen.
    pub tool_in_tip: Isometry3<f64>,
    pub tool_chosen: String,
    /// At home, the cosine between the tool's push axis (z) and the
    /// direction from the last joint's axis to the tool: near 1 the tool
    /// points out of the wrist, below 0 back into the arm (`None` when the
    /// tool sits on the last joint's axis point).
    pub tool_outward: Option<f64>,
    /// [`Arm::reach`] (m).
    pub reach: f64,
    /// Share of [`SAMPLES`] random configurations free of self-collision.
    pub self_free: f64,
    /// Checked pairs in contact in more than 5 % of the samples, with
    /// their share, most often first.
    pub frequent_pairs: Vec<(String, String, f64)>,
    /// Self-collision pairs in contact at the home configuration, and
    /// what else it hits at the default mount (the ground).
    pub home_contacts: Vec<(String, String)>,
    pub home_hit: Option<String>,
    /// IK on random reachable poses: solved, tried.
    pub ik: (usize, usize),
    /// The best stance and how many of its [`PROBE_PUSHES`] test pushes
    /// are carried out kinematically, and with every configuration of the
    /// push free of self-collision and of the ground.
    pub stance: Option<BaseStance>,
    pub pushes_kinematic: usize,
    pub pushes_free: usize,
    /// The stances a mobile base tries ([`Arm::stances`]) and how many of
    /// the test pushes one of them carries out (kinematics).
    pub stances: usize,
    pub pushes_any_stance: usize,
    pub warnings: Vec<String>,
}

impl CheckReport {
    /// Why the arm cannot plan at all, if it cannot.
    pub fn fatal(&self) -> Option<String> {
        if let Some(c) = self.tool_outward.filter(|&c| c < -0.5) {
            return Some(format!(
                "the tool's push axis points back into the arm (cosine {c:.2} with the direction out of the wrist): name the tool frame (`tool=FRAME`, `tool_rpy=`) or another tip"
            ));
        }
        if self.self_free == 0.0 {
            return Some(
                "every sampled configuration is in self-collision: no motion can be planned"
                    .to_owned(),
            );
        }
        if self.pushes_free == 0 {
            return Some(format!(
                "none of the {PROBE_PUSHES} test pushes in front of the arm can be carried out without a collision: it cannot push"
            ));
        }
        None
    }
}

/// Checks `arm` at its default mount: `samples` random configurations for
/// self-collision, [`IK_POSES`] poses for IK, all drawn with `seed`.
pub fn check(arm: &Arm, samples: usize, seed: u64) -> CheckReport {
    let arm = arm.clone().with_base(arm.default_base());
    let model = CollisionModel::new(arm.clone());
    let robot = &model.robot;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut free = 0usize;
    let mut counts: BTreeMap<(String, String), usize> = BTreeMap::new();
    let mut solvable: Vec<JointVector> = Vec::new();
    for _ in 0..samples {
        let q = random_configuration(robot.chain(), &mut rng);
        let contacts = model.self_contacts(&q);
        if contacts.is_empty() {
            free += 1;
            if solvable.len() < IK_POSES {
                solvable.push(JointVector::from_slice(&q));
            }
        }
        for (a, b) in contacts {
            *counts.entry((a.to_owned(), b.to_owned())).or_default() += 1;
        }
    }
    let share = |n: usize| n as f64 / samples.max(1) as f64;
    let mut frequent_pairs: Vec<(String, String, f64)> = counts
        .into_iter()
        .map(|((a, b), n)| (a, b, share(n)))
        .filter(|p| p.2 > NAMED_PAIR_SHARE)
        .collect();
    frequent_pairs.sort_by(|x, y| y.2.total_cmp(&x.2));
    let home = robot.home();
    let home_contacts: Vec<(String, String)> = model
        .self_contacts(&home)
        .into_iter()
        .map(|(a, b)| (a.to_owned(), b.to_owned()))
        .collect();
    // IK: the tool poses of free random configurations, solved from home.
    let solved = solvable
        .iter()
        .filter(|q| {
            let target = robot.tool_pose(q);
            robot.inverse_kinematics(&target, &home).iter().any(|s| {
                let got = robot.tool_pose(s);
                (got.translation.vector - target.translation.vector).norm() < 1e-3
                    && got.rotation.angle_to(&target.rotation) < 1e-2
            })
        })
        .count();
    let home_hit = model
        .check(&home, &TreeObstacles::empty(), &Allowed::default())
        .map(|hit| format!("{hit:?}"));
    let poses = robot.link_poses(&home);
    let tool_outward = robot.joint_axes(&poses).last().and_then(|(point, _, _)| {
        let tool = robot.tool_pose(&home);
        let out = tool.translation.vector - point.coords;
        (out.norm() > 1e-3).then(|| (tool.rotation * Vector3::z()).dot(&out.normalize()))
    });
    let empty = TreeObstacles::empty();
    let allowed = Allowed::default();
    let collision_free =
        |q: &JointVector, _: &JointVector, _: f64| model.check(q, &empty, &allowed).is_none();
    let stance = robot.stances().first().copied();
    let (pushes_kinematic, pushes_free) = match &stance {
        Some(s) => (
            robot.push_score(s),
            robot.push_score_with(s, &collision_free),
        ),
        None => (0, 0),
    };
    let stances = robot.stances();
    let pushes_any_stance = robot.stance_coverage();
    let mut report = CheckReport {
        name: robot.name().to_owned(),
        dof: robot.dof(),
        base_link: robot.base_link().to_owned(),
        tip_link: robot.tip_link().to_owned(),
        joints: robot
            .joints()
            .iter()
            .map(|j| (j.name.clone(), j.kind.name(), j.lower, j.upper, j.velocity))
            .collect(),
        tool_in_tip: robot.tool_in_tip(),
        tool_chosen: robot.tool_chosen().to_owned(),
        tool_outward,
        reach: robot.reach(),
        self_free: share(free),
        frequent_pairs,
        home_contacts,
        home_hit,
        ik: (solved, solvable.len()),
        stance,
        pushes_kinematic,
        pushes_free,
        stances: stances.len(),
        pushes_any_stance,
        warnings: Vec::new(),
    };
    report.warnings = warnings(&report);
    report
}

fn warnings(r: &CheckReport) -> Vec<String> {
    let mut out = Vec::new();
    if r.dof < 6 {
        out.push(format!(
            "{} joints: the ⊔ push needs a full tool pose (6 or more joints)",
            r.dof
        ));
    }
    if let Some(c) = r.tool_outward.filter(|&c| c.abs() < 0.5) {
        out.push(format!(
            "the tool's push axis is across the wrist, not out of it (cosine {c:.2}): a push will lead with the wrist's side"
        ));
    }
    if !r.home_contacts.is_empty() {
        let pairs: Vec<String> = r
            .home_contacts
            .iter()
            .map(|(a, b)| format!("{a}–{b}"))
            .collect();
        out.push(format!(
            "the home configuration is in self-collision ({}): plans from home will be refused",
            pairs.join(", ")
        ));
    }
    for (a, b, share) in &r.frequent_pairs {
        if *share > 0.5 {
            out.push(format!(
                "{a}–{b} touch in {:.0} % of random configurations: if they cannot really touch there, the fitted shapes overlap (disable the pair in the robot's configuration)",
                100.0 * share
            ));
        }
    }
    if r.ik.1 > 0 && (r.ik.0 as f64) < 0.8 * r.ik.1 as f64 {
        out.push(format!(
            "IK solved only {} of {} reachable poses",
            r.ik.0, r.ik.1
        ));
    }
    if r.pushes_kinematic > 0 && r.pushes_free == 0 {
        out.push(
            "the test pushes are reachable but every one collides: the tool may point into the arm or overlap a link (see the pairs above)"
                .to_owned(),
        );
    } else if r.pushes_kinematic == 0 {
        out.push(
            "the arm cannot carry out a straight push in front of itself (the chain may be too short, or the tool may point back into the wrist)"
                .to_owned(),
        );
    }
    out
}

impl fmt::Display for CheckReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "robot {}: {} joints, {} → {}",
            self.name, self.dof, self.base_link, self.tip_link
        )?;
        for (name, kind, lo, hi, v) in &self.joints {
            writeln!(
                f,
                "  {name:<28} {kind:<10} [{lo:>8.3}, {hi:>8.3}]  velocity {v:.2}"
            )?;
        }
        let t = self.tool_in_tip.translation.vector;
        let z: Vector3<f64> = self.tool_in_tip.rotation * Vector3::z();
        let (r, p, y) = UnitQuaternion::euler_angles(&self.tool_in_tip.rotation);
        writeln!(
            f,
            "tool frame in {}: xyz [{:.3}, {:.3}, {:.3}] m, rpy [{r:.3}, {p:.3}, {y:.3}] rad; push axis (z) [{:.2}, {:.2}, {:.2}]; chosen by {}",
            self.tip_link, t.x, t.y, t.z, z.x, z.y, z.z, self.tool_chosen
        )?;
        if let Some(c) = self.tool_outward {
            writeln!(
                f,
                "push axis against the direction out of the wrist: cosine {c:.2}"
            )?;
        }
        writeln!(f, "reach {:.2} m", self.reach)?;
        writeln!(
            f,
            "self-collision: {:.1} % of random configurations free",
            100.0 * self.self_free
        )?;
        for (a, b, share) in &self.frequent_pairs {
            writeln!(f, "  {a}–{b} in contact in {:.1} %", 100.0 * share)?;
        }
        match &self.home_hit {
            Some(hit) => writeln!(f, "home collides at the default mount: {hit}")?,
            None => writeln!(f, "home is collision-free at the default mount")?,
        }
        writeln!(
            f,
            "IK: {} of {} reachable poses solved",
            self.ik.0, self.ik.1
        )?;
        match &self.stance {
            Some(s) => writeln!(
                f,
                "best stance: the grip {:.2} m ahead of and {:.2} m above the base; test pushes carried out: {} of {PROBE_PUSHES} (kinematics), {} of {PROBE_PUSHES} collision-free",
                s.stand_off, s.height, self.pushes_kinematic, self.pushes_free
            )?,
            None => writeln!(f, "no stance")?,
        }
        writeln!(
            f,
            "stances tried: {}; test pushes carried out from one of them: {} of {PROBE_PUSHES}",
            self.stances, self.pushes_any_stance
        )?;
        for w in &self.warnings {
            writeln!(f, "warning: {w}")?;
        }
        match self.fatal() {
            Some(why) => writeln!(f, "cannot plan: {why}"),
            None => writeln!(f, "ok: the arm can plan pushes"),
        }
    }
}
