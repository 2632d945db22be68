// treemanip viewer: the shapes it draws (trees as cylinders and spheres)
// and their colours. The tree frame is z-up, metres.

import * as THREE from './vendor/three.module.min.js';

export const COLOURS = {
  background: 0xf2f4f7,
  tree: 0x7a6a58,
  predicted: 0xe07b20,
  truth: 0x2e9e4f,
  target: 0x3b6fd8,
  arm: 0x8a94a6,
  gripper: 0x4a5160,
  selected: 0xd02070,
  region: 0xc81e1e,
};
export const NODE_RADIUS = 0.012; // m, drawn size of a node
const MIN_BRANCH_RADIUS = 0.003; // m, so thin twigs stay visible

const UP = new THREE.Vector3(0, 1, 0);

/** A cylinder or capsule mesh from a to b (THREE.Vector3s). */
export function placeBetween(mesh, a, b) {
  const d = new THREE.Vector3().subVectors(b, a);
  const length = d.length();
  mesh.position.copy(a).addScaledVector(d, 0.5);
  if (length > 1e-9) mesh.quaternion.setFromUnitVectors(UP, d.multiplyScalar(1 / length));
  return length;
}

/** A tree drawn as branch cylinders and node spheres, in one colour. */
export class TreeMesh {
  constructor(tree, colour, { opacity = 1, pickable = false } = {}) {
    this.tree = tree;
    this.group = new THREE.Group();
    const material = new THREE.MeshStandardMaterial({
      color: colour, transparent: opacity < 1, opacity, roughness: 0.8,
    });
    this.branches = [];
    this.nodes = [];
    const unit = new THREE.CylinderGeometry(1, 1, 1, 12);
    const ball = new THREE.SphereGeometry(NODE_RADIUS, 14, 10);
    tree.parents.forEach((parent, i) => {
      const node = new THREE.Mesh(ball, material.clone());
      node.userData.node = i;
      if (pickable) node.userData.pickable = true;
      this.nodes.push(node);
      this.group.add(node);
      if (parent !== null) {
        const r = Math.max(tree.radius[i] ?? MIN_BRANCH_RADIUS, MIN_BRANCH_RADIUS);
        const branch = new THREE.Mesh(unit, material);
        branch.userData = { child: i, parent, r };
        this.branches.push(branch);
        this.group.add(branch);
      }
    });
    this.update(tree.positions);
  }

  /** Moves nodes and branches to `positions` ([[x,y,z]] m). */
  update(positions) {
    const p = positions.map((q) => new THREE.Vector3(q[0], q[1], q[2]));
    this.nodes.forEach((m, i) => m.position.copy(p[i]));
    for (const b of this.branches) {
      const length = placeBetween(b, p[b.userData.parent], p[b.userData.child]);
      b.scale.set(b.userData.r, length, b.userData.r);
    }
  }

  colourNode(i, colour) {
    this.nodes[i].material.color.set(colour);
  }

  /** Each branch its own colour: `colourOf(child node)` → THREE.Color. */
  colourBranches(colourOf) {
    for (const b of this.branches) {
      b.material = b.material.clone();
      b.material.color.set(colourOf(b.userData.child));
    }
  }
}


/**
 * A mesh for one collision shape of `/v1/robot/link-poses` in its link's
 * frame (the API's one shape schema): capsules, spheres and cylinders in
 * `arm`, boxes (the gripper's) in `grip`.
 */
export function shapeMesh(s, arm, grip) {
  let m = null;
  if (s.kind === 'capsule') {
    const a = new THREE.Vector3(...s.a);
    const b = new THREE.Vector3(...s.b);
    m = new THREE.Mesh(new THREE.CapsuleGeometry(s.radius, Math.max(a.distanceTo(b), 1e-6), 6, 16), arm);
    placeBetween(m, a, b);
    return m;
  }
  if (s.kind === 'sphere') {
    m = new THREE.Mesh(new THREE.SphereGeometry(s.radius, 16, 12), arm);
  } else if (s.kind === 'cylinder') {
    m = new THREE.Mesh(new THREE.CylinderGeometry(s.radius, s.radius, 2 * s.half_length, 16), arm);
  } else if (s.kind === 'box') {
    const h = s.half_extents;
    m = new THREE.Mesh(new THREE.BoxGeometry(2 * h[0], 2 * h[1], 2 * h[2]), grip);
  } else {
    return null;
  }
  m.position.set(s.centre[0], s.centre[1], s.centre[2]);
  if (s.rotation) {
    m.quaternion.set(s.rotation[0], s.rotation[1], s.rotation[2], s.rotation[3]);
  } else if (s.yaw) {
    m.quaternion.setFromAxisAngle(new THREE.Vector3(0, 0, 1), s.yaw);
  }
  if (s.kind === 'cylinder') {
    // three.js cylinders run along y; ours along the rotation's z.
    m.quaternion.multiply(new THREE.Quaternion().setFromAxisAngle(new THREE.Vector3(1, 0, 0), Math.PI / 2));
  }
  return m;
}
