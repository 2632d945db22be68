"""Load a treemanip URDF with yourdfpy, an independent parser, and print what
it sees as JSON: every node frame's world position from yourdfpy's own
forward kinematics at the rest pose, each branch joint's damping, and the
Gazebo springStiffness values (read with the standard library's XML parser).

Usage: python3 load_tree_urdf.py FILE.urdf
"""

import json
import sys
import xml.etree.ElementTree as ET

import yourdfpy


def main(path):
    urdf = yourdfpy.URDF.load(
        path, load_meshes=False, build_collision_scene_graph=False
    )
    nodes = sorted(
        (link for link in urdf.link_map if link.startswith("node_")),
        key=lambda name: int(name[len("node_"):]),
    )
    positions = [
        [float(v) for v in urdf.get_transform(node, "world")[:3, 3]] for node in nodes
    ]
    damping = {
        j.name: float(j.dynamics.damping)
        for j in urdf.robot.joints
        if j.type == "revolute" and j.dynamics is not None
    }
    stiffness = {
        g.get("reference"): float(g.find("springStiffness").text)
        for g in ET.parse(path).getroot().findall("gazebo")
    }
    cylinders = {}
    for link in urdf.robot.links:
        for c in link.collisions:
            if c.geometry.cylinder is not None:
                cylinders[link.name] = [
                    float(c.geometry.cylinder.radius),
                    float(c.geometry.cylinder.length),
                ]
    json.dump(
        {
            "base_link": urdf.base_link,
            "positions": positions,
            "damping": damping,
            "stiffness": stiffness,
            "cylinders": cylinders,
            "actuated_joints": len(urdf.actuated_joints),
        },
        sys.stdout,
    )


if __name__ == "__main__":
    main(sys.argv[1])
