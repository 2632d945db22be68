//! `import`: a robot configuration and its URDF become a self-contained
//! [`RobotDescription`] (chain, fitted shapes, limits, disabled pairs).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use nalgebra::Isometry3;

use crate::robot::model::description::{
    DEFAULT_ACCELERATION, DEFAULT_LINEAR_ACCELERATION, DescriptionError, JointSpec, LinkSpec,
    Provenance, RobotConfig, RobotDescription, SELF_COLLISION_SAMPLES, ToolSpec, arr, shape_spec,
};
use crate::robot::model::link_geometry::{LinkGeometry, link_geometry};
use crate::robot::model::self_pairs::{
    DisableReason, DisabledPair, all_link_poses, disabled_pairs,
};
use crate::robot::model::srdf::{SrdfPair, disabled_collisions};
use crate::robot::model::tool_mount::{ToolChoice, flange_axis, frame};
use crate::robot::model::urdf_chain::{Chain, JointKind, parse_urdf};

/// Imports the robot that the configuration at `config_path` describes:
/// reads its URDF and meshes (through `packages` and the URDF's
/// ancestors), fits the meshes, samples the self-collision pairs.
pub fn import(
    config_path: &Path,
    packages: &[PathBuf],
    command: &str,
) -> Result<RobotDescription, DescriptionError> {
    let fail = |file: &Path, message: String| DescriptionError {
        file: file.to_path_buf(),
        message,
    };
    let text = std::fs::read_to_string(config_path)
        .map_err(|e| fail(config_path, format!("cannot be read: {e}")))?;
    let config: RobotConfig =
        toml::from_str(&text).map_err(|e| fail(config_path, e.to_string()))?;
    let urdf_path = config_path
        .parent()
        .unwrap_or(Path::new("."))
        .join(&config.urdf);
    let urdf_text = std::fs::read_to_string(&urdf_path)
        .map_err(|e| fail(&urdf_path, format!("cannot be read: {e}")))?;
    let robot = parse_urdf(&urdf_text).map_err(|e| fail(&urdf_path, e.to_string()))?;
    let srdf = match &config.srdf {
        Some(path) => {
            let path = config_path.parent().unwrap_or(Path::new(".")).join(path);
            let text = std::fs::read_to_string(&path)
                .map_err(|e| fail(&path, format!("cannot be read: {e}")))?;
            let pairs = disabled_collisions(&text).map_err(|m| fail(&path, m))?;
            Some((path, pairs))
        }
        None => None,
    };
    let mut description = describe(
        config,
        &robot,
        urdf_path.parent(),
        packages,
        command,
        SELF_COLLISION_SAMPLES,
    )
    .map_err(|(file, message)| match file {
        Blame::Config => fail(config_path, message),
        Blame::Urdf => fail(&urdf_path, message),
    })?;
    if let Some((path, pairs)) = srdf {
        add_srdf_pairs(&mut description, &robot, &pairs).map_err(|m| fail(&path, m))?;
    }
    Ok(description)
}

/// Adds an SRDF's disabled pairs that the description does not already
/// have; a link the URDF lacks is an error (the SRDF is for another
/// robot).
fn add_srdf_pairs(
    description: &mut RobotDescription,
    robot: &urdf_rs::Robot,
    pairs: &[SrdfPair],
) -> Result<(), String> {
    for p in pairs {
        for l in [&p.link1, &p.link2] {
            if !robot.links.iter().any(|x| &x.name == l) {
                return Err(format!(
                    "<disable_collisions link1=\"{}\" link2=\"{}\">: link `{l}` is not in the URDF",
                    p.link1, p.link2
                ));
            }
        }
        add_pair(
            &mut description.disabled_pairs,
            &p.link1,
            &p.link2,
            DisableReason::Srdf,
        );
    }
    Ok(())
}

/// Adds the pair `a`–`b` (either order) to `pairs` unless it is there.
fn add_pair(pairs: &mut Vec<DisabledPair>, a: &str, b: &str, reason: DisableReason) {
    let known = pairs
        .iter()
        .any(|p| (p.a == a && p.b == b) || (p.a == b && p.b == a));
    if !known {
        pairs.push(DisabledPair {
            a: a.to_owned(),
            b: b.to_owned(),
            reason,
        });
    }
}

/// The configuration's tool, placed as its [`ToolChoice`] and
/// `tool_adjust` say ([`crate::robot::model::tool_mount`]).
fn place_tool(
    config: &RobotConfig,
    robot: &urdf_rs::Robot,
    chain: &Chain,
    geometry: &[LinkGeometry],
    poses: &HashMap<String, Isometry3<f64>>,
) -> Result<ToolSpec, String> {
    let mut tool = config.tool.clone();
    match &config.tool_choice {
        ToolChoice::Configured => {}
        ToolChoice::FlangeAxis => tool.place(flange_axis(robot, chain, geometry, poses)?),
        ToolChoice::Frame(name) => tool.place(frame(robot, chain, poses, name)?),
    }
    if let Some((xyz, rpy)) = config.tool_adjust {
        tool.adjust(xyz, rpy);
    }
    Ok(tool)
}

/// Which file a problem of [`describe`] lies in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Blame {
    Config,
    Urdf,
}

/// The description of `robot` (a parsed URDF whose meshes resolve through
/// `urdf_dir` and `packages`) as `config` asks, with the self-collision
/// pairs sampled over `samples` configurations (0: only the adjacent
/// links and the configured pairs are left out).
pub fn describe(
    config: RobotConfig,
    robot: &urdf_rs::Robot,
    urdf_dir: Option<&Path>,
    packages: &[PathBuf],
    command: &str,
    samples: usize,
) -> Result<RobotDescription, (Blame, String)> {
    let config_path = Blame::Config;
    let urdf_path = Blame::Urdf;
    let fail = |file: &Blame, message: String| (*file, message);
    let chain = Chain::from_robot(
        robot,
        config.base_link.as_deref(),
        config.tip_link.as_deref(),
    )
    .map_err(|e| fail(&urdf_path, e.to_string()))?;
    let dof = chain.dof();
    let acceleration = config
        .acceleration
        .as_ref()
        .map(|a| a.values(dof, "acceleration"))
        .transpose()
        .map_err(|m| fail(&config_path, m))?;
    let jerk = config
        .jerk
        .as_ref()
        .map(|a| a.values(dof, "jerk"))
        .transpose()
        .map_err(|m| fail(&config_path, m))?;
    let limits = chain.limits();
    let home = match &config.home {
        Some(h) if h.len() != dof => {
            return Err(fail(
                &config_path,
                format!("home: {} values for a {dof}-joint chain", h.len()),
            ));
        }
        Some(h) => {
            if let Some(k) = h
                .iter()
                .zip(&limits)
                .position(|(q, (lo, hi))| !(q.is_finite() && *lo <= *q && q <= hi))
            {
                return Err(fail(
                    &config_path,
                    format!("home[{k}] = {} is outside the joint's limits", h[k]),
                ));
            }
            h.clone()
        }
        // Continuous joints' ±∞ limits leave 0 as it is.
        None => limits.iter().map(|(lo, hi)| 0f64.clamp(*lo, *hi)).collect(),
    };
    let geometry =
        link_geometry(robot, urdf_dir, packages).map_err(|e| fail(&urdf_path, e.to_string()))?;
    let mut pairs = disabled_pairs(robot, &chain, &geometry, samples, 0);
    for [a, b] in &config.disabled_pairs {
        for l in [a, b] {
            let tool = config.tool.gripper && l == crate::robot::model::tool::GRIPPER_LINK;
            if !tool && !robot.links.iter().any(|x| &x.name == l) {
                return Err(fail(
                    &config_path,
                    format!(
                        "disabled_pairs: link `{l}` is not in the URDF (nor the tool's `gripper`)"
                    ),
                ));
            }
        }
        add_pair(&mut pairs, a, b, DisableReason::Configured);
    }
    // Each link with shapes, on the chain link it rides on.
    let zero = vec![0.0; dof];
    let poses = all_link_poses(robot, &chain, &zero);
    let tool =
        place_tool(&config, robot, &chain, &geometry, &poses).map_err(|m| fail(&config_path, m))?;
    let chain_links: Vec<&str> = std::iter::once(chain.base_link.as_str())
        .chain(chain.joints.iter().map(|j| j.child_link.as_str()))
        .collect();
    let parent_of = |link: &str| {
        robot
            .joints
            .iter()
            .find(|j| j.child.link == link)
            .map(|j| j.parent.link.as_str())
    };
    let mut links = Vec::new();
    for g in &geometry {
        let mut frame = g.link.as_str();
        while !chain_links.contains(&frame) {
            match parent_of(frame) {
                Some(p) => frame = p,
                None => break,
            }
        }
        if !chain_links.contains(&frame) {
            // Above the chain's base: fixed relative to it.
            frame = chain.base_link.as_str();
        }
        let (Some(at), Some(of)) = (poses.get(&g.link), poses.get(frame)) else {
            continue;
        };
        links.push(LinkSpec {
            name: g.link.clone(),
            frame: frame.to_owned(),
            pose: (&(of.inverse() * at)).into(),
            shapes: g.shapes.iter().map(shape_spec).collect(),
        });
    }
    let joints = chain
        .joints
        .iter()
        .map(|j| {
            let v = j.variable;
            let is_linear = j.kind == JointKind::Prismatic;
            let default_acc = if is_linear {
                DEFAULT_LINEAR_ACCELERATION
            } else {
                DEFAULT_ACCELERATION
            };
            JointSpec {
                name: j.name.clone(),
                kind: j.kind.name().to_owned(),
                child: j.child_link.clone(),
                origin: (&j.origin).into(),
                axis: arr(&j.axis),
                lower: j.lower.is_finite().then_some(j.lower),
                upper: j.upper.is_finite().then_some(j.upper),
                velocity: v.map(|_| j.velocity),
                acceleration: v.map(|k| acceleration.as_ref().map_or(default_acc, |a| a[k])),
                jerk: v.and_then(|k| jerk.as_ref().map(|a| a[k])),
                mimic_joint: j
                    .mimic
                    .and_then(|m| chain.variables().nth(m.variable).map(|x| x.name.clone())),
                mimic_multiplier: j.mimic.map(|m| m.multiplier),
                mimic_offset: j.mimic.map(|m| m.offset),
            }
        })
        .collect();
    Ok(RobotDescription {
        name: config.name,
        base_link: chain.base_link.clone(),
        tip_link: chain.tip_link.clone(),
        dof,
        home,
        joints,
        links,
        disabled_pairs: pairs,
        tool,
        source: Provenance {
            urdf: config.urdf.display().to_string(),
            licence: config.licence,
            command: command.to_owned(),
            self_collision_samples: samples,
        },
    })
}
