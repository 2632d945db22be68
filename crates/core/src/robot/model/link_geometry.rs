//! Each link's collision geometry, read from its URDF.
//!
//! Primitives (box, cylinder, sphere, capsule) are kept as they are, placed
//! by their `<origin>` in the link's frame. Meshes (STL, COLLADA, OBJ, read
//! with `mesh-loader`) are replaced by the few capsules that enclose every
//! triangle ([`mesh_fit`](crate::robot::model::mesh_fit)), after their `scale` and
//! `<origin>`; how snugly is reported per mesh.
//!
//! A mesh's `filename` is found the way ROS finds it:
//! - `package://NAME/rest` in the first directory of the package path that
//!   holds `NAME/rest` (the package path: `TREEMANIP_PACKAGE_PATH`,
//!   colon-separated directories that contain package folders, as
//!   `ROS_PACKAGE_PATH`; then the URDF's directory and its ancestors, for
//!   a description unpacked with its package folder around it);
//! - `file:///abs/path` as the path;
//! - anything else relative to the URDF's directory.
//!
//! A mesh that is not found, cannot be read or has no triangles is an
//! error naming the link, the file and where it was looked for.

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Point3, Vector3};

use crate::geometry::shape::Shape;
use crate::robot::model::mesh_fit::{Capsule, fit_capsules};
use crate::robot::model::urdf_chain::isometry;

/// The environment variable listing package directories.
pub const PACKAGE_PATH_VAR: &str = "TREEMANIP_PACKAGE_PATH";

/// How one mesh was approximated.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshReport {
    pub file: PathBuf,
    pub triangles: usize,
    pub capsules: usize,
    /// The capsules' volume over the mesh's convex hull's.
    pub volume_ratio: Option<f64>,
}

/// A link's collision shapes.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkGeometry {
    pub link: String,
    pub shapes: Vec<Shape>,
    pub meshes: Vec<MeshReport>,
}

/// Collision geometry that cannot be used, naming the link and the file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GeometryError {
    #[error("link `{link}`: mesh `{filename}` not found (looked in {searched})")]
    MissingMesh {
        link: String,
        filename: String,
        searched: String,
    },
    #[error("link `{link}`: mesh {file} cannot be read: {message}")]
    UnreadableMesh {
        link: String,
        file: PathBuf,
        message: String,
    },
    #[error("link `{link}`: mesh {file} has no triangles")]
    EmptyMesh { link: String, file: PathBuf },
    #[error("link `{link}`: {message}")]
    BadShape { link: String, message: String },
}

/// The package path from `TREEMANIP_PACKAGE_PATH` (empty when unset).
pub fn package_path_from_env() -> Vec<PathBuf> {
    std::env::var_os(PACKAGE_PATH_VAR)
        .map(|v| {
            std::env::split_paths(&v)
                .filter(|p| !p.as_os_str().is_empty())
                .collect()
        })
        .unwrap_or_default()
}

/// Where the mesh `filename` of `link` is (see the module's documentation).
pub fn resolve_mesh(
    link: &str,
    filename: &str,
    urdf_dir: Option<&Path>,
    packages: &[PathBuf],
) -> Result<PathBuf, GeometryError> {
    let mut candidates: Vec<PathBuf> = Vec::new();
    if let Some(rest) = filename.strip_prefix("package://") {
        let ancestors = urdf_dir.into_iter().flat_map(Path::ancestors);
        for dir in packages.iter().map(PathBuf::as_path).chain(ancestors) {
            candidates.push(dir.join(rest));
        }
    } else if let Some(path) = filename.strip_prefix("file://") {
        candidates.push(PathBuf::from(path));
    } else {
        let path = Path::new(filename);
        candidates.push(match urdf_dir {
            Some(dir) if path.is_relative() => dir.join(path),
            _ => path.to_path_buf(),
        });
    }
    candidates
        .iter()
        .find(|p| p.is_file())
        .cloned()
        .ok_or_else(|| GeometryError::MissingMesh {
            link: link.to_owned(),
            filename: filename.to_owned(),
            searched: if candidates.is_empty() {
                format!("no directory: set {PACKAGE_PATH_VAR}")
            } else {
                candidates
                    .iter()
                    .map(|p| p.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            },
        })
}

/// The triangles of the mesh at `file`, scaled and placed by `pose`.
pub fn mesh_triangles(
    link: &str,
    file: &Path,
    scale: [f64; 3],
    pose: &Isometry3<f64>,
) -> Result<Vec<[Point3<f64>; 3]>, GeometryError> {
    let scene = mesh_loader::Loader::default()
        .merge_meshes(true)
        .load(file)
        .map_err(|e| GeometryError::UnreadableMesh {
            link: link.to_owned(),
            file: file.to_path_buf(),
            message: e.to_string(),
        })?;
    let mut triangles = Vec::new();
    for mesh in &scene.meshes {
        let corner = |i: u32| {
            mesh.vertices.get(i as usize).map(|v| {
                pose * Point3::new(
                    f64::from(v[0]) * scale[0],
                    f64::from(v[1]) * scale[1],
                    f64::from(v[2]) * scale[2],
                )
            })
        };
        for face in &mesh.faces {
            let (Some(a), Some(b), Some(c)) = (corner(face[0]), corner(face[1]), corner(face[2]))
            else {
                return Err(GeometryError::UnreadableMesh {
                    link: link.to_owned(),
                    file: file.to_path_buf(),
                    message: format!("a face indexes past its {} vertices", mesh.vertices.len()),
                });
            };
            if [a, b, c]
                .iter()
                .all(|p| p.coords.iter().all(|x| x.is_finite()))
            {
                triangles.push([a, b, c]);
            }
        }
    }
    if triangles.is_empty() {
        return Err(GeometryError::EmptyMesh {
            link: link.to_owned(),
            file: file.to_path_buf(),
        });
    }
    Ok(triangles)
}

fn positive(link: &str, what: &str, v: f64) -> Result<f64, GeometryError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(GeometryError::BadShape {
            link: link.to_owned(),
            message: format!("{what} must be positive and finite, it is {v}"),
        })
    }
}

/// The collision geometry of every link of `robot` that has any, in the
/// URDF's order.
pub fn link_geometry(
    robot: &urdf_rs::Robot,
    urdf_dir: Option<&Path>,
    packages: &[PathBuf],
) -> Result<Vec<LinkGeometry>, GeometryError> {
    let mut out = Vec::new();
    for link in robot.links.iter().filter(|l| !l.collision.is_empty()) {
        let name = link.name.as_str();
        let mut geometry = LinkGeometry {
            link: name.to_owned(),
            shapes: Vec::new(),
            meshes: Vec::new(),
        };
        for collision in &link.collision {
            let pose = isometry(&collision.origin);
            match &collision.geometry {
                urdf_rs::Geometry::Box { size } => {
                    let [x, y, z] = size.0;
                    geometry.shapes.push(Shape::Box {
                        pose,
                        half_extents: Vector3::new(
                            positive(name, "box size x", x)? / 2.0,
                            positive(name, "box size y", y)? / 2.0,
                            positive(name, "box size z", z)? / 2.0,
                        ),
                    });
                }
                urdf_rs::Geometry::Cylinder { radius, length } => {
                    geometry.shapes.push(Shape::Cylinder {
                        pose,
                        radius: positive(name, "cylinder radius", *radius)?,
                        half_length: positive(name, "cylinder length", *length)? / 2.0,
                    });
                }
                urdf_rs::Geometry::Capsule { radius, length } => {
                    let half = positive(name, "capsule length", *length)? / 2.0;
                    geometry.shapes.push(Shape::Capsule {
                        a: pose * Point3::new(0.0, 0.0, -half),
                        b: pose * Point3::new(0.0, 0.0, half),
                        radius: positive(name, "capsule radius", *radius)?,
                    });
                }
                urdf_rs::Geometry::Sphere { radius } => {
                    geometry.shapes.push(Shape::Sphere {
                        centre: pose * Point3::origin(),
                        radius: positive(name, "sphere radius", *radius)?,
                    });
                }
                urdf_rs::Geometry::Mesh { filename, scale } => {
                    let file = resolve_mesh(name, filename, urdf_dir, packages)?;
                    let scale = scale.map_or([1.0; 3], |s| s.0);
                    for (k, s) in scale.iter().enumerate() {
                        positive(
                            name,
                            ["mesh scale x", "mesh scale y", "mesh scale z"][k],
                            *s,
                        )?;
                    }
                    let triangles = mesh_triangles(name, &file, scale, &pose)?;
                    let fit = fit_capsules(&triangles).ok_or_else(|| GeometryError::EmptyMesh {
                        link: name.to_owned(),
                        file: file.clone(),
                    })?;
                    geometry.meshes.push(MeshReport {
                        file,
                        triangles: fit.triangles,
                        capsules: fit.capsules.len(),
                        volume_ratio: fit.volume_ratio,
                    });
                    geometry
                        .shapes
                        .extend(fit.capsules.iter().map(Capsule::shape));
                    geometry
                        .shapes
                        .extend(fit.cylinder.map(|c| Shape::Cylinder {
                            pose: c.pose,
                            radius: c.radius,
                            half_length: c.half_length,
                        }));
                }
            }
        }
        out.push(geometry);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A binary STL of `triangles`.
    fn stl(triangles: &[[[f32; 3]; 3]]) -> Vec<u8> {
        let mut out = vec![0u8; 80];
        out.extend_from_slice(&(triangles.len() as u32).to_le_bytes());
        for t in triangles {
            out.extend_from_slice(&[0u8; 12]);
            for p in t {
                for x in p {
                    out.extend_from_slice(&x.to_le_bytes());
                }
            }
            out.extend_from_slice(&[0u8; 2]);
        }
        out
    }

    fn urdf(mesh: &str, scale: &str) -> String {
        format!(
            r#"<robot name="r">
  <link name="base"><collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision></link>
  <link name="arm">
    <collision><origin xyz="0 0 0.5" rpy="0 0 0"/><geometry><mesh filename="{mesh}" {scale}/></geometry></collision>
    <collision><geometry><sphere radius="0.05"/></geometry></collision>
  </link>
  <joint name="j" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
</robot>"#
        )
    }

    #[test]
    fn meshes_are_found_through_the_package_path_and_enclosed() {
        let scratch = tempfile::tempdir().unwrap();
        let dir = scratch.path();
        let pkg = dir.join("share").join("my_arm").join("meshes");
        std::fs::create_dir_all(&pkg).unwrap();
        // A thin bar 0.4 m long along x.
        let bar = [
            [[0.0, -0.01, 0.0], [0.4, -0.01, 0.0], [0.4, 0.01, 0.0]],
            [[0.0, -0.01, 0.0], [0.4, 0.01, 0.0], [0.0, 0.01, 0.02]],
        ];
        std::fs::write(pkg.join("bar.stl"), stl(&bar)).unwrap();
        let robot = urdf_rs::read_from_string(&urdf(
            "package://my_arm/meshes/bar.stl",
            r#"scale="0.5 1 1""#,
        ))
        .unwrap();
        // Not found without the package path: the error says where it looked.
        let e = link_geometry(&robot, None, &[]).unwrap_err();
        assert!(
            matches!(&e, GeometryError::MissingMesh { link, .. } if link == "arm"),
            "{e}"
        );
        let links = link_geometry(&robot, None, &[dir.join("share")]).unwrap();
        assert_eq!(links.len(), 2);
        let arm = &links[1];
        assert_eq!(arm.meshes.len(), 1);
        assert_eq!(arm.meshes[0].triangles, 2);
        // Scaled to 0.2 m and lifted 0.5 m by the origin: every corner is
        // inside the capsules.
        let capsules: Vec<Capsule> = arm.shapes.iter().filter_map(Capsule::from_shape).collect();
        for t in &bar {
            for p in t {
                let q = Point3::new(
                    f64::from(p[0]) * 0.5,
                    f64::from(p[1]),
                    f64::from(p[2]) + 0.5,
                );
                assert!(capsules.iter().any(|c| c.contains(&q)), "{q} outside");
            }
        }
        assert!(capsules.iter().all(|c| c.height() <= 0.2 + 1e-6));
        assert!(
            arm.shapes.iter().any(
                |s| matches!(s, Shape::Sphere { radius, .. } if (*radius - 0.05).abs() < 1e-12)
            )
        );
        // Relative to the URDF's directory, too.
        let relative = urdf_rs::read_from_string(&urdf("meshes/bar.stl", "")).unwrap();
        assert!(link_geometry(&relative, Some(&dir.join("share").join("my_arm")), &[]).is_ok());
        // An unreadable file names the link and the file.
        std::fs::write(pkg.join("bad.stl"), b"solid nothing\nendsolid").unwrap();
        let bad = urdf_rs::read_from_string(&urdf("package://my_arm/meshes/bad.stl", "")).unwrap();
        let e = link_geometry(&bad, None, &[dir.join("share")]).unwrap_err();
        assert!(
            matches!(&e, GeometryError::EmptyMesh { link, .. } | GeometryError::UnreadableMesh { link, .. } if link == "arm"),
            "{e}"
        );
        // A negative scale is refused.
        let flipped = urdf_rs::read_from_string(&urdf(
            "package://my_arm/meshes/bar.stl",
            r#"scale="-1 1 1""#,
        ))
        .unwrap();
        assert!(matches!(
            link_geometry(&flipped, None, &[dir.join("share")]).unwrap_err(),
            GeometryError::BadShape { .. }
        ));
    }
}
