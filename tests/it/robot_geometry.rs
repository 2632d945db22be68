//! Collision geometry from a URDF no one here wrote: the Franka Panda that
//! `example-robot-data` ships, whose links collide as STL meshes. Every
//! mesh is found through `package://`, fitted with one to three capsules
//! per mesh, and every corner of every triangle lies inside one of its
//! link's capsules (so every triangle does: capsules are convex).

use std::path::Path;

use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use treemanip::robot::link_geometry::{LinkShape, link_geometry, mesh_triangles, resolve_mesh};

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
    for link in &links {
        let capsules: Vec<_> = link
            .shapes
            .iter()
            .filter_map(|s| match s {
                LinkShape::Capsule(c) => Some(*c),
                _ => None,
            })
            .collect();
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
        }
    }
    // Found relative to the URDF too (its package folder is above it).
    assert!(link_geometry(&robot, Some(dir), &[]).is_ok());
    // And not at all from elsewhere, with the places tried named.
    let e = link_geometry(&robot, Some(Path::new("/nonexistent")), &[]).unwrap_err();
    assert!(e.to_string().contains("not found"), "{e}");
}
