//! Collision geometry from a URDF no one here wrote: the Franka Panda that
//! `example-robot-data` ships, whose links collide as STL meshes. Every
//! mesh is found through `package://`, fitted with one to three capsules
//! per mesh, and every corner of every triangle lies inside one of its
//! link's capsules (so every triangle does: capsules are convex).

use std::path::Path;

use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use treemanip_core::robot::model::link_geometry::{link_geometry, mesh_triangles, resolve_mesh};
use treemanip_core::robot::model::mesh_fit::Capsule;

use crate::robot_chain::panda_urdf;

#[test]
fn the_pandas_meshes_are_enclosed_by_their_capsules() {
    let Some(path) = panda_urdf() else { return };
    let robot = urdf_rs::read_file(&path).unwrap();
    let dir = path.parent().unwrap();
    // `package://example-robot-data/...`: the folder that holds the
    // package, given as the package path.
    let share = dir.ancestors().nth(4).unwrap().to_path_buf();
    assert!(
        share.join("example-robot-data").is_dir(),
        "{}",
        share.display()
    );
    let links = link_geometry(&robot, None, std::slice::from_ref(&share)).unwrap();
    let meshes: usize = links.iter().map(|l| l.meshes.len()).sum();
    assert!(meshes >= 8, "{meshes} meshes");
    let mut ratios = Vec::new();
    for link in &links {
        let capsules: Vec<_> = link.shapes.iter().filter_map(Capsule::from_shape).collect();
        let urdf_link = robot.links.iter().find(|l| l.name == link.link).unwrap();
        for collision in &urdf_link.collision {
            let urdf_rs::Geometry::Mesh { filename, scale } = &collision.geometry else {
                continue;
            };
            let file = resolve_mesh(&link.link, filename, Some(dir), &[]).unwrap();
            let [x, y, z] = collision.origin.xyz.0;
            let [r, p, w] = collision.origin.rpy.0;
            let pose = Isometry3::from_parts(
                Translation3::new(x, y, z),
                UnitQuaternion::from_euler_angles(r, p, w),
            );
            let triangles =
                mesh_triangles(&link.link, &file, scale.map_or([1.0; 3], |s| s.0), &pose).unwrap();
            for t in &triangles {
                for corner in t {
                    assert!(
                        capsules.iter().any(|c| c.contains(corner)),
                        "{}: {corner} outside",
                        link.link
                    );
                }
            }
        }
        for m in &link.meshes {
            let ratio = m.volume_ratio.unwrap();
            eprintln!(
                "{:<14} {:>6} triangles  {} capsule(s)  volume / hull {ratio:.2}",
                link.link, m.triangles, m.capsules
            );
            assert!((0.9..4.0).contains(&ratio), "{}: {ratio}", link.link);
            ratios.push(ratio);
        }
    }
    // The Panda's links are tubes with the next joint's housing off to one
    // side; one capsule each takes 2.33× their hulls on average, a split
    // across the main axis about 2.0×.
    let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
    assert!(mean < 2.1, "mean volume / hull {mean:.2}");
    // Found relative to the URDF too (its package folder is above it).
    assert!(link_geometry(&robot, Some(dir), &[]).is_ok());
    // And not at all from elsewhere, with the places tried named.
    let e = link_geometry(&robot, Some(Path::new("/nonexistent")), &[]).unwrap_err();
    assert!(e.to_string().contains("not found"), "{e}");
}

/// Self-collision pairs on the Panda: neighbours along the arm (and the
/// hand welded to link 8) are `adjacent`; of the pairs found never to touch
/// over 2,000 random configurations (as `robot import` samples), at most
/// 5 % touch in 300 others drawn with another seed; the base and the hand
/// are not left out (the arm can fold the hand onto its base).
#[test]
fn the_pandas_self_collision_pairs_are_found_by_sampling() {
    use treemanip_core::robot::model::self_pairs::{DisableReason, all_link_poses, disabled_pairs};
    use treemanip_core::robot::model::urdf_chain::Chain;
    let Some(path) = panda_urdf() else { return };
    let robot = urdf_rs::read_file(&path).unwrap();
    let chain = Chain::from_robot(&robot, Some("panda_link0"), Some("panda_hand")).unwrap();
    let links = link_geometry(&robot, path.parent(), &[]).unwrap();
    let pairs = disabled_pairs(&robot, &chain, &links, 2000, 1);
    let find = |a: &str, b: &str| {
        pairs
            .iter()
            .find(|p| (p.a == a && p.b == b) || (p.a == b && p.b == a))
            .map(|p| p.reason)
    };
    for k in 0..7 {
        let (a, b) = (format!("panda_link{k}"), format!("panda_link{}", k + 1));
        if links.iter().any(|l| l.link == b) {
            assert_eq!(find(&a, &b), Some(DisableReason::Adjacent), "{a}-{b}");
        }
    }
    assert_eq!(
        find("panda_link7", "panda_hand"),
        Some(DisableReason::Adjacent)
    );
    assert_eq!(find("panda_link0", "panda_hand"), None, "{pairs:?}");
    // Never-pairs hold up on other samples.
    let never: Vec<_> = pairs
        .iter()
        .filter(|p| p.reason == DisableReason::Never)
        .collect();
    assert!(!never.is_empty());
    let again = disabled_pairs(&robot, &chain, &links, 300, 2);
    let lost = never
        .iter()
        .filter(|p| {
            !again
                .iter()
                .any(|q| q.a == p.a && q.b == p.b && q.reason == DisableReason::Never)
        })
        .count();
    assert!(
        lost * 100 <= never.len() * 5,
        "{lost} of {} never-pairs touched",
        never.len()
    );
    // Joints off the chain (the fingers) stay at zero, and every link is
    // placed.
    let poses = all_link_poses(&robot, &chain, &vec![0.0; chain.dof()]);
    assert!(poses.contains_key("panda_leftfinger") && poses.contains_key("panda_hand"));
}
