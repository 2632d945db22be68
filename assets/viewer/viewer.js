// treemanip viewer: draws what the API computes. Trees come from
// /v1/trees/example, /v1/trees/urdf, a scanned cloud (/v1/trees/from-points)
// or pasted JSON; predictions from
// /v1/forward beside /v1/simulate; affordances from /v1/policy; arm motion
// from /v1/plan and /v1/robot/link-poses. Nothing here re-implements the
// server's geometry. The tree frame is z-up, metres.

import * as THREE from './vendor/three.module.min.js';
import { OrbitControls } from './vendor/OrbitControls.js';
import { COLOURS, NODE_RADIUS, TreeMesh, shapeMesh } from './meshes.js';
import { ApiError, api } from './api.js';
import { treeFromCloud } from './cloud.js';

const $ = (id) => document.getElementById(id);

function showError(message) {
  const box = $('error');
  box.textContent = message;
  box.hidden = !message;
}

/** Runs an async UI action: one at a time, errors shown in the page. */
async function action(fn) {
  showError('');
  document.body.dataset.busy = '1';
  try {
    await fn();
  } catch (e) {
    showError(e instanceof ApiError ? e.message : `viewer: ${e.message}`);
  } finally {
    document.body.dataset.busy = '0';
  }
}

// ---------------------------------------------------------------- scene

const view = $('view');
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
renderer.setClearColor(COLOURS.background);
view.appendChild(renderer.domElement);

const scene = new THREE.Scene();
const camera = new THREE.PerspectiveCamera(45, 1, 0.01, 50);
camera.up.set(0, 0, 1);
camera.position.set(1.8, -1.6, 1.4);
const controls = new OrbitControls(camera, renderer.domElement);
controls.target.set(0, 0, 0.6);
controls.update();

scene.add(new THREE.HemisphereLight(0xffffff, 0x888877, 2.0));
const sun = new THREE.DirectionalLight(0xffffff, 1.5);
sun.position.set(2, -3, 4);
scene.add(sun);
const grid = new THREE.GridHelper(3, 30, 0xb0b6c0, 0xd6dae0);
grid.rotation.x = Math.PI / 2; // into the z = 0 plane
scene.add(grid);
scene.add(new THREE.AxesHelper(0.25));

function resize() {
  const w = view.clientWidth || 1;
  const h = view.clientHeight || 1;
  renderer.setSize(w, h, false);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', resize);
resize();

const layers = {}; // name → THREE.Object3D currently in the scene

function setLayer(name, object) {
  if (layers[name]) {
    scene.remove(layers[name]);
    layers[name].traverse((o) => {
      if (o.geometry) o.geometry.dispose();
    });
  }
  if (object) {
    object.name = name;
    scene.add(object);
  }
  layers[name] = object || null;
}

// ---------------------------------------------------------------- state

const state = {
  tree: null, // tree JSON as the API takes it
  treeMesh: null,
  selected: 1,
  truth: null, // /v1/simulate answer for the current push
  target: null, // [[x,y,z]] per node
  plan: null,
  poses: null, // /v1/robot/link-poses answer along the plan
  armLinks: [], // THREE.Group per link
  playing: false,
  frame: 0,
  planTruth: null, // simulated result of the plan's push
};

function cm(v) {
  return (100 * v).toFixed(1);
}

function norm(v) {
  return Math.hypot(v[0], v[1], v[2]);
}

function clearResults() {
  for (const name of ['predicted', 'truth', 'target', 'affordance', 'arm', 'cloud']) setLayer(name, null);
  state.truth = null;
  state.target = null;
  state.plan = null;
  state.poses = null;
  state.armLinks = [];
  state.playing = false;
  $('error-table').tBodies[0].replaceChildren();
  $('policy-list').replaceChildren();
  for (const id of ['predict-status', 'policy-status', 'plan-status', 'phase']) $(id).textContent = '';
  $('play').disabled = true;
  $('scrub').disabled = true;
}

function setTree(tree, origin) {
  clearResults();
  state.tree = tree;
  state.treeMesh = new TreeMesh(tree, COLOURS.tree, { pickable: true });
  setLayer('tree', state.treeMesh.group);
  const n = tree.positions.length;
  const select = $('push-node');
  select.replaceChildren();
  for (let i = 1; i < n; i++) select.add(new Option(String(i), String(i)));
  selectNode(n - 1);
  // Frame the tree.
  const box = new THREE.Box3().setFromObject(state.treeMesh.group);
  const centre = box.getCenter(new THREE.Vector3());
  const size = box.getSize(new THREE.Vector3()).length();
  controls.target.copy(centre);
  camera.position.copy(centre).add(new THREE.Vector3(1.1, -1.0, 0.6).multiplyScalar(Math.max(size, 0.5)));
  controls.update();
  $('tree-json').value = JSON.stringify(tree);
  $('tree-status').textContent = `${n} nodes (${origin}).`;
  document.body.dataset.tree = String(n);
}

function selectNode(i) {
  if (!state.treeMesh) return;
  state.selected = i;
  state.treeMesh.nodes.forEach((m, k) => m.material.color.set(k === i ? COLOURS.selected : COLOURS.tree));
  $('push-node').value = String(i);
}

function pushVector() {
  const v = ['push-x', 'push-y', 'push-z'].map((id) => Number($(id).value) / 100);
  if (!v.every(Number.isFinite)) throw new Error('the push must be three numbers (cm)');
  return v;
}

function requireTree() {
  if (!state.tree) throw new Error('load a tree first');
}

// ---------------------------------------------------------------- flow 1: tree

async function loadExample() {
  const nodes = $('example-nodes').value;
  const seed = $('example-seed').value;
  const answer = await api(`/v1/trees/example?nodes=${encodeURIComponent(nodes)}&seed=${encodeURIComponent(seed)}`);
  setTree(answer.tree, `example, seed ${answer.seed}`);
}

async function loadUrdf(file) {
  const text = await file.text();
  const answer = await api('/v1/trees/urdf', { urdf: text });
  setTree(answer.tree, file.name);
}

async function loadCloud(file) {
  const { answer, dots } = await treeFromCloud(file);
  setTree(answer.tree, `${file.name}: ${answer.points_used} points used`);
  setLayer('cloud', dots);
  document.body.dataset.cloud = String(dots.geometry.attributes.position.count);
  if (answer.warnings.length) $('tree-status').textContent += ` ${answer.warnings.join(' ')}`;
}

async function loadJson() {
  let tree;
  try {
    tree = JSON.parse($('tree-json').value);
  } catch (e) {
    throw new Error(`the tree is not JSON: ${e.message}`);
  }
  // The server validates; /v1/simulate of a zero push is its cheapest
  // check of a tree, so a bad tree shows the API's own message.
  await api('/v1/simulate', { tree, contact_node: 1, push: [0, 0, 0] });
  setTree(tree, 'pasted JSON');
}

// ---------------------------------------------------------------- flow 2: predict vs truth

async function predict() {
  requireTree();
  const push = pushVector();
  const node = state.selected;
  const [forward, truth] = await Promise.all([
    api('/v1/forward', { tree: state.tree, contact_node: node, push }),
    api('/v1/simulate', { tree: state.tree, contact_node: node, push }),
  ]);
  const predicted = forward.positions[0];
  state.truth = truth;
  setLayer('predicted', new TreeMesh({ ...state.tree, positions: predicted }, COLOURS.predicted, { opacity: 0.85 }).group);
  const truthMesh = new TreeMesh({ ...state.tree, positions: truth.final_positions }, COLOURS.truth, { opacity: 0.85 });
  // The true tree's branches by bending stress (blue: none, red: the peak).
  const peak = truth.peak_stress;
  if (peak) truthMesh.colourBranches((child) => heat(truth.branch_stress[child] ?? 0, peak.stress));
  setLayer('truth', truthMesh.group);
  const body = $('error-table').tBodies[0];
  body.replaceChildren();
  let sum = 0;
  let max = 0;
  predicted.forEach((p, i) => {
    const t = truth.final_positions[i];
    const e = norm([p[0] - t[0], p[1] - t[1], p[2] - t[2]]);
    sum += e;
    max = Math.max(max, e);
    const row = body.insertRow();
    for (const text of [i, cm(norm(forward.displacements[0][i])), cm(norm(truth.displacements[i])), cm(e)]) {
      row.insertCell().textContent = String(text);
    }
  });
  const n = predicted.length;
  const warn = forward.warnings ? ` Warnings: ${forward.warnings.map((w) => w.message).join('; ')}` : '';
  $('predict-status').textContent =
    `Node ${node}, push ${push.map(cm).join(', ')} cm: mean error ${cm(sum / n)} cm, max ${cm(max)} cm ` +
    `(${forward.model.name}).` +
    (peak ? ` Peak bending stress ${(peak.stress / 1e6).toFixed(1)} MPa at branch ${peak.node} (true tree's branches coloured by stress).` : '') +
    warn;
}

// ---------------------------------------------------------------- flow 3: target and policy

function showTarget(target) {
  state.target = target;
  setLayer('target', new TreeMesh({ ...state.tree, positions: target }, COLOURS.target, { opacity: 0.45 }).group);
}

async function targetFromPush() {
  requireTree();
  const push = pushVector();
  const truth = await api('/v1/simulate', { tree: state.tree, contact_node: state.selected, push });
  showTarget(truth.final_positions);
  $('policy-status').textContent = `Target: node ${state.selected} pushed ${push.map(cm).join(', ')} cm (simulated).`;
}

function loadTarget() {
  requireTree();
  let target;
  try {
    target = JSON.parse($('target-json').value);
  } catch (e) {
    throw new Error(`the target is not JSON: ${e.message}`);
  }
  if (!Array.isArray(target)) throw new Error('the target must be a list of [x, y, z]');
  showTarget(target);
}

/** Blue (low) → red (high) for a value in [0, max] (an affordance share, a stress). */
function heat(value, max) {
  const c = new THREE.Color();
  c.setHSL(0.66 * (1 - Math.min(value / (max || 1), 1)), 0.85, 0.5);
  return c;
}

async function policy() {
  requireTree();
  if (!state.target) throw new Error('set a target first (e.g. “Target = simulated push”)');
  const answer = await api('/v1/policy', { tree: state.tree, target_positions: state.target });
  const group = new THREE.Group();
  const max = Math.max(...answer.candidates.map((c) => c.affordance));
  const ball = new THREE.SphereGeometry(NODE_RADIUS * 1.5, 16, 12);
  for (const c of answer.candidates) {
    const p = state.tree.positions[c.node];
    const m = new THREE.Mesh(ball, new THREE.MeshBasicMaterial({ color: heat(c.affordance, max) }));
    m.position.set(p[0], p[1], p[2]);
    m.userData = { node: c.node, affordance: c.affordance };
    group.add(m);
  }
  const top = answer.candidates.slice(0, 3);
  for (const c of top) {
    const p = state.tree.positions[c.node];
    const length = norm(c.push);
    const dir = new THREE.Vector3(...c.push).normalize();
    const arrow = new THREE.ArrowHelper(dir, new THREE.Vector3(...p), Math.max(length * 3, 0.06), 0xc01010, 0.025, 0.015);
    arrow.userData = { node: c.node, rank: c.rank };
    group.add(arrow);
  }
  group.userData.arrows = top.length;
  setLayer('affordance', group);
  const list = $('policy-list');
  list.replaceChildren();
  for (const c of answer.candidates.slice(0, 5)) {
    const li = document.createElement('li');
    li.textContent = `node ${c.node}: ${(100 * c.affordance).toFixed(1)} %, push ${c.push.map(cm).join(', ')} cm`;
    list.appendChild(li);
  }
  $('policy-status').textContent = `Affordance per node as colour (blue low, red high); top ${top.length} pushes as arrows (drawn ×3).`;
}

// ---------------------------------------------------------------- flow 4: plan and play

/** The arm's links, and a post from the ground to its base (the mount). */
function armMesh(links, base) {
  const group = new THREE.Group();
  const [x, y, z] = base.position;
  if (z > 0.01) {
    const post = new THREE.Mesh(
      new THREE.CylinderGeometry(0.06, 0.08, z, 20),
      new THREE.MeshStandardMaterial({ color: COLOURS.gripper, roughness: 0.7 }),
    );
    post.rotation.x = Math.PI / 2;
    post.position.set(x, y, z / 2);
    group.add(post);
  }
  const armMaterial = new THREE.MeshStandardMaterial({ color: COLOURS.arm, roughness: 0.5, metalness: 0.2 });
  const gripMaterial = new THREE.MeshStandardMaterial({ color: COLOURS.gripper, roughness: 0.6 });
  const frames = links.map((link) => {
    const frame = new THREE.Group();
    frame.name = link.name;
    for (const s of link.shapes) {
      const m = shapeMesh(s, armMaterial, gripMaterial);
      if (m) frame.add(m);
    }
    group.add(frame);
    return frame;
  });
  group.userData.links = frames.length;
  return { group, frames };
}

function showFrame(k) {
  const { plan, poses } = state;
  if (!plan || !poses) return;
  k = Math.max(0, Math.min(k, poses.poses.length - 1));
  state.frame = k;
  poses.poses[k].forEach((pose, i) => {
    state.armLinks[i].position.set(pose[0], pose[1], pose[2]);
    state.armLinks[i].quaternion.set(pose[3], pose[4], pose[5], pose[6]);
  });
  // While pushing, the tree follows the simulated push linearly in time.
  const traj = plan.trajectory;
  const start = plan.push_start_index;
  let phase = 'approach';
  let f = 0;
  if (start !== null && k >= start && state.planTruth) {
    const t0 = traj[start].t;
    const t1 = traj[traj.length - 1].t;
    f = t1 > t0 ? (traj[k].t - t0) / (t1 - t0) : 1;
    phase = 'push';
  }
  const p0 = state.tree.positions;
  const p1 = state.planTruth ? state.planTruth.final_positions : p0;
  state.treeMesh.update(p0.map((p, i) => p.map((v, j) => v + f * (p1[i][j] - v))));
  $('scrub').value = String(k);
  $('phase').textContent = `${phase} · t = ${traj[k].t.toFixed(2)} s`;
}

/** A fruit (sphere) across the selected node's branch, 1 cm above its middle. */
function fruitRegion() {
  const node = state.selected;
  const parent = state.tree.parents[node];
  if (parent === null || parent === undefined) throw new Error('select a non-root node for the fruit');
  const [a, b] = [state.tree.positions[parent], state.tree.positions[node]];
  const radius = Number($('fruit-radius').value) / 100;
  if (!(radius > 0)) throw new Error('the fruit radius must be positive');
  const centre = [0, 1, 2].map((k) => (a[k] + b[k]) / 2 + (k === 2 ? 0.01 : 0));
  return { kind: 'sphere', centre, radius };
}

/** The regions of a `clear` objective as translucent shapes. */
function showRegions(regions) {
  const group = new THREE.Group();
  const material = new THREE.MeshBasicMaterial({ color: COLOURS.region, transparent: true, opacity: 0.55, depthWrite: false });
  for (const r of regions) {
    if (r.kind !== 'sphere') continue;
    const ball = new THREE.Mesh(new THREE.SphereGeometry(r.radius, 32, 24), material);
    ball.position.set(...r.centre);
    group.add(ball);
  }
  setLayer('region', group);
}

async function plan() {
  requireTree();
  const clear = $('plan-objective').value === 'clear';
  if (!clear && !state.target) throw new Error('set a target first (e.g. “Target = simulated push”)');
  $('plan-status').textContent = 'Planning…';
  const request = {
    tree: state.tree,
    strategy: $('plan-strategy').value,
    seed: 1,
  };
  if (clear) {
    const region = fruitRegion();
    request.objective = { kind: 'clear', regions: [region] };
    showRegions([region]);
    setLayer('target', null);
  } else {
    request.target_positions = state.target;
    setLayer('region', null);
  }
  request.robot = { name: $('plan-robot').value || undefined };
  if ($('plan-region').checked) {
    request.robot.base_region = { min: [-1.0, -0.5, 0.1], max: [0.0, 0.5, 1.0] };
  }
  state.playing = false;
  // The arm's scene: tree, target and affordances; the push comparison
  // would hide it.
  for (const name of ['arm', 'predicted', 'truth']) setLayer(name, null);
  state.treeMesh.update(state.tree.positions);
  let answer;
  try {
    answer = await api('/v1/plan', request);
  } catch (e) {
    $('plan-status').textContent = '';
    throw e;
  }
  const tried = answer.attempts.length;
  if (answer.status !== 'planned') {
    $('plan-status').textContent = `No plan (${tried} attempts; outcomes: ${answer.attempts.map((a) => a.outcome).join(', ')}).`;
    document.body.dataset.plan = 'no_plan';
    return;
  }
  const configurations = answer.trajectory.map((p) => p.q);
  const [poses, truth] = await Promise.all([
    api('/v1/robot/link-poses', { robot: answer.robot, base: answer.base, configurations }),
    api('/v1/simulate', { tree: state.tree, contact_node: answer.node, push: answer.push }),
  ]);
  state.plan = answer;
  state.poses = poses;
  state.planTruth = truth;
  const arm = armMesh(poses.links, answer.base);
  state.armLinks = arm.frames;
  setLayer('arm', arm.group);
  const scrub = $('scrub');
  scrub.max = String(configurations.length - 1);
  scrub.disabled = false;
  $('play').disabled = false;
  showFrame(0);
  const err = answer.predicted_error === null ? '–' : cm(answer.predicted_error);
  const what = answer.objective === 'clear' ? 'deepest intrusion into the fruit' : 'error';
  const loads = answer.simulated_loads
    ? ` Held: peak stress ${(answer.simulated_loads.peak_stress / 1e6).toFixed(1)} MPa, force ${answer.simulated_loads.contact_force.toFixed(1)} N.`
    : '';
  const guard =
    answer.guard_contact_force === null || answer.guard_contact_force === undefined
      ? ''
      : ` Stop the push when the wrist reads ${answer.guard_contact_force.toFixed(1)} N (guard).`;
  $('plan-status').textContent =
    `Push node ${answer.node} by ${answer.push.map(cm).join(', ')} cm from base ` +
    `(${answer.base.position.map((v) => v.toFixed(2)).join(', ')}) m: predicted ${what} ${err} cm ` +
    `(no action ${cm(answer.no_action_error)} cm); ${configurations.length} waypoints, ` +
    `${answer.total_ms.toFixed(0)} ms.${loads}${guard}`;
  document.body.dataset.plan = 'planned';
  play(true);
}

let playClock = null;

function play(on) {
  state.playing = on;
  $('play').textContent = on ? 'Pause' : 'Play';
  if (on) {
    if (state.frame >= state.poses.poses.length - 1) showFrame(0);
    playClock = performance.now() / 1000 - state.plan.trajectory[state.frame].t;
  }
}

function tick() {
  if (state.playing && state.plan) {
    const t = performance.now() / 1000 - playClock;
    const traj = state.plan.trajectory;
    let k = state.frame;
    while (k < traj.length - 1 && traj[k + 1].t <= t) k++;
    if (k !== state.frame) showFrame(k);
    if (k >= traj.length - 1) play(false);
  }
  controls.update();
  renderer.render(scene, camera);
  requestAnimationFrame(tick);
}

// ---------------------------------------------------------------- picking

const pointer = { x: 0, y: 0, moved: false };
renderer.domElement.addEventListener('pointerdown', (e) => {
  pointer.x = e.clientX;
  pointer.y = e.clientY;
});
renderer.domElement.addEventListener('pointerup', (e) => {
  if (Math.hypot(e.clientX - pointer.x, e.clientY - pointer.y) > 4 || !state.treeMesh) return;
  const rect = renderer.domElement.getBoundingClientRect();
  const ndc = new THREE.Vector2(((e.clientX - rect.left) / rect.width) * 2 - 1, -((e.clientY - rect.top) / rect.height) * 2 + 1);
  const ray = new THREE.Raycaster();
  ray.setFromCamera(ndc, camera);
  const hit = ray.intersectObjects(state.treeMesh.nodes).find((h) => h.object.userData.node > 0);
  if (hit) selectNode(hit.object.userData.node);
});

// ---------------------------------------------------------------- wiring

$('example-load').addEventListener('click', () => action(loadExample));
$('json-load').addEventListener('click', () => action(loadJson));
$('urdf-file').addEventListener('change', (e) => {
  const file = e.target.files[0];
  if (file) action(() => loadUrdf(file));
});
$('ply-file').addEventListener('change', (e) => {
  const file = e.target.files[0];
  if (file) action(() => loadCloud(file));
});
$('push-node').addEventListener('change', (e) => selectNode(Number(e.target.value)));
$('predict').addEventListener('click', () => action(predict));
$('target-from-push').addEventListener('click', () => action(targetFromPush));
$('target-load').addEventListener('click', () => action(async () => loadTarget()));
$('policy').addEventListener('click', () => action(policy));
$('plan').addEventListener('click', () => action(plan));
$('play').addEventListener('click', () => play(!state.playing));
$('scrub').addEventListener('input', (e) => {
  play(false);
  showFrame(Number(e.target.value));
});

/** The canvas as rendered now: RGBA bytes. */
function readPixels() {
  renderer.render(scene, camera);
  const gl = renderer.getContext();
  const w = gl.drawingBufferWidth;
  const h = gl.drawingBufferHeight;
  const pixels = new Uint8Array(w * h * 4);
  gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, pixels);
  return pixels;
}

/** Pixels whose colour is within `tolerance` (sum of |Δ| over RGB) of `hex`, or beyond it. */
function countPixels(hex, tolerance, near) {
  const rgb = [(hex >> 16) & 255, (hex >> 8) & 255, hex & 255];
  const pixels = readPixels();
  let count = 0;
  for (let i = 0; i < pixels.length; i += 4) {
    const d = Math.abs(pixels[i] - rgb[0]) + Math.abs(pixels[i + 1] - rgb[1]) + Math.abs(pixels[i + 2] - rgb[2]);
    if ((d < tolerance) === near) count++;
  }
  return { count, total: pixels.length / 4 };
}

/** For tests and scripts: what is drawn, and how much of the canvas shows it. */
window.treemanipViewer = {
  state,
  layers: () => Object.fromEntries(Object.entries(layers).map(([k, v]) => [k, v ? (v.userData.links ?? v.children.length) : 0])),
  nonBackgroundPixels: () => countPixels(COLOURS.background, 24, false),
  pixelsNear: (hex, tolerance = 60) => countPixels(hex, tolerance, true).count,
  colours: COLOURS,
  showFrame,
  play,
};

/** The arms the server plans for (GET /v1/robots), default first. */
async function loadRobots() {
  const select = $('plan-robot');
  const { robots } = await api('/v1/robots');
  robots.sort((a, b) => Number(b.default) - Number(a.default));
  for (const r of robots) {
    const option = document.createElement('option');
    option.value = r.name;
    option.textContent = `${r.name} (${r.dof} joints)`;
    select.append(option);
  }
}

loadRobots().then(() => {
  document.body.dataset.ready = '1';
}, (e) => {
  document.body.dataset.ready = '1';
  $('plan-status').textContent = e.message;
});
requestAnimationFrame(tick);
