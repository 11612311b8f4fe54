// The chronomap 4D viewer: voxels of a 4D map in 3D, a time slider over its sessions, the
// objects that changed between two times, and a voxel's history. docs/viewer.md describes it.

import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { ServerSource, TourSource, whenId } from './data.js';
import { viridis, heat, gradientCss, APPEARED, VANISHED, MOVED, MOVED_FROM, css } from './colors.js';

const $ = (id) => document.getElementById(id);
const state = {
  info: null, source: null, snap: null, rank: 0, budget: 0, colorMode: 'color', cut: 1, diff: null,
  playing: false, cullFaces: true, visible: [], drawn: 0, errors: [], ready: false, lastLoadMs: 0, selected: null,
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
const NO_MODEL = [120, 128, 140];

// Per drawn cell of `snap`, the predicted probability of occupancy (the most probable modelled
// cube inside it, or the modelled cube it lies in), NaN where no cube is modelled (it never
// changed: it stays as observed).
function cellPredictions(snap, pred) {
  const out = new Float32Array(snap.count).fill(NaN);
  const cellKey = (x, y, z, l) => (x >> l) + 65536 * ((y >> l) + 65536 * (z >> l));
  const byLevel = new Map();  // level of the snapshot's cells -> Map(key -> cell)
  for (let i = 0; i < snap.count; ++i) {
    const l = snap.levels[i];
    if (!byLevel.has(l)) byLevel.set(l, new Map());
    byLevel.get(l).set(cellKey(snap.keys[3 * i], snap.keys[3 * i + 1], snap.keys[3 * i + 2], l), i);
  }
  const coarse = new Map();  // cubes larger than some cells: level -> Map(key -> p)
  for (let c = 0; c < pred.levels.length; ++c) {
    const x = pred.keys[3 * c], y = pred.keys[3 * c + 1], z = pred.keys[3 * c + 2], lc = pred.levels[c], p = pred.p[c];
    for (const [l, cells] of byLevel) {
      if (lc > l) {
        if (!coarse.has(lc)) coarse.set(lc, new Map());
        coarse.get(lc).set(cellKey(x, y, z, lc), p);
        continue;
      }
      const i = cells.get(cellKey(x, y, z, l));
      if (i !== undefined && !(out[i] >= p)) out[i] = p;
    }
  }
  for (const [lc, cubes] of coarse) {
    for (let i = 0; i < snap.count; ++i) {
      if (snap.levels[i] >= lc) continue;
      const p = cubes.get(cellKey(snap.keys[3 * i], snap.keys[3 * i + 1], snap.keys[3 * i + 2], lc));
      if (p !== undefined && !(out[i] >= p)) out[i] = p;
    }
  }
  return out;
}

// The time the prediction layer and the cost map are for: the date and hour field's when one was
// chosen (up to a week past the last session), else the slider's session.
function predictionTime(rank) {
  return state.predictAt ? { time: state.predictAt } : { rank };
}
async function loadPrediction(rank) {
  if (state.colorMode !== 'predicted' || !state.source.predicts) return;
  const t0 = performance.now(), at = predictionTime(rank);
  let pred = null;
  try {
    pred = await state.source.prediction(at);
  } catch (e) {
    // A time the server refuses (more than a week past the last session) is said beside the field.
    $('predictnote').textContent = String(e.message || e).replace(/^[^:]*: /, '');
    return;
  }
  if (whenId(predictionTime(state.rank)) === pred.at) {
    state.prediction = pred;
    state.lastPredictionMs = performance.now() - t0;
    $('predictnote').textContent = '';
  }
}
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
    case 'predicted': {
      const p = state.cellP ? state.cellP[i] : NaN;
      return Number.isNaN(p) ? NO_MODEL : viridis(p);
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

// The shading the scene's lights (the hemisphere light and the sun, as a Lambert material shades
// them) give each face direction, per linear channel: a face of the mesh is flat, so its shade is
// one colour, computed here once instead of for every pixel. SKY and SUN are the lights' intensities.
const SKY = 1.6, SUN = 1.6;
const GROUND = new THREE.Color(0x445066), SUN_DIR = new THREE.Vector3(-0.5, -0.8, 1.6).normalize();
const SHADE = FACES.map(({ n }) => {
  const w = 0.5 * n[2] + 0.5, d = Math.max(0, n[0] * SUN_DIR.x + n[1] * SUN_DIR.y + n[2] * SUN_DIR.z);
  return new THREE.Vector3(...[GROUND.r, GROUND.g, GROUND.b].map((g) => (SKY * (g * (1 - w) + w) + SUN * d) / Math.PI));
});

// The mesh's shader. A face of the mesh may span many voxels (see surfaceLayer); the colour of the
// voxel under a pixel comes from a 3D texture of the cells' colours (sRGB, one texel per cell of the
// level's grid), lit by the face's shade in linear light and shown in sRGB.
const vertexShader = `
uniform vec3 uToCell;
uniform float uPerKey;
out vec3 vCell;
void main() {
  vCell = position * uPerKey + uToCell;
  gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0);
}`;
const fragmentShader = `
uniform highp sampler3D uColors;
uniform vec3 uNormal;
uniform vec3 uShade;
uniform float opacity;
in vec3 vCell;
out highp vec4 outColor;
void main() {
  vec4 texel = texelFetch(uColors, ivec3(floor(vCell - 0.5 * uNormal)), 0);
  if (texel.a == 0.0) discard;
  vec3 srgb = texel.rgb;
  vec3 lit = pow(srgb, vec3(2.2)) * uShade;
  outColor = vec4(pow(lit, vec3(1.0 / 2.2)), opacity);
}`;
const voxelUniforms = { opacity: { value: 1 } };

// Each voxel's colour varies by a few percent, so that the voxels of a flat wall stay visible.
const JITTER = Float32Array.from({ length: 256 }, (_, h) => 0.94 + (0.06 * h) / 255);

// A layer draws the drawn cells of one level: its mesh (the faces of each direction grouped, one
// material per direction), the 3D texture of its cells' colours, and buffers kept from one
// snapshot to the next (written into, grown by a quarter when a snapshot does not fit).
const layers = new Map();
const scratch = { grid: new Uint8Array(0), mask: new Uint8Array(0) };
function layerFor(level) {
  let layer = layers.get(level);
  if (layer) return layer;
  const shared = { uColors: { value: null }, uToCell: { value: new THREE.Vector3() }, uPerKey: { value: 1 } };
  const materials = FACES.map((f, i) => new THREE.ShaderMaterial({
    glslVersion: THREE.GLSL3, vertexShader, fragmentShader,
    uniforms: { ...shared, opacity: voxelUniforms.opacity, uNormal: { value: new THREE.Vector3(...f.n) }, uShade: { value: SHADE[i] } },
  }));
  layer = { level, materials, shared, capacity: 0, position: null, geometry: null, mesh: null, texture: null, colors: null, plane: [] };
  layers.set(level, layer);
  return layer;
}
function reserveQuads(layer, count) {
  if (count <= layer.capacity) return;
  const cap = Math.max(count, Math.ceil(layer.capacity * 1.25), 1024);
  const position = new Float32Array(12 * cap);
  if (layer.position) position.set(layer.position);
  layer.position = position;
  layer.capacity = cap;
  layer.resized = true;
}
function setVoxelMaterials(fn) { for (const layer of layers.values()) layer.materials.forEach(fn); }

// Draws the drawn cells of level l (bounds b: least and greatest cell coordinates) as the faces
// between a cell and no drawn cell of that level, merged into rectangles where they lie in one
// plane (greedy meshing: a wall is a few rectangles rather than a quad per voxel face). Returns
// the number of rectangles.
function surfaceLayer(snap, drawn, n, l, b) {
  const layer = layerFor(l), keys = snap.keys, levels = snap.levels, s = 1 << l, o = state.info.key_origin;
  const N = [b[3] - b[0] + 3, b[4] - b[1] + 3, b[5] - b[2] + 3], nxy = N[0] * N[1], total = nxy * N[2];
  if (total > 64e6) throw new Error(`a level-${l} grid of ${N.join(' x ')} cells is too large to draw`);
  if (scratch.grid.length < total) scratch.grid = new Uint8Array(Math.ceil(total * 1.25));
  const grid = scratch.grid;
  grid.fill(0, 0, total);
  if (!layer.colors || layer.colors.length !== 4 * total) layer.colors = new Uint8Array(4 * total);
  const colors = layer.colors;
  colors.fill(0);  // alpha 0: no drawn cell
  // Cells per slice along each axis: empty slices are skipped.
  const slices = [new Uint32Array(N[0]), new Uint32Array(N[1]), new Uint32Array(N[2])];
  for (let k = 0; k < n; ++k) {
    const i = drawn[k];
    if (levels[i] !== l) continue;
    const x = (keys[3 * i] >> l) - b[0] + 1, y = (keys[3 * i + 1] >> l) - b[1] + 1, z = (keys[3 * i + 2] >> l) - b[2] + 1;
    const j = x + N[0] * y + nxy * z;
    grid[j] = 1;
    ++slices[0][x]; ++slices[1][y]; ++slices[2][z];
    const c = colorOf(snap, i);
    const jitter = JITTER[((keys[3 * i] * 73856093) ^ (keys[3 * i + 1] * 19349663) ^ (keys[3 * i + 2] * 83492791)) & 255];
    colors[4 * j] = c[0] * jitter; colors[4 * j + 1] = c[1] * jitter; colors[4 * j + 2] = c[2] * jitter; colors[4 * j + 3] = 255;
  }
  const stride = [1, N[0], nxy];
  // The faces of each direction (grid index of the cell), found in one pass over the grid in its
  // order (z, y, x), then sorted stably by the slice along the direction's axis: within a slice,
  // they come row by row.
  const faces = FACES.map(() => []);
  for (let z = 1; z < N[2] - 1; ++z) {
    if (slices[2][z] === 0) continue;
    for (let y = 1; y < N[1] - 1; ++y) {
      let j = 1 + N[0] * y + nxy * z;
      for (let x = 1; x < N[0] - 1; ++x, ++j) {
        if (grid[j] === 0) continue;
        if (grid[j + 1] === 0) faces[0].push(j);
        if (grid[j - 1] === 0) faces[1].push(j);
        if (grid[j + N[0]] === 0) faces[2].push(j);
        if (grid[j - N[0]] === 0) faces[3].push(j);
        if (grid[j + nxy] === 0) faces[4].push(j);
        if (grid[j - nxy] === 0) faces[5].push(j);
      }
    }
  }
  // Grid coordinate g along axis a to the mesh's units (keys relative to the origin); rectangles
  // reach a 64th of a cell beyond their edges so that no pixel falls between two of them (the
  // part beyond a drawn cell finds no colour and is not drawn).
  const toKey = (a, g) => (g - 1 + b[a]) * s - o;
  const EPS = 1 / 64;
  reserveQuads(layer, layer.capacity || 1024);
  let q = 0;
  const groups = [];
  const coord = (j, a) => (a === 0 ? j % N[0] : a === 1 ? Math.floor(j / N[0]) % N[1] : Math.floor(j / nxy));
  for (let f = 0; f < 6; ++f) {
    const a = f >> 1, u = a === 0 ? 1 : 0, v = a === 2 ? 1 : 2;
    const nu = N[u], list = faces[f], first = q, corners = FACES[f].c;
    // Stable counting sort by slice.
    const start = new Uint32Array(N[a] + 1);
    for (const j of list) ++start[coord(j, a) + 1];
    for (let w = 1; w <= N[a]; ++w) start[w] += start[w - 1];
    const sorted = new Int32Array(list.length), fill = start.slice();
    for (const j of list) sorted[fill[coord(j, a)]++] = j;
    if (scratch.mask.length < nu * N[v]) scratch.mask = new Uint8Array(nu * N[v]);
    const mask = scratch.mask;
    let plane = f % 2 ? -Infinity : Infinity;
    for (let w = 1; w < N[a] - 1; ++w) {
      if (start[w] === start[w + 1]) continue;
      const at = toKey(a, w + (f % 2 ? 0 : 1));
      if (f % 2 ? at > plane : at < plane) plane = at;
      for (let k = start[w]; k < start[w + 1]; ++k) mask[coord(sorted[k], u) + nu * coord(sorted[k], v)] = 1;
      for (let k = start[w]; k < start[w + 1]; ++k) {
        const uu = coord(sorted[k], u), vv = coord(sorted[k], v);
        if (!mask[uu + nu * vv]) continue;
        let du = 1;
        while (mask[uu + du + nu * vv]) ++du;
        let dv = 1;
        for (; ; ++dv) {
          let full = true;
          for (let x = 0; x < du && full; ++x) full = mask[uu + x + nu * (vv + dv)] === 1;
          if (!full) break;
        }
        for (let y = 0; y < dv; ++y) mask.fill(0, uu + nu * (vv + y), uu + du + nu * (vv + y));
        if (q === layer.capacity) reserveQuads(layer, q + 1);
        const p = layer.position;
        for (let c = 0; c < 4; ++c) {
          const corner = corners[c], e = 12 * q + 3 * c;
          p[e + a] = at;
          p[e + u] = toKey(u, uu + corner[u] * (du + 2 * EPS) - EPS);
          p[e + v] = toKey(v, vv + corner[v] * (dv + 2 * EPS) - EPS);
        }
        ++q;
      }
    }
    groups.push([first, q - first]);
    layer.plane[f] = plane;
  }
  if (layer.resized || !layer.geometry) {
    if (layer.geometry) layer.geometry.dispose();
    const index = new Uint32Array(6 * layer.capacity);  // the same two triangles for every rectangle
    for (let r = 0, base = 0, at = 0; r < layer.capacity; ++r, base += 4, at += 6) {
      index[at] = base; index[at + 1] = base + 1; index[at + 2] = base + 2;
      index[at + 3] = base; index[at + 4] = base + 2; index[at + 5] = base + 3;
    }
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(layer.position, 3).setUsage(THREE.DynamicDrawUsage));
    g.setIndex(new THREE.BufferAttribute(index, 1));
    // For picking: a sphere around the whole key space (the ray test is per triangle anyway).
    g.boundingSphere = new THREE.Sphere(new THREE.Vector3(), 2 * 65536);
    layer.geometry = g;
    layer.resized = false;
    if (layer.mesh) layer.mesh.geometry = g;
  } else {
    const attribute = layer.geometry.getAttribute('position');
    attribute.clearUpdateRanges();
    attribute.addUpdateRange(0, 12 * q);
    attribute.needsUpdate = true;
  }
  const g = layer.geometry;
  g.clearGroups();
  groups.forEach(([first, count], f) => g.addGroup(6 * first, 6 * count, f));
  g.setDrawRange(0, 6 * q);
  if (layer.texture && (layer.texture.image.width !== N[0] || layer.texture.image.height !== N[1] || layer.texture.image.depth !== N[2])) {
    layer.texture.dispose();
    layer.texture = null;
  }
  if (!layer.texture) {
    layer.texture = new THREE.Data3DTexture(colors, N[0], N[1], N[2]);
    layer.texture.magFilter = layer.texture.minFilter = THREE.NearestFilter;
    layer.texture.unpackAlignment = 1;
  }
  layer.texture.image.data = colors;
  layer.texture.needsUpdate = true;
  layer.shared.uColors.value = layer.texture;
  layer.shared.uPerKey.value = 1 / s;
  layer.shared.uToCell.value.set(o / s - b[0] + 1, o / s - b[1] + 1, o / s - b[2] + 1);
  if (!layer.mesh) {
    layer.mesh = new THREE.Mesh(g, layer.materials);
    layer.mesh.frustumCulled = false;
    layer.mesh.userData.level = l;
  }
  layer.mesh.scale.setScalar(state.info.resolution_m);
  if (!layer.mesh.parent) scene.add(layer.mesh);
  return q;
}

// The drawn cells, one layer per level of detail among them. Returns the number of rectangles.
function surfaceMesh(snap, drawn, n) {
  const bounds = new Map(), keys = snap.keys, levels = snap.levels;
  for (let k = 0; k < n; ++k) {
    const i = drawn[k], l = levels[i];
    let b = bounds.get(l);
    if (!b) bounds.set(l, b = [Infinity, Infinity, Infinity, -Infinity, -Infinity, -Infinity]);
    const x = keys[3 * i] >> l, y = keys[3 * i + 1] >> l, z = keys[3 * i + 2] >> l;
    if (x < b[0]) b[0] = x; if (x > b[3]) b[3] = x;
    if (y < b[1]) b[1] = y; if (y > b[4]) b[4] = y;
    if (z < b[2]) b[2] = z; if (z > b[5]) b[5] = z;
  }
  let quads = 0;
  for (const [l, b] of bounds) quads += surfaceLayer(snap, drawn, n, l, b);
  for (const layer of layers.values()) if (!bounds.has(layer.level) && layer.mesh) scene.remove(layer.mesh);
  return quads;
}

/** The drawn cell (its index in the shown snapshot) behind a point of a face with normal n. */
function cellAt(point, normal) {
  const r = state.info.resolution_m, o = state.info.key_origin, snap = state.shown;
  const key = [point.x, point.y, point.z].map((v, a) => Math.floor(v / r - 0.5 * normal.getComponent(a)) + o);
  for (let k = 0; k < state.drawn; ++k) {
    const i = state.visible[k], l = snap.levels[i];
    if ((snap.keys[3 * i] >> l) === (key[0] >> l) && (snap.keys[3 * i + 1] >> l) === (key[1] >> l) &&
        (snap.keys[3 * i + 2] >> l) === (key[2] >> l)) return i;
  }
  return -1;
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
  state.cellP = state.colorMode === 'predicted' && state.prediction && state.prediction.at === whenId(predictionTime(snap.rank)) ?
    cellPredictions(snap, state.prediction) : null;
  state.maxChanges = 1;
  for (let i = 0; i < snap.count; ++i) state.maxChanges = Math.max(state.maxChanges, snap.changes[i]);
  const cut = cutHeightKey();
  const t0 = performance.now();
  if (state.visible.length < snap.count) state.visible = new Uint32Array(Math.ceil(snap.count * 1.25));
  let n = 0;
  for (let i = 0; i < snap.count; ++i) if (snap.keys[3 * i + 2] < cut) state.visible[n++] = i;
  state.drawn = n;
  state.faces = surfaceMesh(snap, state.visible, n);
  state.lastBuildMs = performance.now() - t0;
  // Opaque unless a diff is shown over it (blending costs a software renderer every pixel).
  voxelUniforms.opacity.value = state.diff ? 0.28 : 1;
  setVoxelMaterials((m) => { m.transparent = !!state.diff; m.depthWrite = !state.diff; });
  drawChanged();
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
  if (!state.predictAt && $('predictat')) $('predictat').value = fieldTime(state.info.sessions[rank].time_s);
  const t0 = performance.now();
  const [snap] = await Promise.all([state.source.snapshot(rank, state.budget), loadPrediction(rank), loadCostmap(rank)]);
  if (state.rank !== rank) return;  // a later move of the slider won
  state.snap = snap;
  state.lastLoadMs = performance.now() - t0;
  drawSnapshot();
  state.loadedRank = rank;
  scheduleRefine();
  // The neighbouring sessions, fetched and decoded while this one is looked at: the slider and
  // play usually move by one.
  if (state.source.prefetches) {
    for (const next of [rank + 1, rank - 1]) {
      if (next >= 0 && next < state.info.sessions.length) state.source.snapshot(next, state.budget).catch(() => {});
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Finer cells where the camera looks: when the whole map comes in coarse cubes, the server is
// asked, after each camera move, for the cells of the part of the map in view (footprint) with
// the same budget.

let refineTimer = null;
function scheduleRefine() {
  clearTimeout(refineTimer);
  refineTimer = setTimeout(() => refine().catch(report), 250);
}

// The part of the map on screen, up to twice the distance to the orbit target (farther cells
// look small enough in coarse cubes): the box in x, y (metres) around the camera (when within
// the map's heights) and the parts of the rays through the picture's corners within those
// heights, each cut at that reach.
function footprint() {
  const r = state.info.resolution_m, o = state.info.key_origin, b = state.bounds;
  camera.updateMatrixWorld();  // the camera may have moved since the last frame
  const z0 = (b.zmin - o) * r, z1 = (b.zmax - o) * r, p = camera.position;
  const reach = 2 * p.distanceTo(controls.target);
  const xs = [], ys = [];
  if (p.z >= z0 && p.z <= z1) { xs.push(p.x); ys.push(p.y); }
  for (const [u, v] of [[-1, -1], [1, -1], [1, 1], [-1, 1]]) {
    const d = new THREE.Vector3(u, v, 0.5).unproject(camera).sub(p).normalize();
    // The ray's part within the heights, cut at the reach: a ray that meets the heights only
    // beyond it (or never: it rises above them) bounds the view at the reach.
    let t0 = 0, t1 = reach;
    if (Math.abs(d.z) > 1e-9) {
      const a = (z0 - p.z) / d.z, c = (z1 - p.z) / d.z;
      t0 = Math.min(reach, Math.max(0, Math.min(a, c)));
      t1 = Math.max(a, c) < 0 ? reach : Math.min(reach, Math.max(a, c));
    }
    for (const t of [t0, t1]) { xs.push(p.x + t * d.x); ys.push(p.y + t * d.y); }
  }
  if (!xs.length) return null;
  const clip = (v, k0, k1) => Math.min((k1 - o) * r, Math.max((k0 - o) * r, v));
  return [clip(Math.min(...xs), b.xmin, b.xmax), clip(Math.min(...ys), b.ymin, b.ymax),
          clip(Math.max(...xs), b.xmin, b.xmax), clip(Math.max(...ys), b.ymin, b.ymax)];
}

async function refine() {
  const snap = state.snap;
  if (!state.source.refines || !snap || snap.level === 0) { state.detail = null; return; }
  const r = state.info.resolution_m, o = state.info.key_origin, b = state.bounds;
  const f = footprint();
  // Most of the map in view: the whole map's cells are as fine as the budget allows.
  const area = f ? (f[2] - f[0]) * (f[3] - f[1]) : 0, whole = (b.xmax - b.xmin) * (b.ymax - b.ymin) * r * r;
  if (!f || area <= 0 || area >= 0.6 * whole) {
    if (state.detail) { state.detail = null; drawSnapshot(); }
    return;
  }
  // Whole coarse cells, so that each is either replaced or kept.
  const cell = 1 << snap.level;
  const lo = (v) => Math.max(0, Math.floor((v / r + o) / cell) * cell);
  const hi = (v) => Math.min(65535, Math.ceil((v / r + o) / cell) * cell - 1);
  const region = [lo(f[0]), lo(f[1]), b.zmin, hi(f[2]), hi(f[3]), Math.min(65535, b.zmax)];
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
//
// The objects are the one call's (findChanges: the list `chronomap diff --json` prints, with
// moves), from /api/diff?format=json or the tour's copy of it; the changed cells (the binary
// reply) only draw them, coloured by the object their component belongs to.

const KIND_COLOUR = { appeared: APPEARED, vanished: VANISHED, moved: MOVED };
const ARROW = 0xf4f6fa;  // light, to stand out on the moved object's amber voxels

function clearDiff() {
  state.diff = null;
  if (changed) { scene.remove(changed); changed.dispose(); changed = null; }
  frames.clear();
  $('tags').innerHTML = '';
  $('leaders').innerHTML = '';
  state.labels = [];
  state.arrows = [];
  redraw();
  $('objects').innerHTML = '';
  $('diffsum').textContent = '';
  $('showdiff').classList.remove('on');
  $('showdiff').textContent = 'Show changes';
}

// Per component id, the object it belongs to and whether it is a move's old place.
function objectOfComponent(objects) {
  const out = new Map();
  for (const o of objects) {
    o.components.forEach((c, k) => out.set(c, { object: o, old: o.kind === 'moved' && k === 0 }));
  }
  return out;
}

function cellColour(d, i, owners) {
  const owner = owners.get(d.component[i]);
  if (owner && owner.object.kind === 'moved') return owner.old ? MOVED_FROM : MOVED;
  return d.kinds[i] === 1 ? APPEARED : VANISHED;
}

// The changed cells below the height cut, as the map's voxels are cut (cutHeightKey).
function drawChanged() {
  const d = state.diff;
  if (!d) return;
  const cut = cutHeightKey();
  if (changed && state.diffCut === cut) return;
  if (changed) { scene.remove(changed); changed.dispose(); }
  const n = d.keys.length / 3, owners = objectOfComponent(d.objects);
  changed = instanced(n, new THREE.MeshLambertMaterial());
  const colors = changed.instanceColor.array;
  let m = 0;
  for (let i = 0; i < n; ++i) {
    if (d.keys[3 * i + 2] >= cut) continue;
    const size = cellCenter(d.keys, d.levels, i, tmp) * 0.98;
    mat.compose(tmp, quat, scl.set(size, size, size));
    changed.setMatrixAt(m, mat);
    srgb.setRGB(...cellColour(d, i, owners).map((v) => v / 255), THREE.SRGBColorSpace);
    colors.set([srgb.r, srgb.g, srgb.b], 3 * m);
    ++m;
  }
  changed.count = m;
  state.diffDrawn = m;
  state.diffCut = cut;
  scene.add(changed);
  // An object wholly above the cut is hidden with its frame, arrow and label.
  const cutM = (cut - state.info.key_origin) * state.info.resolution_m;
  for (const f of frames.children) f.visible = f.userData.bottom < cutM;
  redraw();
}

// A move's old place: its centroid and size (the json's `from`) as a box.
const placeBox = (p) => new THREE.Box3().setFromCenterAndSize(new THREE.Vector3(...p.centroid), new THREE.Vector3(...p.size));

function addObject(o) {
  const colour = new THREE.Color(css(KIND_COLOUR[o.kind]));
  const b = new THREE.Box3(new THREE.Vector3(...o.bbox_min), new THREE.Vector3(...o.bbox_max));
  b.expandByScalar(state.info.resolution_m);
  const group = new THREE.Group();
  group.add(new THREE.Box3Helper(b, colour));
  let bottom = b.min.z;
  if (o.kind === 'moved') {
    // Where it stood, framed dimmer, and an arrow from there to where it is now (centroids),
    // drawn over the voxels so that it stays visible inside the object.
    const old = placeBox(o.from).expandByScalar(state.info.resolution_m);
    group.add(new THREE.Box3Helper(old, new THREE.Color(css(MOVED_FROM))));
    bottom = Math.min(bottom, old.min.z);
    const from = new THREE.Vector3(...o.from.centroid), to = new THREE.Vector3(...o.to.centroid);
    const length = from.distanceTo(to);
    if (length > 0) {
      const head = Math.min(0.4 * length, 0.25);
      const arrow = new THREE.ArrowHelper(to.clone().sub(from).normalize(), from, length, ARROW, head, 0.6 * head);
      arrow.traverse((x) => { if (x.material) { x.material.depthTest = false; x.renderOrder = 10; } });
      arrow.userData = { from: from.toArray(), to: to.toArray() };
      group.add(arrow);
      group.userData.arrow = arrow;
    }
  }
  const tag = document.createElement('div');
  tag.className = `tag ${o.kind}`;
  tag.textContent = o.id;
  $('tags').appendChild(tag);
  group.userData = { ...group.userData, object: o, tag, bottom, top: new THREE.Vector3((b.min.x + b.max.x) / 2, (b.min.y + b.max.y) / 2, b.max.z) };
  frames.add(group);
}

async function showDiff(from, to) {
  $('from').value = from;
  $('to').value = to;
  const asked = `${from}/${to}`;
  state.diffAsked = asked;
  const d = await state.source.diff(from, to);
  if (state.diffAsked !== asked) return state.diff;  // a later choice won
  clearDiff();
  state.diff = d;
  $('showdiff').classList.add('on');
  $('showdiff').textContent = 'Hide changes';
  for (const o of d.objects) addObject(o);
  // The moves' arrows as drawn: tail and tip (metres), for tests and the console.
  state.arrows = frames.children.filter((g) => g.userData.arrow).map((g) => {
    const a = g.userData.arrow, dir = new THREE.Vector3(0, 1, 0).applyQuaternion(a.quaternion);
    return { id: g.userData.object.id, tail: a.position.toArray(), tip: a.position.clone().addScaledVector(dir, a.cone.position.y).toArray() };
  });
  listObjects(d);
  // The slider shows the later state, where the changes are seen.
  if (state.rank !== to) await setSession(to);
  else drawSnapshot();
  return d;
}

// The panel's choices: shown at once, in place of what was shown; a pair the tour does not hold
// is said in the panel.
function showChosen() {
  showDiff(Number($('from').value), Number($('to').value)).catch((e) => {
    clearDiff();
    drawSnapshot();
    $('diffsum').textContent = String(e.message || e);
  });
}

function listObjects(d) {
  const total = d.appeared_voxels !== undefined ? d.appeared_voxels + d.vanished_voxels : d.voxels;
  $('diffsum').textContent = `${d.objects.length} object${d.objects.length === 1 ? '' : 's'}, ${total} changed voxels` +
    (d.cells_sent < d.cells ? ` (${d.cells_sent} of ${d.cells} cells drawn)` : '');
  const list = $('objects');
  for (const o of d.objects) {
    const row = document.createElement('div');
    row.className = 'obj';
    const sz = o.size.map((v) => v.toFixed(2)).join(' × ');
    const what = o.kind === 'moved' ? `moved ${o.distance_m.toFixed(2)} m` : o.kind;
    row.innerHTML = `<span class="num ${o.kind}">${o.id}</span>` +
      `<span>${what} <span class="dim">${sz} m</span></span><span class="dim">${o.voxels} vox</span>`;
    row.title = `centre ${o.centroid.map((v) => v.toFixed(2)).join(', ')} m` +
      (o.kind === 'moved' ? `, from ${o.from.centroid.map((v) => v.toFixed(2)).join(', ')} m` : '');
    row.addEventListener('click', () => focusOn(o));
    list.appendChild(row);
  }
  if (!d.objects.length) list.innerHTML = '<div class="dim">nothing changed between these times</div>';
}

/** Flies to an object: the json's fields (centroid, bbox_min, bbox_max) or a component's (_m). */
function focusOn(c) {
  const centroid = c.centroid ?? c.centroid_m, lo = c.bbox_min ?? c.bbox_min_m, hi = c.bbox_max ?? c.bbox_max_m;
  const center = new THREE.Vector3(...centroid);
  const size = Math.max(...hi.map((v, k) => v - lo[k]), 0.5);
  const dir = camera.position.clone().sub(controls.target).normalize();
  controls.target.copy(center);
  camera.position.copy(center).addScaledVector(dir, size * 4 + 1);
  controls.update();
}

// Labels: each first tried just above its object's frame, else at the nearest free spot on
// rings around it (8 directions, 14 px apart), so that no two overlap; a label placed away from
// its spot gets a leader line to the object's top.
const LABEL_GAP = 4, RING_PX = 14, RINGS = 12;
const overlaps = (a, b) => a.x < b.x + b.w + 2 && b.x < a.x + a.w + 2 && a.y < b.y + b.h + 2 && b.y < a.y + a.h + 2;
// The panels on screen: labels are not placed over them (unless their object lies under one).
function panelRects() {
  return [...document.querySelectorAll('.panel')].filter((p) => p.offsetParent !== null || getComputedStyle(p).display !== 'none')
    .map((p) => p.getBoundingClientRect()).filter((r) => r.width > 0)
    .map((r) => ({ x: r.left, y: r.top, w: r.width, h: r.height }));
}
function placeTags() {
  const w = window.innerWidth, h = window.innerHeight, placed = [], leaders = [];
  const panels = frames.children.length ? panelRects() : [];
  state.labels = [];
  for (const f of frames.children) {
    const p = f.userData.top.clone().project(camera);
    const tag = f.userData.tag;
    const visible = f.visible && p.z < 1 && Math.abs(p.x) < 1.05 && Math.abs(p.y) < 1.05;
    tag.style.display = visible ? '' : 'none';
    if (!visible) continue;
    const ax = ((p.x + 1) / 2) * w, ay = ((1 - p.y) / 2) * h;
    const tw = tag.offsetWidth, th = tag.offsetHeight;
    const home = { x: ax - tw / 2, y: ay - th - LABEL_GAP, w: tw, h: th };
    let at = home;
    search: for (let ring = 0; ring <= RINGS; ++ring) {
      for (let k = 0; k < (ring ? 8 : 1); ++k) {
        const a = (k / 8) * 2 * Math.PI - Math.PI / 2;
        const c = { ...home, x: home.x + Math.cos(a) * ring * RING_PX * 1.6, y: home.y + Math.sin(a) * ring * RING_PX };
        const inside = c.x >= 0 && c.y >= 0 && c.x + c.w <= w && c.y + c.h <= h;
        if (inside && !placed.some((q) => overlaps(c, q)) && !panels.some((q) => overlaps(c, q))) { at = c; break search; }
      }
    }
    placed.push(at);
    tag.style.left = `${at.x}px`;
    tag.style.top = `${at.y}px`;
    const moved = Math.hypot(at.x - home.x, at.y - home.y) > 1;
    if (moved) {
      // From the label's edge nearest the object to the object's top.
      const lx = Math.min(Math.max(ax, at.x), at.x + at.w), ly = Math.min(Math.max(ay, at.y), at.y + at.h);
      leaders.push(`<line x1="${lx}" y1="${ly}" x2="${ax}" y2="${ay}" stroke="${css(KIND_COLOUR[f.userData.object.kind])}" ` +
                   'stroke-width="1.5"/><circle cx="' + ax + '" cy="' + ay + '" r="2.5" fill="#e5e9f0"/>');
    }
    state.labels.push({ id: f.userData.object.id, x: at.x, y: at.y, w: at.w, h: at.h, anchor: [ax, ay], leader: moved });
  }
  $('leaders').innerHTML = leaders.join('');
}

// ---------------------------------------------------------------------------------------------
// History of a voxel

const raycaster = new THREE.Raycaster();
async function pick(event) {
  if (!state.shown) return;
  const rect = renderer.domElement.getBoundingClientRect();
  const ndc = new THREE.Vector2(((event.clientX - rect.left) / rect.width) * 2 - 1, -((event.clientY - rect.top) / rect.height) * 2 + 1);
  raycaster.setFromCamera(ndc, camera);
  const meshes = [...layers.values()].filter((layer) => layer.mesh && layer.mesh.parent).map((layer) => layer.mesh);
  const hit = raycaster.intersectObjects(meshes, false)[0];
  if (!hit) return;
  const cell = cellAt(hit.point, hit.face.normal);
  if (cell >= 0) await selectCell(cell);
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
  if (mode === 'predicted') {
    const p = state.prediction;
    const when = state.predictAt ? `${state.predictAt.replace('T', ' ').replace(':00Z', ' UTC')}` : 'the slider\'s time';
    html = `<div>predicted probability of occupancy at ${when} (${p ? p.model : 'combined'} model, docs/rhythm.md)</div>` +
      `<div class="ramp" style="background:${gradientCss(viridis)}"></div><div class="ends"><span>0</span><span>1</span></div>` +
      `<div class="key"><span class="sw" style="background:${css(NO_MODEL)}"></span>never changed: no model</div>`;
    if (p && p.fit_s > 0) html += `<div class="dim">models fitted on the server in ${p.fit_s.toFixed(p.fit_s < 1 ? 2 : 1)} s</div>`;
  }
  if (mode === 'age') {
    html = `<div>sessions since the voxel took its state</div><div class="ramp" style="background:${gradientCss((t) => viridis(1 - t))}"></div>` +
      `<div class="ends"><span>1</span><span>${state.rank}</span></div><div class="key"><span class="sw" style="background:rgb(255,140,40)"></span>set by this session</div>`;
  }
  if (state.costmap) {
    const c = state.costmap;
    html += `<div style="margin-top:6px">navigation cost (${c.z_min_m}–${c.z_max_m} m above the floor, ${c.model} model)</div>` +
      `<div class="ramp" style="background:${gradientCss(heat)}"></div><div class="ends"><span>low</span><span>high</span></div>` +
      [[0, 'free'], [99, 'too close for the robot'], [100, 'obstacle']].map(([v, t]) =>
        `<div class="key"><span class="sw" style="background:${css(costColor(v).slice(0, 3))}"></span>${t}</div>`).join('');
  }
  if (state.diff) {
    html += `<div class="key"><span class="sw appeared"></span>appeared (numbered, framed)</div>` +
      `<div class="key"><span class="sw vanished"></span>vanished</div>` +
      `<div class="key"><span class="sw moved"></span>moved (where it stood: paler), arrow from there</div>`;
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
  $('colormode').addEventListener('change', () => setColorMode($('colormode').value).catch(report));
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
  if ($('costmap')) $('costmap').addEventListener('click', () => setCostmap(!state.costmapOn).catch(report));
  $('showdiff').addEventListener('click', () => {
    if (state.diff) { state.diffAsked = null; clearDiff(); drawSnapshot(); return; }
    showChosen();
  });
  // A new choice of times shows its changes at once.
  $('from').addEventListener('change', showChosen);
  $('to').addEventListener('change', showChosen);
  if ($('predictat')) {
    $('predictat').addEventListener('change', () => setPredictionTime($('predictat').value).catch(report));
    $('predictnow').addEventListener('click', () => setPredictionTime('').catch(report));
  }
  let down = null;
  renderer.domElement.addEventListener('pointerdown', (e) => { down = [e.clientX, e.clientY]; });
  renderer.domElement.addEventListener('pointerup', (e) => {
    if (down && Math.hypot(e.clientX - down[0], e.clientY - down[1]) < 4) pick(e).catch(report);
  });
}

// A direction's faces are drawn only when the camera is beyond the plane of one of them.
function cullFaceDirections() {
  const r = state.info.resolution_m, p = camera.position;
  const cam = [p.x / r, p.y / r, p.z / r];
  for (const layer of layers.values()) {
    for (let f = 0; f < 6; ++f) {
      const c = cam[f >> 1];
      layer.materials[f].visible = !state.cullFaces || (f % 2 ? c < layer.plane[f] : c > layer.plane[f]);
    }
  }
}

// Frames are drawn only when something moved or changed, so an idle page costs nothing.
let dirty = true;
function redraw() { dirty = true; }
function animate() {
  requestAnimationFrame(animate);
  if (!controls.update() && !dirty) return;
  dirty = false;
  placeTags();
  cullFaceDirections();
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
  if (!state.source.predicts) {
    $('predictedmode').remove(); $('costmaprow').remove(); $('predictrow').remove();
  } else {
    state.rank = state.info.sessions.length - 1;
    setPredictionLimits();
  }
  wire();
  animate();
  const last = state.info.sessions.length - 1;
  await setSession(last);
  $('busy').style.display = 'none';
  state.ready = true;
}

// The navigation cost map (chronomap costmap at the slider's time) as a layer on the floor:
// free green, costly from blue to red by cost, orange where the robot's centre cannot be
// (within its radius of an obstacle), red for obstacles; unknown is not drawn.
let costLayer = null;
function costColor(c) {
  if (c === 255) return [0, 0, 0, 0];
  if (c === 0) return [60, 180, 90, 110];
  if (c === 100) return [220, 30, 40, 235];
  if (c === 99) return [245, 150, 40, 210];
  return [...heat(c / 98), 210];
}
async function loadCostmap(rank) {
  if (!state.costmapOn || !state.source.predicts) return;
  const cm = await state.source.costmap(predictionTime(rank));
  if (whenId(predictionTime(state.rank)) !== cm.at || !state.costmapOn) return;
  state.costmap = cm;
  if (costLayer) { scene.remove(costLayer); costLayer.geometry.dispose(); costLayer.material.map.dispose(); costLayer.material.dispose(); }
  const rgba = new Uint8Array(4 * cm.width * cm.height);
  for (let i = 0; i < cm.cost.length; ++i) rgba.set(costColor(cm.cost[i]), 4 * i);
  const texture = new THREE.DataTexture(rgba, cm.width, cm.height);
  texture.magFilter = THREE.NearestFilter;
  texture.colorSpace = THREE.SRGBColorSpace;
  texture.needsUpdate = true;
  const w = cm.width * cm.resolution_m, h = cm.height * cm.resolution_m;
  costLayer = new THREE.Mesh(new THREE.PlaneGeometry(w, h),
                             new THREE.MeshBasicMaterial({ map: texture, transparent: true, depthWrite: false }));
  const r = state.info.resolution_m, o = state.info.key_origin;
  const floor = state.bounds ? (state.bounds.zmin - o) * r : 0;
  costLayer.position.set(cm.origin_m[0] + w / 2, cm.origin_m[1] + h / 2, floor + cm.z_min_m);
  costLayer.renderOrder = 1;
  scene.add(costLayer);
  updateLegend();
  redraw();
}
async function setCostmap(on) {
  state.costmapOn = on;
  $('costmap').classList.toggle('on', on);
  if (!on) {
    if (costLayer) { scene.remove(costLayer); costLayer = null; }
    state.costmap = null;
    updateLegend();
    redraw();
    return;
  }
  $('busy').style.display = 'block';
  $('busy').textContent = 'computing the cost map (the first time, the server fits the temporal models)';
  try { await loadCostmap(state.rank); } finally { $('busy').style.display = 'none'; }
}

async function setColorMode(mode) {
  state.colorMode = mode;
  $('colormode').value = mode;
  if ($('predictrow')) $('predictrow').style.display = mode === 'predicted' ? '' : 'none';
  if (mode === 'predicted') {
    $('busy').style.display = 'block';
    $('busy').textContent = 'predicting occupancy (the first time, the server fits the temporal models)';
    try { await loadPrediction(state.rank); } finally { $('busy').style.display = 'none'; }
  }
  drawSnapshot();
}

// The date and hour field (UTC): from the first session to a week past the last. A value of ''
// follows the slider again.
const WEEK_S = 7 * 24 * 3600;
const fieldTime = (s) => new Date(Math.floor(s / 60) * 60000).toISOString().slice(0, 16);
function setPredictionLimits() {
  const s = state.info.sessions;
  $('predictat').min = fieldTime(s[0].time_s + 59.999);
  $('predictat').max = fieldTime(s[s.length - 1].time_s + WEEK_S);
  $('predictat').value = fieldTime(s[state.rank].time_s);
}
async function setPredictionTime(value) {
  const s = state.info.sessions, last = s[s.length - 1];
  const at = value ? Date.parse(`${value.slice(0, 16)}:00Z`) / 1000 : NaN;
  if (value && !(at >= s[0].time_s && at <= last.time_s + WEEK_S)) {
    // What the server would answer (it refuses the same times), said without asking it.
    const show = (t) => fieldTime(t).replace('T', ' ');
    $('predictnote').textContent = at > last.time_s ?
      `${value.replace('T', ' ')} UTC lies more than a week past the map's last session (${show(last.time_s)}): ` +
      `the temporal models predict up to ${show(last.time_s + WEEK_S)} UTC` :
      `${value.replace('T', ' ')} UTC lies before the map's first session (${show(s[0].time_s)} UTC)`;
    return;
  }
  $('predictnote').textContent = '';
  state.predictAt = value ? `${value.slice(0, 16)}:00Z` : null;
  $('predictat').value = value ? value.slice(0, 16) : fieldTime(state.info.sessions[state.rank].time_s);
  $('predictnow').disabled = !value;
  $('busy').style.display = 'block';
  $('busy').textContent = 'predicting occupancy (the first time, the server fits the temporal models)';
  try {
    await Promise.all([loadPrediction(state.rank), loadCostmap(state.rank).catch((e) => {
      $('predictnote').textContent = String(e.message || e).replace(/^[^:]*: /, '');
    })]);
  } finally { $('busy').style.display = 'none'; }
  drawSnapshot();
}

// Test hooks: the same calls the controls make.
state.setSession = (rank) => setSession(rank);
state.nextFrame = () => nextFrame();
state.showDiff = (from, to) => showDiff(from, to);
state.clearDiff = () => { clearDiff(); drawSnapshot(); };
state.selectCell = (i) => selectCell(i);
state.setColorMode = (m) => setColorMode(m);
state.setCostmap = (on) => setCostmap(on);
state.setPredictionTime = (value) => setPredictionTime(value);
state.toggleTopView = () => $('topview').click();
/** Cuts at `metres` above the map's origin (the slider's value nearest to it). */
state.setCut = (metres) => {
  const r = state.info.resolution_m, o = state.info.key_origin, b = state.bounds;
  const f = ((metres / r + o) - b.zmin) / Math.max(1, b.zmax - b.zmin);
  $('cut').value = Math.round(Math.min(1, Math.max(0, f)) * 1000);
  $('cut').dispatchEvent(new Event('input'));
};

main().catch(report);
