//! Trees as URDF, the format the paper stores them in, so that other robot
//! software (Gazebo, Isaac, PyBullet, ROS tools) can load our trees.
//!
//! # Layout
//! All link frames are parallel to the world frame at rest, so a joint axis
//! of `1 0 0` is the world x axis.
//! - `world` → fixed joint `root_joint` (origin = root position) → `node_0`.
//! - For every other node j with parent i, a spherical joint at node i made of
//!   three revolute joints, as is usual in URDF:
//!   `node_i` → `branch_j_rx` (axis x) → link `branch_j_x` → `branch_j_ry`
//!   (axis y) → `branch_j_y` → `branch_j_rz` (axis z) → link `branch_j`.
//!   The link `branch_j` is the rigid branch: a cylinder of radius r and
//!   length ℓ from node i to node j (visual, collision and a solid-wood
//!   inertial), then a fixed joint `node_j_tip` (origin = p_j − p_i) to the
//!   link `node_j`.
//!
//! # Where the joint parameters are
//! - K_d (N·m·s/rad): `<dynamics damping="…"/>` of each of the three revolute
//!   joints, which is what URDF consumers read as viscous joint damping.
//! - K_s (N·m/rad): URDF has no stiffness field. We use Gazebo's URDF
//!   extension, `<gazebo reference="branch_j_rx"><springStiffness>K_s</springStiffness>
//!   <springReference>0</springReference></gazebo>`, one per revolute joint,
//!   which Gazebo applies as a torsional spring about the rest pose.
//! - r and ℓ: the `<cylinder radius length>` of link `branch_j`'s collision.
//!
//! Positions, r, ℓ, K_s and K_d survive a write/read round trip to within
//! floating-point rounding (numbers are written in Rust's shortest exact
//! decimal form; positions are stored as parent-relative offsets).

use std::collections::HashMap;
use std::path::Path;

use nalgebra::{Point3, Rotation3, Vector3};
use quick_xml::events::Event;
use urdf_rs::{
    Axis, Collision, Dynamics, Geometry, Inertia, Inertial, Joint, JointLimit, JointType, Link,
    LinkName, Mass, Material, Pose, Robot, Vec3, Vec4, Visual,
};

use super::model::{Branch, MAX_NODES, Tree, TreeError};
use super::wood::Wood;

/// Placeholder limits for the revolute joints of a branch: a full turn of
/// travel, and effort/velocity limits high enough never to bind. The spring,
/// not the limit, is what holds a branch in place.
const JOINT_EFFORT_LIMIT: f64 = 1.0e6;
const JOINT_VELOCITY_LIMIT: f64 = 100.0;

#[derive(Debug, thiserror::Error)]
pub enum UrdfError {
    #[error("cannot read {path}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("not a valid URDF document: {0}")]
    Parse(String),
    #[error("not a treemanip tree URDF: {0}")]
    Layout(String),
    #[error("the URDF describes an invalid tree: {0}")]
    Tree(#[from] TreeError),
}

/// Writes `tree` as a URDF document named `name`. `wood` only supplies the
/// density for the inertials other simulators need.
pub fn to_urdf_string(tree: &Tree, name: &str, wood: &Wood) -> String {
    let mut links = vec![empty_link("world"), empty_link("node_0")];
    let p0 = tree.position(0);
    let mut joints = vec![fixed_joint(
        "root_joint",
        "world",
        "node_0",
        [p0.x, p0.y, p0.z],
    )];
    let mut gazebo = String::new();
    for (j, branch) in tree.branches_iter() {
        let i = tree.parent(j).expect("non-root nodes have parents");
        let offset = tree.position(j) - tree.position(i);
        let x_link = format!("branch_{j}_x");
        let y_link = format!("branch_{j}_y");
        let body = format!("branch_{j}");
        let node = format!("node_{j}");
        let chain = [
            ("rx", format!("node_{i}"), &x_link, [1.0, 0.0, 0.0]),
            ("ry", x_link.clone(), &y_link, [0.0, 1.0, 0.0]),
            ("rz", y_link.clone(), &body, [0.0, 0.0, 1.0]),
        ];
        for (suffix, parent, child, axis) in chain {
            let joint_name = format!("branch_{j}_{suffix}");
            gazebo.push_str(&format!(
                "  <gazebo reference=\"{joint_name}\">\n    <springStiffness>{}</springStiffness>\n    <springReference>0</springReference>\n  </gazebo>\n",
                branch.stiffness
            ));
            joints.push(revolute_joint(&joint_name, &parent, child, axis, branch));
        }
        links.push(empty_link(&x_link));
        links.push(empty_link(&y_link));
        links.push(branch_link(&body, offset, branch, wood));
        links.push(empty_link(&node));
        joints.push(fixed_joint(
            &format!("{node}_tip"),
            &body,
            &node,
            [offset.x, offset.y, offset.z],
        ));
    }
    let robot = Robot {
        name: name.to_owned(),
        version: None,
        links,
        joints,
        materials: vec![Material {
            name: "bark".to_owned(),
            color: Some(urdf_rs::Color {
                rgba: Vec4([0.45, 0.3, 0.15, 1.0]),
            }),
            texture: None,
        }],
    };
    let body = urdf_rs::write_to_string(&robot).expect("serialising plain structs cannot fail");
    let close = body
        .rfind("</robot>")
        .expect("serialised robot ends with </robot>");
    format!(
        "<?xml version=\"1.0\"?>\n<!-- treemanip tree: {} nodes. Joint stiffness K_s (N*m/rad) is in the <gazebo> springStiffness elements, damping K_d (N*m*s/rad) in <dynamics damping>. -->\n{}{gazebo}{}\n",
        tree.len(),
        &body[..close],
        &body[close..]
    )
}

/// Reads a tree written by [`to_urdf_string`] (or laid out the same way).
pub fn from_urdf_str(text: &str) -> Result<Tree, UrdfError> {
    let robot = urdf_rs::read_from_string(text).map_err(|e| UrdfError::Parse(e.to_string()))?;
    let stiffness = read_spring_stiffness(text)?;
    let joints: HashMap<&str, &Joint> = robot.joints.iter().map(|j| (j.name.as_str(), j)).collect();
    let links: HashMap<&str, &Link> = robot.links.iter().map(|l| (l.name.as_str(), l)).collect();
    let joint = |name: &str| {
        joints
            .get(name)
            .copied()
            .ok_or_else(|| UrdfError::Layout(format!("joint `{name}` is missing")))
    };

    let n = robot
        .links
        .iter()
        .filter(|l| parse_index(&l.name, "node_", "").is_some())
        .count();
    if n > MAX_NODES {
        return Err(TreeError::NodeCount {
            got: n,
            min: super::model::MIN_NODES,
            max: MAX_NODES,
        }
        .into());
    }
    for k in 0..n {
        if !links.contains_key(format!("node_{k}").as_str()) {
            return Err(UrdfError::Layout(format!(
                "links node_0 … node_{} expected, `node_{k}` is missing",
                n - 1
            )));
        }
    }
    let root = joint("root_joint")?;
    let mut parents = vec![None; n];
    let mut offsets = vec![Vector3::zeros(); n];
    let mut branches = vec![None; n];
    for j in 1..n {
        let rx = joint(&format!("branch_{j}_rx"))?;
        let parent = parse_index(&rx.parent.link, "node_", "").ok_or_else(|| {
            UrdfError::Layout(format!(
                "joint `branch_{j}_rx` must hang from a `node_<i>` link, not `{}`",
                rx.parent.link
            ))
        })?;
        parents[j] = Some(parent);
        offsets[j] = Vector3::from(joint(&format!("node_{j}_tip"))?.origin.xyz.0);
        let body = links
            .get(format!("branch_{j}").as_str())
            .ok_or_else(|| UrdfError::Layout(format!("link `branch_{j}` is missing")))?;
        let (radius, length) = body
            .collision
            .iter()
            .find_map(|c| match c.geometry {
                Geometry::Cylinder { radius, length } => Some((radius, length)),
                _ => None,
            })
            .ok_or_else(|| {
                UrdfError::Layout(format!("link `branch_{j}` has no collision cylinder"))
            })?;
        let damping = rx.dynamics.as_ref().map_or(0.0, |d| d.damping);
        let stiffness = *stiffness.get(&format!("branch_{j}_rx")).ok_or_else(|| {
            UrdfError::Layout(format!(
                "no <gazebo reference=\"branch_{j}_rx\"> springStiffness for node {j}"
            ))
        })?;
        branches[j] = Some(Branch {
            radius,
            length,
            stiffness,
            damping,
        });
    }
    let positions = absolute_positions(Point3::from(root.origin.xyz.0), &parents, &offsets);
    Ok(Tree::new(positions, parents, branches)?)
}

pub fn write_file(tree: &Tree, name: &str, wood: &Wood, path: &Path) -> std::io::Result<()> {
    std::fs::write(path, to_urdf_string(tree, name, wood))
}

pub fn read_file(path: &Path) -> Result<Tree, UrdfError> {
    let text = std::fs::read_to_string(path).map_err(|source| UrdfError::Io {
        path: path.display().to_string(),
        source,
    })?;
    from_urdf_str(&text)
}

/// Positions from parent-relative offsets. A node whose parent chain never
/// reaches the root gets NaN, which [`Tree::new`] then reports (after it has
/// reported the broken topology itself).
fn absolute_positions(
    root: Point3<f64>,
    parents: &[Option<usize>],
    offsets: &[Vector3<f64>],
) -> Vec<Point3<f64>> {
    let n = parents.len();
    let mut positions: Vec<Option<Point3<f64>>> = vec![None; n];
    if n > 0 {
        positions[0] = Some(root);
    }
    for start in 0..n {
        let mut chain = Vec::new();
        let mut current = start;
        while positions[current].is_none() && chain.len() <= n {
            chain.push(current);
            match parents[current] {
                Some(p) if p < n => current = p,
                _ => break,
            }
        }
        let mut base = positions[current];
        for &node in chain.iter().rev() {
            base = base.map(|b| b + offsets[node]);
            positions[node] = base;
        }
    }
    positions
        .into_iter()
        .map(|p| p.unwrap_or(Point3::new(f64::NAN, f64::NAN, f64::NAN)))
        .collect()
}

/// `springStiffness` of every `<gazebo reference="…">` block, by reference.
/// urdf-rs drops extension elements, so they are read with quick-xml.
fn read_spring_stiffness(text: &str) -> Result<HashMap<String, f64>, UrdfError> {
    let mut reader = quick_xml::Reader::from_str(text);
    let mut reference: Option<String> = None;
    let mut in_stiffness = false;
    let mut out = HashMap::new();
    loop {
        let event = reader
            .read_event()
            .map_err(|e| UrdfError::Parse(e.to_string()))?;
        match event {
            Event::Start(e) if e.name().as_ref() == b"gazebo" => {
                reference = e
                    .try_get_attribute("reference")
                    .map_err(|e| UrdfError::Parse(e.to_string()))?
                    .map(|a| String::from_utf8_lossy(&a.value).into_owned());
            }
            Event::End(e) if e.name().as_ref() == b"gazebo" => reference = None,
            Event::Start(e) if e.name().as_ref() == b"springStiffness" => in_stiffness = true,
            Event::End(e) if e.name().as_ref() == b"springStiffness" => in_stiffness = false,
            Event::Text(t) if in_stiffness => {
                if let Some(r) = &reference {
                    let raw = String::from_utf8_lossy(&t).trim().to_owned();
                    let value: f64 = raw.parse().map_err(|_| {
                        UrdfError::Parse(format!("springStiffness of `{r}` is not a number: {raw}"))
                    })?;
                    out.insert(r.clone(), value);
                }
            }
            Event::Eof => break,
            _ => {}
        }
    }
    Ok(out)
}

fn parse_index(name: &str, prefix: &str, suffix: &str) -> Option<usize> {
    let digits = name.strip_prefix(prefix)?.strip_suffix(suffix)?;
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok()
}

fn empty_link(name: &str) -> Link {
    Link {
        name: name.to_owned(),
        inertial: Inertial::default(),
        visual: Vec::new(),
        collision: Vec::new(),
    }
}

/// The rigid branch: a cylinder from the link origin (the parent node) to
/// `offset` (the child node).
fn branch_link(name: &str, offset: Vector3<f64>, branch: &Branch, wood: &Wood) -> Link {
    let axis = offset.normalize();
    let rotation = Rotation3::rotation_between(&Vector3::z(), &axis)
        .unwrap_or_else(|| Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI));
    let (roll, pitch, yaw) = rotation.euler_angles();
    let centre = offset / 2.0;
    let pose = Pose {
        xyz: Vec3([centre.x, centre.y, centre.z]),
        rpy: Vec3([roll, pitch, yaw]),
    };
    let geometry = Geometry::Cylinder {
        radius: branch.radius,
        length: branch.length,
    };
    let (r, l) = (branch.radius, branch.length);
    let mass = wood.mass(r, l);
    let transverse = mass * (3.0 * r * r + l * l) / 12.0;
    Link {
        name: name.to_owned(),
        inertial: Inertial {
            origin: pose.clone(),
            mass: Mass { value: mass },
            inertia: Inertia {
                ixx: transverse,
                ixy: 0.0,
                ixz: 0.0,
                iyy: transverse,
                iyz: 0.0,
                izz: mass * r * r / 2.0,
            },
        },
        visual: vec![Visual {
            name: None,
            origin: pose.clone(),
            geometry: geometry.clone(),
            material: Some(Material {
                name: "bark".to_owned(),
                color: None,
                texture: None,
            }),
        }],
        collision: vec![Collision {
            name: None,
            origin: pose,
            geometry,
        }],
    }
}

fn fixed_joint(name: &str, parent: &str, child: &str, xyz: [f64; 3]) -> Joint {
    Joint {
        name: name.to_owned(),
        joint_type: JointType::Fixed,
        origin: Pose {
            xyz: Vec3(xyz),
            rpy: Vec3([0.0; 3]),
        },
        parent: LinkName {
            link: parent.to_owned(),
        },
        child: LinkName {
            link: child.to_owned(),
        },
        axis: Axis::default(),
        limit: JointLimit::default(),
        calibration: None,
        dynamics: None,
        mimic: None,
        safety_controller: None,
    }
}

fn revolute_joint(name: &str, parent: &str, child: &str, axis: [f64; 3], b: &Branch) -> Joint {
    Joint {
        joint_type: JointType::Revolute,
        axis: Axis { xyz: Vec3(axis) },
        limit: JointLimit {
            lower: -std::f64::consts::PI,
            upper: std::f64::consts::PI,
            effort: JOINT_EFFORT_LIMIT,
            velocity: JOINT_VELOCITY_LIMIT,
            ..JointLimit::default()
        },
        dynamics: Some(Dynamics {
            damping: b.damping,
            friction: 0.0,
        }),
        ..fixed_joint(name, parent, child, [0.0; 3])
    }
}
