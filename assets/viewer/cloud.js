// A scanned point cloud: the PLY file goes to /v1/trees/from-points, which
// answers the tree found in it; the file's points are drawn as grey dots
// under that tree (three.js's PLY loader reads them for display only).

import * as THREE from './vendor/three.module.min.js';
import { PLYLoader } from './vendor/PLYLoader.js';
import { api } from './api.js';

/** The tree in a PLY file's cloud, the API's answer, and the dots to draw. */
export async function treeFromCloud(file) {
  const buffer = await file.arrayBuffer();
  const answer = await api('/v1/trees/from-points', buffer, 'application/x-ply');
  const geometry = new PLYLoader().parse(buffer);
  const dots = new THREE.Points(
    geometry,
    new THREE.PointsMaterial({ color: 0x8a8f98, size: 0.004, sizeAttenuation: true }),
  );
  return { answer, dots };
}
