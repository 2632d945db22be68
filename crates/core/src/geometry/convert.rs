//! nalgebra's vectors and isometries as parry's math types: parry 0.31
//! moved to its own `Vec3`/`Pose` (glam-like), while the rest of treemanip
//! speaks nalgebra.

use nalgebra::{Isometry3, Vector3};
use parry3d_f64::math::{Pose, Rot3, Vec3};

/// A vector as parry's.
pub fn vec3(v: &Vector3<f64>) -> Vec3 {
    Vec3::new(v.x, v.y, v.z)
}

/// An isometry as parry's pose.
pub fn pose(iso: &Isometry3<f64>) -> Pose {
    let q = iso.rotation.quaternion();
    Pose::from_parts(
        vec3(&iso.translation.vector),
        Rot3::from_xyzw(q.i, q.j, q.k, q.w),
    )
}
