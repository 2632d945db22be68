//! Robot descriptions (`robot::model::description`): the shipped `robots/*.toml`
//! load without their URDFs or meshes and keep the URDF's kinematics, an
//! import round-trips through TOML, and bad files and configurations are
//! named.

use std::path::Path;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use treemanip_core::robot::model::description::{RobotDescription, import};
use treemanip_core::robot::model::urdf_chain::Chain;
use treemanip_core::robot::model::urdf_chain::random_configuration;

use crate::robot_chain::panda_urdf;

fn shipped(name: &str) -> RobotDescription {
    let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
        .join("robots")
        .join(format!("{name}.toml"));
    let text = std::fs::read_to_string(&path).unwrap();
    RobotDescription::from_toml_str(&text, &path).unwrap()
}

#[test]
fn the_shipped_robots_load_without_their_urdfs() {
    for (name, dof, tip) in [
        ("ur5", 6, "ee_link"),
        ("ur10", 6, "ee_link"),
        ("panda", 7, "panda_hand"),
        ("iiwa", 7, "lbr_iiwa_link_7"),
    ] {
        let d = shipped(name);
        let chain = d.chain().unwrap();
        assert_eq!(
            (chain.dof(), d.dof, chain.tip_link.as_str()),
            (dof, dof, tip)
        );
        assert_eq!(d.acceleration_limits().len(), dof, "{name}");
        for ((q, (lo, hi)), joint) in d.home.iter().zip(chain.limits()).zip(chain.variables()) {
            assert!(
                lo <= *q && *q <= hi,
                "{name}: home {q} outside {} limits",
                joint.name
            );
        }
        // Every link of the chain that collides has shapes, placed on a
        // chain link, and the neighbours along the arm are left unchecked.
        assert!(
            d.links.len() >= dof,
            "{name}: {} links with shapes",
            d.links.len()
        );
        let frames: Vec<&str> = std::iter::once(d.base_link.as_str())
            .chain(d.joints.iter().map(|j| j.child.as_str()))
            .collect();
        assert!(d.links.iter().all(|l| frames.contains(&l.frame.as_str())));
        assert!(d.disabled_pairs.len() >= dof - 1, "{name}");
        assert!(!d.source.licence.is_empty() && d.source.command.contains("robot import"));
        // The tip moves: a well-formed chain.
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let a = chain.tip_pose(&random_configuration(&chain, &mut rng));
        let b = chain.tip_pose(&random_configuration(&chain, &mut rng));
        assert!((a.translation.vector - b.translation.vector).norm() > 1e-3);
    }
}

/// The shipped Panda moves its hand exactly as the URDF it came from.
#[test]
fn the_shipped_panda_keeps_the_urdfs_kinematics() {
    let Some(path) = panda_urdf() else { return };
    let text = std::fs::read_to_string(&path).unwrap();
    let urdf = Chain::from_urdf_str(&text, Some("panda_link0"), Some("panda_hand")).unwrap();
    let chain = shipped("panda").chain().unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    for _ in 0..50 {
        let q = random_configuration(&urdf, &mut rng);
        let (a, b) = (urdf.tip_pose(&q), chain.tip_pose(&q));
        assert!((a.translation.vector - b.translation.vector).norm() < 1e-9);
        assert!(a.rotation.angle_to(&b.rotation) < 1e-9);
    }
}

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn imports_round_trip_and_bad_configurations_are_named() {
    let dir = crate::common::temp_dir("description");
    write(
        &dir,
        "arm.urdf",
        r#"<robot name="arm">
  <link name="base"><collision><geometry><cylinder radius="0.05" length="0.1"/></geometry></collision></link>
  <link name="l1"><collision><origin xyz="0 0 0.15"/><geometry><box size="0.04 0.04 0.3"/></geometry></collision></link>
  <link name="l2"><collision><origin xyz="0 0 0.1"/><geometry><capsule radius="0.02" length="0.2"/></geometry></collision></link>
  <link name="tip"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.05"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="2" effort="1"/></joint>
  <joint name="j2" type="prismatic"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.3"/><axis xyz="0 0 1"/><limit lower="0" upper="0.2" velocity="0.5" effort="1"/></joint>
  <joint name="j3" type="fixed"><parent link="l2"/><child link="tip"/><origin xyz="0 0 0.2"/></joint>
</robot>"#,
    );
    let good = write(
        &dir,
        "arm.toml",
        "name = \"arm\"\nurdf = \"arm.urdf\"\nacceleration = [4, 1]\nlicence = \"test\"\n",
    );
    let d = import(&good, &[], "test").unwrap();
    assert_eq!((d.dof, d.tip_link.as_str()), (2, "tip"));
    assert_eq!(d.acceleration_limits(), vec![4.0, 1.0]);
    // Home: zero clamped into the limits.
    assert_eq!(d.home, vec![0.0, 0.0]);
    let text = d.to_toml().unwrap();
    let back = RobotDescription::from_toml_str(&text, Path::new("arm.toml")).unwrap();
    assert_eq!(back, d);
    let q = [1.0, 0.1];
    let (a, b) = (
        back.chain().unwrap().tip_pose(&q),
        Chain::from_urdf_str(
            &std::fs::read_to_string(dir.join("arm.urdf")).unwrap(),
            None,
            None,
        )
        .unwrap()
        .tip_pose(&q),
    );
    assert!((a.translation.vector - b.translation.vector).norm() < 1e-12);
    // Configurations that cannot be used name the field.
    for (config, needle) in [
        ("name = \"a\"\nurdf = \"arm.urdf\"\nhome = [0]\n", "home"),
        (
            "name = \"a\"\nurdf = \"arm.urdf\"\nhome = [9, 0]\n",
            "home[0]",
        ),
        (
            "name = \"a\"\nurdf = \"arm.urdf\"\nacceleration = [1, -1]\n",
            "acceleration[1]",
        ),
        (
            "name = \"a\"\nurdf = \"arm.urdf\"\ndisabled_pairs = [[\"l1\", \"nope\"]]\n",
            "nope",
        ),
        ("name = \"a\"\nurdf = \"missing.urdf\"\n", "missing.urdf"),
        (
            "name = \"a\"\nurdf = \"arm.urdf\"\ntip_link = \"nowhere\"\n",
            "nowhere",
        ),
        ("name = \"a\"\nurdf = \"arm.urdf\"\ncolour = 1\n", "colour"),
    ] {
        let path = write(&dir, "bad.toml", config);
        let e = import(&path, &[], "test").unwrap_err().to_string();
        assert!(e.contains(needle), "{config}: {e}");
    }
    // Descriptions that cannot be used name the element.
    for (from, to, needle) in [
        (
            "kind = \"prismatic\"",
            "kind = \"spherical\"",
            "joints[1] (j2): unknown kind",
        ),
        (
            "velocity = 0.5",
            "velocity = -0.5",
            "joints[1] (j2): needs a positive velocity",
        ),
        ("radius = 0.02", "radius = -0.02", "shapes[0]: radius"),
        ("dof = 2", "dof = 3", "dof is 3"),
    ] {
        assert!(text.contains(from), "{from}");
        let e = RobotDescription::from_toml_str(&text.replacen(from, to, 1), Path::new("arm.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains(needle), "{to}: {e}");
        assert!(e.starts_with("arm.toml: "), "{e}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A MoveIt SRDF's `<disable_collisions>` pairs join the sampled ones:
/// example-robot-data's Panda with its own SRDF keeps every pair the SRDF
/// names (those the sampling did not find marked as the SRDF's), and an
/// SRDF naming a link the URDF lacks, or one that is not XML, is an error
/// naming the SRDF.
#[test]
fn an_srdfs_disabled_pairs_are_kept_and_bad_ones_named() {
    if !crate::common::python_has("pinocchio") {
        return;
    }
    let out = crate::common::python_json(
        "import json, os, sysconfig; print(json.dumps(os.path.join(sysconfig.get_paths()['purelib'], \
         'cmeel.prefix', 'share', 'example-robot-data', 'robots', 'panda_description')))",
        &serde_json::Value::Null,
    );
    let panda: String = serde_json::from_slice(&out).unwrap();
    let srdf_path = format!("{panda}/srdf/panda.srdf");
    let srdf = std::fs::read_to_string(&srdf_path).expect("example-robot-data ships panda.srdf");
    let dir = crate::common::temp_dir("srdf");
    let config = |srdf: &str| {
        format!(
            "name = \"panda\"\nurdf = \"{panda}/urdf/panda.urdf\"\ntip_link = \"panda_hand\"\n\
             srdf = \"{srdf}\"\n"
        )
    };
    let good = write(&dir, "panda.toml", &config(&srdf_path));
    let d = import(&good, &[], "test").unwrap();
    let pairs = treemanip_core::robot::model::srdf::disabled_collisions(&srdf).unwrap();
    assert!(pairs.len() > 20, "{} pairs", pairs.len());
    for p in &pairs {
        assert!(
            d.disabled_pairs
                .iter()
                .any(|x| (x.a == p.link1 && x.b == p.link2) || (x.a == p.link2 && x.b == p.link1)),
            "{} – {} kept",
            p.link1,
            p.link2
        );
    }
    let from_srdf = d
        .disabled_pairs
        .iter()
        .filter(|x| x.reason == treemanip_core::robot::model::self_pairs::DisableReason::Srdf)
        .count();
    assert!(from_srdf > 0, "the SRDF adds pairs the sampling kept");
    // The hand against link 5: the setup assistant disabled it because
    // they touch at the default pose ("Default"); our sampling finds the
    // same (within the planner's 1 mm self-clearance at rest).
    assert!(d.disabled_pairs.iter().any(|x| x.reason
        == treemanip_core::robot::model::self_pairs::DisableReason::Default
        && [&x.a, &x.b].contains(&&"panda_link5".to_owned())
        && [&x.a, &x.b].contains(&&"panda_hand".to_owned())));
    let wrong = write(
        &dir,
        "wrong.srdf",
        "<robot name=\"x\"><disable_collisions link1=\"panda_link1\" link2=\"elbow\" reason=\"Never\"/></robot>",
    );
    let broken = write(&dir, "broken.srdf", "<robot><a></b></robot>");
    for (srdf, needle) in [
        (wrong, "link `elbow` is not in the URDF"),
        (broken, "not XML"),
        (dir.join("absent.srdf"), "cannot be read"),
    ] {
        let bad = write(&dir, "bad.toml", &config(&srdf.display().to_string()));
        let e = import(&bad, &[], "test").unwrap_err().to_string();
        assert!(
            e.contains(needle) && e.contains(&*srdf.display().to_string()),
            "{e}"
        );
    }
}
