//! Which arms a server plans for: `NAME=PATH[,tip=LINK][,base=LINK]`
//! specifications ([`RobotSpec`]), each loaded from an imported
//! description (`.toml`) or a bare URDF ([`load`]), and the built-in UR5.

use std::path::{Path, PathBuf};

use crate::robot::arm::Arm;
use crate::robot::collision::{Allowed, CollisionModel, TreeObstacles};
use crate::robot::model::description::{
    DescriptionError, RobotConfig, RobotDescription, SELF_COLLISION_SAMPLES,
};
use crate::robot::model::import::{Blame, describe, import};
use crate::robot::model::joint_vector::JointVector;
use crate::robot::model::tool_mount::ToolChoice;
use crate::robot::model::urdf_chain::parse_urdf;
use crate::robot::model::urdf_chain::random_configuration;
use crate::robot::motion::rrt::distance;

/// The fewest joints an arm may have: the ⊔ push needs the tool's full
/// pose (position, push axis and slot orientation).
pub const MIN_DOF: usize = 6;

/// The built-in arm's name.
pub const BUILT_IN: &str = "ur5";

/// One `--robot` value.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotSpec {
    pub name: String,
    pub path: PathBuf,
    pub tip: Option<String>,
    pub base: Option<String>,
    /// `tool=FRAME`: the URDF frame (the tip or a link it carries) whose z
    /// is the push axis (default: the last joint's axis, out of the wrist).
    pub tool: Option<String>,
    /// `tool_xyz=[x,y,z]` (m) and `tool_rpy=[r,p,y]` (rad): the chosen
    /// tool mount moved and turned in its own frame.
    pub tool_xyz: Option<[f64; 3]>,
    pub tool_rpy: Option<[f64; 3]>,
}

impl RobotSpec {
    /// The arm at `path`, named `name`, with no options.
    pub fn at(name: String, path: PathBuf) -> Self {
        Self {
            name,
            path,
            tip: None,
            base: None,
            tool: None,
            tool_xyz: None,
            tool_rpy: None,
        }
    }
}

/// `text` split at commas outside brackets (`a=x,tool_xyz=[0,0,0.1]`).
fn split_options(text: &str) -> Vec<&str> {
    let (mut out, mut depth, mut start) = (Vec::new(), 0i32, 0);
    for (i, c) in text.char_indices() {
        match c {
            '[' => depth += 1,
            ']' => depth -= 1,
            ',' if depth == 0 => {
                out.push(&text[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    out.push(&text[start..]);
    out
}

/// `[x,y,z]` (brackets optional): three finite numbers.
fn triple(text: &str, what: &str) -> Result<[f64; 3], String> {
    let inner = text.trim().trim_start_matches('[').trim_end_matches(']');
    let values: Vec<f64> = inner
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("{what}={text}: expected [x,y,z], three numbers"))?;
    match values.as_slice() {
        [x, y, z] if values.iter().all(|v| v.is_finite()) => Ok([*x, *y, *z]),
        _ => Err(format!(
            "{what}={text}: expected [x,y,z], three finite numbers"
        )),
    }
}

impl std::str::FromStr for RobotSpec {
    type Err = String;

    /// `NAME=PATH[,tip=LINK][,base=LINK][,tool=FRAME][,tool_xyz=[x,y,z]][,tool_rpy=[r,p,y]]`.
    fn from_str(text: &str) -> Result<Self, String> {
        let mut parts = split_options(text).into_iter();
        let head = parts.next().unwrap_or_default();
        let (name, path) = head
            .split_once('=')
            .ok_or_else(|| format!("`{text}`: expected NAME=PATH[,tip=LINK][,base=LINK]"))?;
        let valid = |s: &str| {
            !s.is_empty()
                && s.chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
        };
        if !valid(name) {
            return Err(format!(
                "`{text}`: the robot's name must be letters, digits, `_` or `-`"
            ));
        }
        if path.is_empty() {
            return Err(format!("`{text}`: no path"));
        }
        let mut spec = RobotSpec::at(name.to_owned(), PathBuf::from(path));
        for part in parts {
            match part.split_once('=') {
                Some(("tip", link)) if !link.is_empty() => spec.tip = Some(link.to_owned()),
                Some(("base", link)) if !link.is_empty() => spec.base = Some(link.to_owned()),
                Some(("tool", link)) if !link.is_empty() => spec.tool = Some(link.to_owned()),
                Some(("tool_xyz", v)) => {
                    spec.tool_xyz =
                        Some(triple(v, "tool_xyz").map_err(|e| format!("`{text}`: {e}"))?)
                }
                Some(("tool_rpy", v)) => {
                    spec.tool_rpy =
                        Some(triple(v, "tool_rpy").map_err(|e| format!("`{text}`: {e}"))?)
                }
                _ => {
                    return Err(format!(
                        "`{text}`: unknown option `{part}` (tip=LINK, base=LINK, tool=FRAME, tool_xyz=[x,y,z] or tool_rpy=[r,p,y])"
                    ));
                }
            }
        }
        Ok(spec)
    }
}

/// The imported descriptions in folder `dir` (every `*.toml` directly in
/// it, written by `treemanip robot import`, as `robots/` holds them), each
/// named by its file's stem, sorted by name; the built-in arm's name is
/// left out (the built-in keeps it; serve the imported one under another
/// name with `--robot`). A folder that does not exist holds none.
pub fn folder(dir: &Path) -> Result<Vec<RobotSpec>, DescriptionError> {
    let entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => {
            return Err(DescriptionError {
                file: dir.to_path_buf(),
                message: format!("cannot be read: {e}"),
            });
        }
    };
    let mut specs: Vec<RobotSpec> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && p.extension().is_some_and(|e| e == "toml"))
        .filter_map(|path| {
            let name = path.file_stem()?.to_str()?.to_owned();
            (name != BUILT_IN).then(|| RobotSpec::at(name, path))
        })
        .collect();
    specs.sort_by(|a, b| a.name.cmp(&b.name));
    Ok(specs)
}

/// The specifications in `TREEMANIP_ROBOTS`-style text: separated by `;`
/// or whitespace.
pub fn parse_list(text: &str) -> Result<Vec<RobotSpec>, String> {
    text.split(|c: char| c == ';' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .map(str::parse)
        .collect()
}

/// The description `spec` names: an imported description (`.toml`), a
/// robot configuration (`.toml` naming its URDF, imported now), or a URDF
/// described now (its meshes fitted, its self-collision pairs sampled)
/// with the documented defaults ([`crate::robot::model::description`]). `tip` and `base`
/// apply to a bare URDF only: a TOML file gives its own chain.
pub fn load_description(
    spec: &RobotSpec,
    packages: &[PathBuf],
) -> Result<RobotDescription, DescriptionError> {
    let fail = |file: &Path, message: String| DescriptionError {
        file: file.to_path_buf(),
        message,
    };
    let text = std::fs::read_to_string(&spec.path)
        .map_err(|e| fail(&spec.path, format!("cannot be read: {e}")))?;
    let is_toml = spec.path.extension().is_some_and(|e| e == "toml");
    let adjust = (spec.tool_xyz.is_some() || spec.tool_rpy.is_some()).then(|| {
        (
            spec.tool_xyz.unwrap_or_default(),
            spec.tool_rpy.unwrap_or_default(),
        )
    });
    let mut description = if is_toml {
        if spec.tip.is_some() || spec.base.is_some() || spec.tool.is_some() {
            return Err(fail(
                &spec.path,
                "an imported description's chain and tool frame are fixed: re-import it for another tip, base or tool frame (tool_xyz/tool_rpy adjust it)"
                    .to_owned(),
            ));
        }
        let is_config = toml::from_str::<toml::Table>(&text)
            .is_ok_and(|t| t.contains_key("urdf") && !t.contains_key("source"));
        let mut description = if is_config {
            // A configuration naming its URDF: imported now.
            let command = format!("--robot {}={}", spec.name, spec.path.display());
            import(&spec.path, packages, &command)?
        } else {
            RobotDescription::from_toml_str(&text, &spec.path)?
        };
        if let Some((xyz, rpy)) = adjust {
            description.tool.adjust(xyz, rpy);
        }
        description
    } else {
        let robot = parse_urdf(&text).map_err(|e| fail(&spec.path, e.to_string()))?;
        let config = RobotConfig {
            name: spec.name.clone(),
            urdf: spec.path.clone(),
            base_link: spec.base.clone(),
            tip_link: spec.tip.clone(),
            acceleration: None,
            jerk: None,
            home: None,
            disabled_pairs: Vec::new(),
            srdf: None,
            licence: String::new(),
            tool: Default::default(),
            tool_choice: match &spec.tool {
                Some(frame) => ToolChoice::Frame(frame.clone()),
                None => ToolChoice::FlangeAxis,
            },
            tool_adjust: adjust,
        };
        let command = format!("--robot {}={}", spec.name, spec.path.display());
        describe(
            config,
            &robot,
            spec.path.parent(),
            packages,
            &command,
            SELF_COLLISION_SAMPLES,
        )
        .map_err(|(blame, message)| match blame {
            Blame::Config | Blame::Urdf => fail(&spec.path, message),
        })?
    };
    description.name = spec.name.clone();
    Ok(description)
}

/// The arm `spec` names (see [`load_description`]). A home that collides
/// with the arm itself or the ground at the default mount (a bare URDF's default, zero clamped
/// into the limits, often does) is replaced by [`free_home`]'s.
pub fn load(spec: &RobotSpec, packages: &[PathBuf]) -> Result<Arm, DescriptionError> {
    let (arm, free) = load_as_described(spec, packages)?;
    if free {
        Ok(arm)
    } else {
        Err(DescriptionError {
            file: spec.path.clone(),
            message: "no collision-free configuration found for a home (give one in a robot configuration; `treemanip robot check` says what collides)".to_owned(),
        })
    }
}

/// The arm `spec` names, with [`free_home`]'s home when there is one
/// (`true`), else with its description's (`false`): what `treemanip robot
/// check` reports on even when [`load`] would refuse it.
pub fn load_as_described(
    spec: &RobotSpec,
    packages: &[PathBuf],
) -> Result<(Arm, bool), DescriptionError> {
    let description = load_description(spec, packages)?;
    let fail = |message: String| DescriptionError {
        file: spec.path.clone(),
        message,
    };
    if description.dof < MIN_DOF {
        return Err(fail(format!(
            "{} has {} joints from {} to {}: pushing with the ⊔ tool needs a full tool pose, {MIN_DOF} or more joints (name another tip link with `tip=LINK`)",
            spec.name, description.dof, description.base_link, description.tip_link
        )));
    }
    let arm = Arm::from_description(&description).map_err(fail)?;
    match free_home(&arm) {
        Some(home) => Ok((arm.with_home(home).map_err(fail)?, true)),
        None => Ok((arm, false)),
    }
}

/// Random configurations tried for a bare URDF's home.
const HOME_SAMPLES: usize = 500;

/// A collision-free home for `arm` at the default mount (10 cm above the
/// ground, [`Arm::default_base`]; its links clear of the ground and
/// each other): its own home, else zero
/// clamped into the limits, else the middle of the limits, else the free
/// random configuration nearest the middle.
pub fn free_home(arm: &Arm) -> Option<JointVector> {
    use rand::SeedableRng;
    let model = CollisionModel::new(arm.clone().with_base(arm.default_base()));
    let empty = TreeObstacles::empty();
    let free = |q: &JointVector| model.check(q, &empty, &Allowed::default()).is_none();
    let limits = arm.limits();
    let middle = JointVector::from_fn(arm.dof(), |i| {
        let (lo, hi) = limits[i];
        if lo.is_finite() && hi.is_finite() {
            (lo + hi) / 2.0
        } else {
            0.0
        }
    });
    let zero = JointVector::from_fn(arm.dof(), |i| 0f64.clamp(limits[i].0, limits[i].1));
    if let Some(q) = [arm.home(), zero, middle].into_iter().find(|q| free(q)) {
        return Some(q);
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let mut samples: Vec<JointVector> = (0..HOME_SAMPLES)
        .map(|_| JointVector::from_slice(&random_configuration(arm.chain(), &mut rng)))
        .collect();
    samples.sort_by(|a, b| distance(a, &middle).total_cmp(&distance(b, &middle)));
    samples.into_iter().find(|q| free(q))
}

/// Where shipped descriptions live, relative to the working directory.
pub const SHIPPED_DIR: &str = "robots";

/// The arm a command line names: `ur5` (the built-in), a specification
/// `NAME=PATH[,tip=LINK][,base=LINK]`, a path to a description or URDF, or
/// the name of a shipped description (`panda` is `robots/panda.toml`).
pub fn resolve(text: &str, packages: &[PathBuf]) -> Result<Arm, DescriptionError> {
    if text == BUILT_IN {
        return Ok(Arm::ur5(Default::default()));
    }
    load(&spec_of(text)?, packages)
}

/// The specification a command line's arm names (see [`resolve`]; not the
/// built-in, which has none).
pub fn spec_of(text: &str) -> Result<RobotSpec, DescriptionError> {
    Ok(if text.contains('=') {
        text.parse::<RobotSpec>()
            .map_err(|message| DescriptionError {
                file: PathBuf::from(text),
                message,
            })?
    } else {
        let path = PathBuf::from(text);
        let path = if path.exists() {
            path
        } else {
            Path::new(SHIPPED_DIR).join(format!("{text}.toml"))
        };
        let name = path
            .file_stem()
            .map_or_else(|| text.to_owned(), |s| s.to_string_lossy().into_owned());
        RobotSpec::at(name, path)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specifications_parse_or_say_what_is_wrong() {
        let s: RobotSpec = "panda=robots/panda.urdf,tip=panda_hand,base=panda_link0"
            .parse()
            .unwrap();
        assert_eq!(s.name, "panda");
        assert_eq!(s.path, PathBuf::from("robots/panda.urdf"));
        assert_eq!(s.tip.as_deref(), Some("panda_hand"));
        assert_eq!(s.base.as_deref(), Some("panda_link0"));
        assert!(
            "panda"
                .parse::<RobotSpec>()
                .unwrap_err()
                .contains("NAME=PATH")
        );
        assert!("a b=x".parse::<RobotSpec>().unwrap_err().contains("name"));
        assert!(
            "a=x,elbow=y"
                .parse::<RobotSpec>()
                .unwrap_err()
                .contains("unknown option")
        );
        assert_eq!(parse_list("a=x.toml; b=y.urdf,tip=t").unwrap().len(), 2);
    }

    /// `robots/` lists the shipped arms by name, without the built-in's
    /// name; a folder that is not there lists none.
    #[test]
    fn a_folder_lists_its_descriptions_by_name() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../robots");
        let names: Vec<String> = folder(&dir).unwrap().into_iter().map(|s| s.name).collect();
        assert_eq!(names, ["iiwa", "panda", "ur10"]);
        assert!(folder(&dir.join("no-such-folder")).unwrap().is_empty());
    }
}
