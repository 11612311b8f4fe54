// The chronomap 4D viewer: voxels of a 4D map in 3D, a time slider over its sessions, the
// objects that changed between two times, and a voxel's history. docs/viewer.md describes it.

import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { ServerSource, TourSource } from './data.js';
import { viridis, heat, gradientCss, APPEARED, VANISHED, css } from './colors.js';

const $ = (id) => document.getElementById(id);
const state = {
  info: null, source: null, snap: null, rank: 0, budget: 0, colorMode: 'color', cut: 1, diff: null,
  playing: false, visible: [], drawn: 0, errors: [], ready: false, lastLoadMs: 0, selected: null,
};
// For tests and for people at the console: what the page shows.
window.chronomap = state;

// ---------------------------------------------------------------------------------------------
// The scene

// A software renderer (SwiftShader, llvmpipe: headless browsers, machines without a GPU) spends
// most of a frame on multisampling and extra pixels; it draws without them.
function softwareRenderer() {
  try {
    const gl = document.createElement('canvas').getContext('webgl2') || document.createElement('canvas').getContext('webgl');
    const ext = gl && gl.getExtension('WEBGL_debug_renderer_info');
    const name = ext ? gl.getParameter(ext.UNMASKED_RENDERER_WEBGL) : '';
    return /swiftshader|llvmpipe|softpipe|software/i.test(name);
  } catch (e) {
    return false;
  }
}
const software = softwareRenderer();
const renderer = new THREE.WebGLRenderer({ antialias: !software, preserveDrawingBuffer: true });
renderer.setPixelRatio(software ? 1 : Math.min(window.devicePixelRatio, 2));
renderer.setClearColor(0x14171c);
$('scene').appendChild(renderer.domElement);
const scene = new THREE.Scene();
const camera = new THREE.PerspectiveCamera(45, 1, 0.05, 5000);
camera.up.set(0, 0, 1);  // the map's z is up
const controls = new OrbitControls(camera, renderer.domElement);
controls.enableDamping = true;
controls.dampingFactor = 0.12;
controls.screenSpacePanning = true;
controls.addEventListener('change', () => redraw());
controls.addEventListener('end', () => scheduleRefine());
scene.add(new THREE.HemisphereLight(0xffffff, 0x445066, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
sun.position.set(-0.5, -0.8, 1.6);
scene.add(sun);

const box = new THREE.BoxGeometry(1, 1, 1);
const voxelMaterial = new THREE.MeshLambertMaterial({ transparent: true, opacity: 1, vertexColors: true });
let voxels = null;  // Mesh of the snapshot's visible faces (surfaceMesh)
let changed = null;  // InstancedMesh of the diff's cells
const frames = new THREE.Group();  // boxes around the objects
scene.add(frames);
let marker = null;  // the selected cell
let grid = null;

function instanced(capacity, material) {
  const m = new THREE.InstancedMesh(box, material, Math.max(1, capacity));
  m.instanceMatrix.setUsage(THREE.DynamicDrawUsage);
  m.instanceColor = new THREE.InstancedBufferAttribute(new Float32Array(3 * Math.max(1, capacity)), 3);
  m.frustumCulled = false;
  return m;
}

function resize() {
  const w = window.innerWidth, h = window.innerHeight;
  renderer.setSize(w, h);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', () => { resize(); redraw(); });
resize();

// Metric centre and edge of a cell.
function cellCenter(keys, levels, i, out) {
  const r = state.info.resolution_m, o = state.info.key_origin, size = 1 << levels[i];
  out.set((keys[3 * i] - o + size / 2) * r, (keys[3 * i + 1] - o + size / 2) * r, (keys[3 * i + 2] - o + size / 2) * r);
  return size * r;
}

// ---------------------------------------------------------------------------------------------
// Colours

const srgb = new THREE.Color();
function colorOf(snap, i) {
  switch (state.colorMode) {
    case 'height': {
      const z = (snap.keys[3 * i + 2] - state.bounds.zmin) / Math.max(1, state.bounds.zmax - state.bounds.zmin);
      return viridis(z);
    }
    case 'changes': return snap.changes[i] === 0 ? [120, 128, 140] : heat(snap.changes[i] / Math.max(1, state.maxChanges));
    case 'age': {
      const age = snap.rank - snap.since[i];
      return age === 0 && snap.rank > 0 ? [255, 140, 40] : viridis(1 - age / Math.max(1, snap.rank));
    }
    default: return [snap.colors[3 * i], snap.colors[3 * i + 1], snap.colors[3 * i + 2]];
  }
}

// ---------------------------------------------------------------------------------------------
// Drawing a snapshot

const tmp = new THREE.Vector3(), mat = new THREE.Matrix4(), quat = new THREE.Quaternion(), scl = new THREE.Vector3();

function computeBounds(snap) {
  if (state.bounds || snap.count === 0) return;
  const b = { xmin: Infinity, ymin: Infinity, zmin: Infinity, xmax: -Infinity, ymax: -Infinity, zmax: -Infinity };
  for (let i = 0; i < snap.count; ++i) {
    const s = 1 << snap.levels[i];
    b.xmin = Math.min(b.xmin, snap.keys[3 * i]); b.xmax = Math.max(b.xmax, snap.keys[3 * i] + s);
    b.ymin = Math.min(b.ymin, snap.keys[3 * i + 1]); b.ymax = Math.max(b.ymax, snap.keys[3 * i + 1] + s);
    b.zmin = Math.min(b.zmin, snap.keys[3 * i + 2]); b.zmax = Math.max(b.zmax, snap.keys[3 * i + 2] + s);
  }
  state.bounds = b;
  const r = state.info.resolution_m, o = state.info.key_origin;
  state.center = new THREE.Vector3(((b.xmin + b.xmax) / 2 - o) * r, ((b.ymin + b.ymax) / 2 - o) * r, ((b.zmin + b.zmax) / 2 - o) * r);
  state.extent = Math.max(b.xmax - b.xmin, b.ymax - b.ymin, b.zmax - b.zmin) * r;
  addGrid();
  resetCamera();
}

function addGrid() {
  const r = state.info.resolution_m, o = state.info.key_origin, b = state.bounds;
  const size = Math.ceil(state.extent * 1.3);
  grid = new THREE.GridHelper(size, size, 0x3b4252, 0x262b34);
  grid.rotation.x = Math.PI / 2;
  grid.position.set(state.center.x, state.center.y, (b.zmin - o) * r - 0.01);
  scene.add(grid);
}

function resetCamera() {
  const c = state.center, e = state.extent;
  controls.target.copy(c);
  camera.position.set(c.x - 0.55 * e, c.y - 0.85 * e, c.z + 0.75 * e);
  camera.near = e / 500; camera.far = e * 20;
  camera.updateProjectionMatrix();
  state.topView = false;
  $('topview').classList.remove('on');
  controls.update();
}

function cutHeightKey() {
  const b = state.bounds;
  return b ? b.zmin + state.cut * (b.zmax - b.zmin) : Infinity;
}

// The six faces of a unit cube: outward normal and corners, counter-clockwise seen from outside.
const FACES = [
  { n: [1, 0, 0], c: [[1, 0, 0], [1, 1, 0], [1, 1, 1], [1, 0, 1]] },
  { n: [-1, 0, 0], c: [[0, 0, 0], [0, 0, 1], [0, 1, 1], [0, 1, 0]] },
  { n: [0, 1, 0], c: [[0, 1, 0], [0, 1, 1], [1, 1, 1], [1, 1, 0]] },
  { n: [0, -1, 0], c: [[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]] },
  { n: [0, 0, 1], c: [[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]] },
  { n: [0, 0, -1], c: [[0, 0, 0], [0, 1, 0], [1, 1, 0], [1, 0, 0]] },
];

// has(x, y, z, level): whether a drawn cell of that level has its corner at the key. One byte
// per cell of a grid over the cells' bounds for each level (a hash set of numbers is several
// times slower), or a set when such a grid would be too large.
function occupancy(snap, drawn) {
  const grids = new Map();
  for (const i of drawn) {
    const l = snap.levels[i];
    let g = grids.get(l);
    if (!g) grids.set(l, g = { lo: [Infinity, Infinity, Infinity], hi: [-Infinity, -Infinity, -Infinity] });
    for (let a = 0; a < 3; ++a) {
      const v = snap.keys[3 * i + a] >> l;
      if (v < g.lo[a]) g.lo[a] = v;
      if (v > g.hi[a]) g.hi[a] = v;
    }
  }
  for (const g of grids.values()) {
    g.n = g.lo.map((v, a) => g.hi[a] - v + 1);
    g.cells = g.n[0] * g.n[1] * g.n[2] <= 64e6 ? new Uint8Array(g.n[0] * g.n[1] * g.n[2]) : new Set();
  }
  const at = (g, x, y, z) => x - g.lo[0] + g.n[0] * (y - g.lo[1] + g.n[1] * (z - g.lo[2]));
  for (const i of drawn) {
    const l = snap.levels[i], g = grids.get(l);
    const j = at(g, snap.keys[3 * i] >> l, snap.keys[3 * i + 1] >> l, snap.keys[3 * i + 2] >> l);
    if (g.cells instanceof Set) g.cells.add(j); else g.cells[j] = 1;
  }
  return (x, y, z, l) => {
    const g = grids.get(l);
    x >>= l; y >>= l; z >>= l;
    if (x < g.lo[0] || y < g.lo[1] || z < g.lo[2] || x > g.hi[0] || y > g.hi[1] || z > g.hi[2]) return false;
    const j = at(g, x, y, z);
    return g.cells instanceof Set ? g.cells.has(j) : g.cells[j] === 1;
  };
}

// The drawn cells as one mesh of the faces between a cell and no drawn cell of its level: the
// faces inside walls and floors are never seen, and leaving them out keeps a frame cheap where
// the browser draws in software. Each voxel's colour varies by a few percent, so that the voxels
// of a flat wall stay visible. Returns the mesh; mesh.userData.cellOfFace maps faces to cells.
function surfaceMesh(snap, drawn) {
  const has = occupancy(snap, drawn);
  const faces = new Uint32Array(6 * drawn.length);  // cell (position in drawn) * 8 + face
  let count = 0;
  for (let k = 0; k < drawn.length; ++k) {
    const i = drawn[k], l = snap.levels[i], s = 1 << l;
    const x = snap.keys[3 * i], y = snap.keys[3 * i + 1], z = snap.keys[3 * i + 2];
    for (let f = 0; f < 6; ++f) {
      const n = FACES[f].n;
      if (!has(x + n[0] * s, y + n[1] * s, z + n[2] * s, l)) faces[count++] = k * 8 + f;
    }
  }
  const position = new Float32Array(12 * count), normal = new Float32Array(12 * count), color = new Float32Array(12 * count);
  const index = new Uint32Array(6 * count), cellOfFace = new Uint32Array(count);
  const r = state.info.resolution_m, o = state.info.key_origin;
  let lastCell = -1, cr = 0, cg = 0, cb = 0;
  for (let q = 0; q < count; ++q) {
    const k = faces[q] >>> 3, f = FACES[faces[q] & 7], i = drawn[k], s = 1 << snap.levels[i];
    const x = snap.keys[3 * i], y = snap.keys[3 * i + 1], z = snap.keys[3 * i + 2];
    if (k !== lastCell) {  // a cell's faces are consecutive: its colour once
      const c = colorOf(snap, i);
      const jitter = 0.94 + 0.06 * (((x * 73856093) ^ (y * 19349663) ^ (z * 83492791)) & 255) / 255;
      srgb.setRGB((c[0] / 255) * jitter, (c[1] / 255) * jitter, (c[2] / 255) * jitter, THREE.SRGBColorSpace);
      cr = srgb.r; cg = srgb.g; cb = srgb.b;
      lastCell = k;
    }
    for (let v = 0; v < 4; ++v) {
      const at = 12 * q + 3 * v, corner = f.c[v];
      position[at] = (x - o + corner[0] * s) * r;
      position[at + 1] = (y - o + corner[1] * s) * r;
      position[at + 2] = (z - o + corner[2] * s) * r;
      normal[at] = f.n[0]; normal[at + 1] = f.n[1]; normal[at + 2] = f.n[2];
      color[at] = cr; color[at + 1] = cg; color[at + 2] = cb;
    }
    const base = 4 * q, at = 6 * q;
    index[at] = base; index[at + 1] = base + 1; index[at + 2] = base + 2;
    index[at + 3] = base; index[at + 4] = base + 2; index[at + 5] = base + 3;
    cellOfFace[q] = k;
  }
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.BufferAttribute(position, 3));
  g.setAttribute('normal', new THREE.BufferAttribute(normal, 3));
  g.setAttribute('color', new THREE.BufferAttribute(color, 3));
  g.setIndex(new THREE.BufferAttribute(index, 1));
  g.computeBoundingSphere();
  const mesh = new THREE.Mesh(g, voxelMaterial);
  mesh.userData.cellOfFace = cellOfFace;
  return mesh;
}

function withDetail(snap, detail) {
  if (!detail || detail.rank !== snap.rank) return snap;
  const [x0, y0, , x1, y1] = detail.region;
  const keep = [];
  for (let i = 0; i < snap.count; ++i) {
    const x = snap.keys[3 * i], y = snap.keys[3 * i + 1];
    if (x < x0 || x > x1 || y < y0 || y > y1) keep.push(i);
  }
  const n = keep.length + detail.snap.count;
  const out = { ...snap, count: n, keys: new Uint16Array(3 * n), levels: new Uint8Array(n), colors: new Uint8Array(3 * n),
                changes: new Uint8Array(n), since: new Uint16Array(n), detailCells: detail.snap.count, detailLevel: detail.snap.level };
  keep.forEach((i, k) => {
    out.keys.set(snap.keys.subarray(3 * i, 3 * i + 3), 3 * k);
    out.colors.set(snap.colors.subarray(3 * i, 3 * i + 3), 3 * k);
    out.levels[k] = snap.levels[i]; out.changes[k] = snap.changes[i]; out.since[k] = snap.since[i];
  });
  const d = detail.snap, at = keep.length;
  out.keys.set(d.keys, 3 * at); out.colors.set(d.colors, 3 * at);
  out.levels.set(d.levels, at); out.changes.set(d.changes, at); out.since.set(d.since, at);
  return out;
}

function drawSnapshot() {
  if (!state.snap) return;
  const snap = withDetail(state.snap, state.detail);
  state.shown = snap;
  computeBounds(snap);
  state.maxChanges = 1;
  for (let i = 0; i < snap.count; ++i) state.maxChanges = Math.max(state.maxChanges, snap.changes[i]);
  const cut = cutHeightKey();
  state.visible = [];
  for (let i = 0; i < snap.count; ++i) if (snap.keys[3 * i + 2] < cut) state.visible.push(i);
  if (voxels) { scene.remove(voxels); voxels.geometry.dispose(); }
  voxels = surfaceMesh(snap, state.visible);
  scene.add(voxels);
  state.drawn = state.visible.length;
  state.faces = voxels.userData.cellOfFace.length;
  voxelMaterial.opacity = state.diff ? 0.28 : 1;
  voxelMaterial.depthWrite = !state.diff;
  redraw();
  updateStats();
  updateLegend();
}

// ---------------------------------------------------------------------------------------------
// Time

function sessionLabel(rank) {
  const s = state.info.sessions[rank];
  return `${s.time.replace('T', ' ').replace('Z', ' UTC')}  ·  session ${rank + 1} of ${state.info.sessions.length}`;
}

async function setSession(rank) {
  state.rank = rank;
  $('time').value = rank;
  $('timelabel').textContent = sessionLabel(rank);
  const t0 = performance.now();
  const snap = await state.source.snapshot(rank, state.budget);
  if (state.rank !== rank) return;  // a later move of the slider won
  state.snap = snap;
  state.lastLoadMs = performance.now() - t0;
  drawSnapshot();
  state.loadedRank = rank;
  scheduleRefine();
}

// ---------------------------------------------------------------------------------------------
// Finer cells where the camera looks: when the whole map comes in coarse cubes, the server is
// asked for the cells around the orbit target, with the same budget, after each camera move.

let refineTimer = null;
function scheduleRefine() {
  clearTimeout(refineTimer);
  refineTimer = setTimeout(() => refine().catch(report), 250);
}

async function refine() {
  const snap = state.snap;
  if (!state.source.refines || !snap || snap.level === 0) { state.detail = null; return; }
  const r = state.info.resolution_m, o = state.info.key_origin, b = state.bounds;
  const radius = 0.7 * camera.position.distanceTo(controls.target);
  if (2 * radius >= 0.8 * state.extent) {
    if (state.detail) { state.detail = null; drawSnapshot(); }
    return;
  }
  // Whole coarse cells, so that each is either replaced or kept.
  const cell = 1 << snap.level;
  const lo = (v) => Math.max(0, Math.floor((v / r + o) / cell) * cell);
  const hi = (v) => Math.min(65535, Math.ceil((v / r + o) / cell) * cell - 1);
  const t = controls.target;
  const region = [lo(t.x - radius), lo(t.y - radius), b.zmin, hi(t.x + radius), hi(t.y + radius), Math.min(65535, b.zmax)];
  if (state.detail && state.detail.rank === snap.rank && state.detail.region.join() === region.join()) return;
  const rank = snap.rank;
  const fine = await state.source.snapshot(rank, state.budget, region);
  if (state.snap.rank !== rank || fine.level >= snap.level) return;
  state.detail = { rank, region, snap: fine };
  drawSnapshot();
}
state.refine = () => refine();
state.focusOn = (c) => focusOn(c);

let playTimer = null;
function setPlaying(on) {
  state.playing = on;
  $('play').textContent = on ? '❚❚' : '▶';
  clearTimeout(playTimer);
  if (!on) return;
  const step = async () => {
    if (!state.playing) return;
    await setSession((state.rank + 1) % state.info.sessions.length).catch(report);
    playTimer = setTimeout(step, 900);
  };
  step();
}

// ---------------------------------------------------------------------------------------------
// What changed

function clearDiff() {
  state.diff = null;
  if (changed) { scene.remove(changed); changed.dispose(); changed = null; }
  frames.clear();
  $('tags').innerHTML = '';
  redraw();
  $('objects').innerHTML = '';
  $('diffsum').textContent = '';
  $('showdiff').classList.remove('on');
}

async function showDiff(from, to) {
  clearDiff();
  const d = await state.source.diff(from, to);
  state.diff = d;
  $('showdiff').classList.add('on');
  const n = d.keys.length / 3;
  changed = instanced(n, new THREE.MeshLambertMaterial());
  const colors = changed.instanceColor.array;
  for (let i = 0; i < n; ++i) {
    const size = cellCenter(d.keys, d.levels, i, tmp) * 0.98;
    mat.compose(tmp, quat, scl.set(size, size, size));
    changed.setMatrixAt(i, mat);
    srgb.setRGB(...(d.kinds[i] === 1 ? APPEARED : VANISHED).map((v) => v / 255), THREE.SRGBColorSpace);
    colors.set([srgb.r, srgb.g, srgb.b], 3 * i);
  }
  changed.count = n;
  scene.add(changed);
  for (const c of d.components) {
    const b = new THREE.Box3(new THREE.Vector3(...c.bbox_min_m), new THREE.Vector3(...c.bbox_max_m));
    const pad = state.info.resolution_m;
    b.expandByScalar(pad);
    const helper = new THREE.Box3Helper(b, new THREE.Color(css(c.kind === 'appeared' ? APPEARED : VANISHED)));
    helper.userData = c;
    frames.add(helper);
    const tag = document.createElement('div');
    tag.className = `tag ${c.kind}`;
    tag.textContent = c.id;
    $('tags').appendChild(tag);
    helper.userData.tag = tag;
    helper.userData.top = new THREE.Vector3((b.min.x + b.max.x) / 2, (b.min.y + b.max.y) / 2, b.max.z);
  }
  listObjects(d);
  drawSnapshot();
  redraw();
  return d;
}

function listObjects(d) {
  const fmtVol = (v) => (v >= 0.1 ? `${v.toFixed(2)} m³` : `${(v * 1000).toFixed(1)} L`);
  $('diffsum').textContent = `${d.components.length} object${d.components.length === 1 ? '' : 's'}, ${d.voxels} voxels` +
    (d.cells_sent < d.cells ? ` (${d.cells_sent} of ${d.cells} cells drawn)` : '');
  const list = $('objects');
  for (const c of d.components) {
    const row = document.createElement('div');
    row.className = 'obj';
    const sz = c.bbox_max_m.map((v, k) => (v - c.bbox_min_m[k]).toFixed(2)).join(' × ');
    row.innerHTML = `<span class="num ${c.kind}">${c.id}</span>` +
      `<span>${c.kind} <span class="dim">${sz} m</span></span><span class="dim">${c.voxels} vox · ${fmtVol(c.volume_m3)}</span>`;
    row.title = `centre ${c.centroid_m.map((v) => v.toFixed(2)).join(', ')} m`;
    row.addEventListener('click', () => focusOn(c));
    list.appendChild(row);
  }
  if (!d.components.length) list.innerHTML = '<div class="dim">nothing changed between these times</div>';
}

function focusOn(c) {
  const center = new THREE.Vector3(...c.centroid_m);
  const size = Math.max(...c.bbox_max_m.map((v, k) => v - c.bbox_min_m[k]), 0.5);
  const dir = camera.position.clone().sub(controls.target).normalize();
  controls.target.copy(center);
  camera.position.copy(center).addScaledVector(dir, size * 4 + 1);
  controls.update();
}

function placeTags() {
  const w = window.innerWidth, h = window.innerHeight;
  for (const f of frames.children) {
    const p = f.userData.top.clone().project(camera);
    const tag = f.userData.tag;
    const visible = p.z < 1 && Math.abs(p.x) < 1.05 && Math.abs(p.y) < 1.05;
    tag.style.display = visible ? '' : 'none';
    tag.style.left = `${((p.x + 1) / 2) * w}px`;
    tag.style.top = `${((1 - p.y) / 2) * h - 4}px`;
  }
}

// ---------------------------------------------------------------------------------------------
// History of a voxel

const raycaster = new THREE.Raycaster();
async function pick(event) {
  if (!voxels || !state.shown) return;
  const rect = renderer.domElement.getBoundingClientRect();
  const ndc = new THREE.Vector2(((event.clientX - rect.left) / rect.width) * 2 - 1, -((event.clientY - rect.top) / rect.height) * 2 + 1);
  raycaster.setFromCamera(ndc, camera);
  const hit = raycaster.intersectObject(voxels, false)[0];
  if (!hit) return;
  await selectCell(state.visible[voxels.userData.cellOfFace[hit.faceIndex >> 1]]);
}

async function selectCell(i) {
  const s = state.shown;
  const key = [s.keys[3 * i], s.keys[3 * i + 1], s.keys[3 * i + 2]];
  const level = s.levels[i];
  state.selected = { key, level };
  if (marker) scene.remove(marker);
  const size = cellCenter(s.keys, s.levels, i, tmp);
  marker = new THREE.Box3Helper(new THREE.Box3().setFromCenterAndSize(tmp, new THREE.Vector3(size, size, size).multiplyScalar(1.25)),
                                new THREE.Color(0xffffff));
  scene.add(marker);
  redraw();
  const h = await state.source.history(key, Math.min(level, state.info.max_history_level ?? level));
  state.history = h;
  showHistory(h, level);
  return h;
}

function showHistory(h, level) {
  $('history').style.display = 'block';
  const c = h.center_m ? ` at ${h.center_m.map((v) => v.toFixed(2)).join(', ')} m` : '';
  $('histtitle').textContent = `History of voxel ${h.key.join(', ')}`;
  $('histsub').textContent = (level > 0 ? `busiest voxel of a ${1 << level}³ cell${c}` : `voxel${c}`) +
    ` · ${h.entries.length} stored state${h.entries.length === 1 ? '' : 's'}`;
  // The timeline: one segment per session in the state valid then.
  const cv = $('histcanvas'), g = cv.getContext('2d'), n = state.info.sessions.length;
  g.clearRect(0, 0, cv.width, cv.height);
  let e = -1;
  for (let s = 0; s < n; ++s) {
    while (e + 1 < h.entries.length && h.entries[e + 1].session <= s) ++e;
    const entry = e >= 0 ? h.entries[e] : null;
    g.fillStyle = !entry ? '#2a2f3a' : entry.state === 'occupied' ? css(entry.color) : '#c8ced8';
    const x0 = Math.round((s / n) * cv.width), x1 = Math.round(((s + 1) / n) * cv.width);
    g.fillRect(x0 + 1, 8, x1 - x0 - 2, 40);
    if (entry && entry.session === s) { g.fillStyle = '#5fb3ff'; g.fillRect(x0 + 1, 50, x1 - x0 - 2, 6); }
    if (s === state.rank) { g.strokeStyle = '#ffffff'; g.lineWidth = 3; g.strokeRect(x0 + 1, 5, x1 - x0 - 2, 46); }
  }
  const rows = h.entries.map((x) => `<tr><td>${x.time.replace('T', ' ')}</td><td>${x.state}</td>` +
    `<td>${x.probability !== undefined ? `P ${x.probability.toFixed(2)}` : ''}</td>` +
    `<td><span class="sw" style="display:inline-block;width:10px;height:10px;background:${x.state === 'occupied' ? css(x.color) : '#c8ced8'}"></span></td></tr>`);
  $('histtable').innerHTML = rows.join('') || '<tr><td class="dim">never observed</td></tr>';
}

// ---------------------------------------------------------------------------------------------
// Panels

function updateStats() {
  const s = state.snap, shown = state.shown;
  const lines = [`${s.count.toLocaleString()} cells` + (s.level > 0 ? ` of ${1 << s.level}³ voxels (level ${s.level})` : ' (unit voxels)'),
    `${s.occupiedVoxels.toLocaleString()} occupied voxels`, `${state.drawn.toLocaleString()} drawn below the cut`];
  if (shown && shown.detailCells) {
    lines.splice(1, 0, `in view: ${shown.detailCells.toLocaleString()} cells` +
      (shown.detailLevel > 0 ? ` of ${1 << shown.detailLevel}³ voxels` : ' (unit voxels)'));
  }
  if (s.bytes) lines.push(`${(s.bytes / 1e6).toFixed(2)} MB, ${state.lastLoadMs.toFixed(0)} ms`);
  $('stats').textContent = lines.join('\n');
}

function updateLegend() {
  const L = $('legend');
  const mode = state.colorMode;
  let html = '';
  if (mode === 'color') html = '<div>each voxel in the mean colour of the rays that ended in it</div>';
  if (mode === 'height') {
    const r = state.info.resolution_m, o = state.info.key_origin, b = state.bounds;
    html = `<div>height</div><div class="ramp" style="background:${gradientCss(viridis)}"></div>` +
      `<div class="ends"><span>${((b.zmin - o) * r).toFixed(1)} m</span><span>${((b.zmax - o) * r).toFixed(1)} m</span></div>`;
  }
  if (mode === 'changes') {
    html = `<div>stored state changes up to this session</div><div class="ramp" style="background:${gradientCss(heat)}"></div>` +
      `<div class="ends"><span>1</span><span>${state.maxChanges}</span></div><div class="key"><span class="sw" style="background:rgb(120,128,140)"></span>never changed</div>`;
  }
  if (mode === 'age') {
    html = `<div>sessions since the voxel took its state</div><div class="ramp" style="background:${gradientCss((t) => viridis(1 - t))}"></div>` +
      `<div class="ends"><span>1</span><span>${state.rank}</span></div><div class="key"><span class="sw" style="background:rgb(255,140,40)"></span>set by this session</div>`;
  }
  if (state.diff) {
    html += `<div class="key"><span class="sw appeared"></span>appeared (numbered, framed)</div>` +
      `<div class="key"><span class="sw vanished"></span>vanished</div>`;
  }
  html += '<div class="dim" style="margin-top:6px">drag: orbit · right drag: pan · wheel: zoom · click: history</div>';
  L.innerHTML = html;
}

function fillSessionSelects() {
  for (const id of ['from', 'to']) {
    const sel = $(id);
    sel.innerHTML = state.info.sessions.map((s, i) => `<option value="${i}">${i + 1}: ${s.time.replace('T', ' ')}</option>`).join('');
  }
  $('from').value = 0;
  $('to').value = Math.min(1, state.info.sessions.length - 1);
}

function report(e) {
  console.error(e);
  state.errors.push(String(e.message || e));
  $('busy').style.display = 'block';
  $('busy').textContent = String(e.message || e);
}

function wire() {
  $('time').addEventListener('input', () => setSession(Number($('time').value)).catch(report));
  $('play').addEventListener('click', () => setPlaying(!state.playing));
  $('colormode').addEventListener('change', () => { state.colorMode = $('colormode').value; drawSnapshot(); });
  $('cut').addEventListener('input', () => {
    state.cut = Number($('cut').value) / 1000;
    const r = state.info.resolution_m, o = state.info.key_origin;
    $('cutlabel').textContent = state.cut >= 1 ? 'none' : `${((cutHeightKey() - o) * r).toFixed(2)} m`;
    drawSnapshot();
  });
  $('topview').addEventListener('click', () => {
    if (state.topView) { resetCamera(); return; }
    const c = state.center;
    controls.target.copy(c);
    camera.position.set(c.x, c.y - 0.001, c.z + state.extent * 1.25);
    controls.update();
    state.topView = true;
    $('topview').classList.add('on');
  });
  $('reset').addEventListener('click', resetCamera);
  $('showdiff').addEventListener('click', () => {
    if (state.diff) { clearDiff(); drawSnapshot(); return; }
    showDiff(Number($('from').value), Number($('to').value)).catch(report);
  });
  let down = null;
  renderer.domElement.addEventListener('pointerdown', (e) => { down = [e.clientX, e.clientY]; });
  renderer.domElement.addEventListener('pointerup', (e) => {
    if (down && Math.hypot(e.clientX - down[0], e.clientY - down[1]) < 4) pick(e).catch(report);
  });
}

// Frames are drawn only when something moved or changed, so an idle page costs nothing.
let dirty = true;
function redraw() { dirty = true; }
function animate() {
  requestAnimationFrame(animate);
  if (!controls.update() && !dirty) return;
  dirty = false;
  placeTags();
  renderer.render(scene, camera);
  state.frames = (state.frames || 0) + 1;
}
/** Resolves once a frame showing the current state has been drawn. */
function nextFrame() {
  redraw();
  const seen = state.frames || 0;
  return new Promise((resolve) => {
    const wait = () => ((state.frames || 0) > seen ? resolve() : requestAnimationFrame(wait));
    requestAnimationFrame(wait);
  });
}

async function main() {
  const embedded = document.getElementById('chronomap-data');
  state.source = embedded ? new TourSource(embedded) : new ServerSource();
  state.info = await state.source.info();
  state.budget = state.info.default_max_voxels;
  $('mapname').textContent = `${state.info.name} · ${state.info.sessions.length} sessions · ${state.info.resolution_m * 100} cm voxels` +
    (state.source.kind === 'tour' ? ' · tour file' : '');
  $('time').max = state.info.sessions.length - 1;
  fillSessionSelects();
  wire();
  animate();
  const last = state.info.sessions.length - 1;
  await setSession(last);
  $('busy').style.display = 'none';
  state.ready = true;
}

// Test hooks: the same calls the controls make.
state.setSession = (rank) => setSession(rank);
state.nextFrame = () => nextFrame();
state.showDiff = (from, to) => showDiff(from, to);
state.clearDiff = () => { clearDiff(); drawSnapshot(); };
state.selectCell = (i) => selectCell(i);
state.setColorMode = (m) => { state.colorMode = m; $('colormode').value = m; drawSnapshot(); };
state.toggleTopView = () => $('topview').click();
/** Cuts at `metres` above the map's origin (the slider's value nearest to it). */
state.setCut = (metres) => {
  const r = state.info.resolution_m, o = state.info.key_origin, b = state.bounds;
  const f = ((metres / r + o) - b.zmin) / Math.max(1, b.zmax - b.zmin);
  $('cut').value = Math.round(Math.min(1, Math.max(0, f)) * 1000);
  $('cut').dispatchEvent(new Event('input'));
};

main().catch(report);
