#!/usr/bin/env python3
"""Measure the public UR5 collision meshes once, for sizing our capsules.

Reads the binary STL collision meshes of the ROS-Industrial UR5 description
(../shared/reference/ur5/collision/*.stl, for reference only), places them
in our link frames (the same DH-derived frames as that description, using
its <collision><origin> transforms), and writes the vertices of each mesh's
unique vertices and triangles to tests/data/ur5_mesh_triangles.json. The
Rust test `capsules_enclose_the_reference_meshes` checks that every triangle
has all three corners inside one of our capsules; a capsule is convex, so
it then contains the whole triangle and the capsules cover the mesh surface.

It also fits one to three capsules per link: triangles are split into
slices by their centroid along the link's main axis, each slice gets the
tightest capsule around all corners of its triangles (axis by PCA, centred
on the minimax radial offset), and the split with the least total capsule
volume wins. The constants in crates/core/src/robot/ur5.rs are
these, radii rounded up by 1 mm.

Needs numpy and scipy. Usage: python3 scripts/measure-ur5-meshes.py [REF_DIR]
"""

import json
import os
import sys

import numpy as np
from scipy.optimize import minimize
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

# link: (stl file, collision origin xyz, rpy) from the reference URDF.
MESHES = {
    "base_link_inertia": ("base.stl", [0, 0, 0], [0, 0, np.pi]),
    "shoulder_link": ("shoulder.stl", [0, 0, 0], [0, 0, np.pi]),
    "upper_arm_link": ("upperarm.stl", [0, 0, 0.13585], [np.pi / 2, 0, -np.pi / 2]),
    "forearm_link": ("forearm.stl", [0, 0, 0.0165], [np.pi / 2, 0, -np.pi / 2]),
    "wrist_1_link": ("wrist1.stl", [0, 0, -0.093], [np.pi / 2, 0, 0]),
    "wrist_2_link": ("wrist2.stl", [0, 0, -0.095], [0, 0, 0]),
    "wrist_3_link": ("wrist3.stl", [0, 0, -0.0818], [np.pi / 2, 0, 0]),
}


def read_stl(path):
    with open(path, "rb") as f:
        data = f.read()
    count = int.from_bytes(data[80:84], "little")
    records = np.frombuffer(data[84 : 84 + 50 * count], dtype=np.dtype([
        ("normal", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")]))
    return records["v"].reshape(-1, 3).astype(np.float64)


def tight_capsule(points):
    centre = points.mean(axis=0)
    axis = np.linalg.svd(points - centre)[2][0]
    basis = np.linalg.svd(np.eye(3) - np.outer(axis, axis))[0][:, :2]

    def radial(offset):
        line = centre + basis @ offset
        rel = points - line
        along = rel @ axis
        return np.linalg.norm(rel - np.outer(along, axis), axis=1)

    best = minimize(lambda o: radial(o).max(), np.zeros(2), method="Nelder-Mead",
                    options={"xatol": 1e-7, "fatol": 1e-9, "maxiter": 4000})
    line = centre + basis @ best.x
    rho = radial(best.x)
    radius = rho.max()
    t = (points - line) @ axis
    slack = np.sqrt(np.maximum(radius**2 - rho**2, 0.0))
    a = line + axis * (t + slack).min()
    b = line + axis * (t - slack).max()
    return a, b, radius


def volume(capsules):
    return sum(np.pi * r * r * np.linalg.norm(b - a) + 4.0 / 3.0 * np.pi * r**3 for a, b, r in capsules)


def best_split(points, triangles):
    """One, two or three capsules over triangle slices, least volume."""
    centre = points.mean(axis=0)
    axis = np.linalg.svd(points - centre)[2][0]
    t = (points[triangles].mean(axis=1) - centre) @ axis

    def fit(masks):
        parts = [np.unique(triangles[m].ravel()) for m in masks]
        if min(len(p) for p in parts) < 4:
            return None
        return [tight_capsule(points[p]) for p in parts]

    best = [tight_capsule(points)]
    cuts = np.linspace(t.min(), t.max(), 22)[1:-1]
    for c in cuts:
        candidate = fit([t <= c, t > c])
        if candidate and volume(candidate) < volume(best) * 0.97:
            best = candidate
    for i, c1 in enumerate(cuts):
        for c2 in cuts[i + 1:]:
            candidate = fit([t <= c1, (t > c1) & (t <= c2), t > c2])
            if candidate and volume(candidate) < volume(best) * 0.97:
                best = candidate
    return best


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ref = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "../../shared/reference/ur5")
    hulls = {}
    for link, (stl, xyz, rpy) in MESHES.items():
        vertices = read_stl(os.path.join(ref, "collision", stl))
        rot = Rotation.from_euler("xyz", rpy)  # URDF rpy: fixed axes x, y, z
        placed = rot.apply(vertices) + np.array(xyz)
        unique, inverse = np.unique(np.round(placed, 7), axis=0, return_inverse=True)
        triangles = inverse.reshape(-1, 3)
        triangles = triangles[(triangles[:, 0] != triangles[:, 1]) & (triangles[:, 1] != triangles[:, 2])
                              & (triangles[:, 0] != triangles[:, 2])]
        hulls[link] = {"vertices": [[float(c) for c in v] for v in unique],
                       "triangles": [[int(i) for i in tri] for tri in triangles]}
        capsules = best_split(unique, triangles)
        print(f"{link:18} {len(unique):5} vertices, {len(triangles)} triangles:")
        for a, b, r in capsules:
            print(f"    a: [{a[0]:.4f}, {a[1]:.4f}, {a[2]:.4f}], b: [{b[0]:.4f}, {b[1]:.4f}, {b[2]:.4f}], radius: {r + 0.001:.4f}")
    out = os.path.join(here, "../tests/data/ur5_mesh_triangles.json")
    with open(out, "w") as f:
        json.dump({"source": "ROS-Industrial universal_robot ur5 collision meshes (BSD), "
                             "vertices (m, in treemanip's UR5 link frames) and triangles; "
                             "scripts/measure-ur5-meshes.py",
                   "links": hulls}, f, separators=(',', ':'))
    print("wrote", os.path.normpath(out))


if __name__ == "__main__":
    main()
