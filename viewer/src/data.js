// Where the page gets its data: the server of `chronomap view` (ServerSource) or the packet
// inside a tour file (TourSource). Both answer the same questions with the same shapes.

const TYPES = { u8: Uint8Array, u16: Uint16Array, u32: Uint32Array, f32: Float32Array };

/** Decodes a CMV1 packet (include/chronomap/view/packet.h): a JSON header, then typed arrays. */
export function readPacket(buffer) {
  const bytes = new Uint8Array(buffer);
  const magic = String.fromCharCode(bytes[0], bytes[1], bytes[2], bytes[3]);
  if (magic !== 'CMV1') throw new Error('not a chronomap viewer packet');
  const headerLength = new DataView(buffer).getUint32(4, true);
  const header = JSON.parse(new TextDecoder().decode(bytes.subarray(8, 8 + headerLength)));
  const arrays = {};
  let at = 8 + headerLength;
  for (const a of header.arrays) {
    at = Math.ceil(at / 8) * 8;
    const T = TYPES[a.type];
    arrays[a.name] = new T(buffer, at, a.length);
    at += a.length * T.BYTES_PER_ELEMENT;
  }
  return { header, arrays, bytes: buffer.byteLength };
}

async function fetchOk(url) {
  const r = await fetch(url);
  if (!r.ok) {
    let message = `${r.status}`;
    try { message = (await r.json()).error; } catch (e) { /* not JSON */ }
    throw new Error(`${url}: ${message}`);
  }
  return r;
}

/** The data of `chronomap view`: asked for piece by piece. */
export class ServerSource {
  static kCached = 12;
  /** The server sends finer cells for the part in view. */
  get refines() { return true; }
  /** Snapshots come over the network: worth asking for the next one early. */
  get prefetches() { return true; }
  constructor() { this.kind = 'server'; this.snapshots = new Map(); }
  async info() { return (await fetchOk('api/map')).json(); }
  /** The occupied cells at session `rank`, at most `budget`; only in `region` (keys x0, y0, z0,
   *  x1, y1, z1) when given. */
  async snapshot(rank, budget, region) {
    const where = region ? `&region=${region.join(',')}` : '';
    const id = `${rank}/${budget}${where}`;
    if (!this.snapshots.has(id)) {
      const p = fetchOk(`api/snapshot?session=${rank}&budget=${budget}${where}`)
        .then((r) => r.arrayBuffer()).then((b) => snapshotFrom(readPacket(b)));
      this.snapshots.set(id, p);
      p.catch(() => this.snapshots.delete(id));
      // Keep the most recent few: a map of many sessions would otherwise fill the page's memory.
      while (this.snapshots.size > ServerSource.kCached) this.snapshots.delete(this.snapshots.keys().next().value);
    }
    const p = this.snapshots.get(id);
    this.snapshots.delete(id);  // most recently used last
    this.snapshots.set(id, p);
    return p;
  }
  /** The changes from session `from` to `to`: the changed cells for drawing (the binary reply:
   *  keys, levels, kinds, component) and the objects of the one call (format=json: the list
   *  `chronomap diff --json` prints), asked for at once. */
  async diff(from, to) {
    const [cells, listed] = await Promise.all([
      fetchOk(`api/diff?from=${from}&to=${to}`).then((r) => r.arrayBuffer()),
      fetchOk(`api/diff?from=${from}&to=${to}&format=json`).then((r) => r.json())]);
    const p = readPacket(cells);
    return { ...p.header, from, to, keys: p.arrays.keys, levels: p.arrays.levels, kinds: p.arrays.kinds,
             component: p.arrays.component, bytes: p.bytes, objects: listed.objects,
             appeared_voxels: listed.appeared_voxels, vanished_voxels: listed.vanished_voxels };
  }
  async history(key, level) {
    return (await fetchOk(`api/history?key=${key.join(',')}&level=${level}`)).json();
  }
  /** The navigation cost map at `at` (chronomap costmap's defaults): width, height,
   *  resolution_m, origin_m, z band, cost (u8, 255 unknown). `at`: { rank } (a session) or
   *  { time } (an ISO-8601 time, up to a week past the last session). */
  async costmap(at, model = 'combined') {
    const q = readPacket(await (await fetchOk(`api/costmap?${whenQuery(at)}&model=${model}`)).arrayBuffer());
    return { ...q.header, rank: at.rank, at: whenId(at), cost: q.arrays.cost, bytes: q.bytes };
  }
  /** The server fits temporal models (or has them from --rhythm). */
  get predicts() { return true; }
  /** Every modelled cube's predicted probability of occupancy at `at` (as for costmap): keys
   *  (corners), levels and p. The first request fits the models on the server (seconds on a
   *  large map). */
  async prediction(at, model = 'combined') {
    const id = `${whenId(at)}/${model}`;
    if (!this.predictions) this.predictions = new Map();
    if (!this.predictions.has(id)) {
      const p = fetchOk(`api/predict?${whenQuery(at)}&model=${model}`).then((r) => r.arrayBuffer()).then((b) => {
        const q = readPacket(b);
        return { ...q.header, rank: at.rank, at: whenId(at), keys: q.arrays.keys, levels: q.arrays.levels, p: q.arrays.p,
                 bytes: q.bytes };
      });
      this.predictions.set(id, p);
      p.catch(() => this.predictions.delete(id));
      while (this.predictions.size > 4) this.predictions.delete(this.predictions.keys().next().value);
    }
    return this.predictions.get(id);
  }
}

/** A time the page asks about: { rank } (a session) or { time } (ISO-8601), as a query and an id. */
const whenQuery = (at) => (at.time !== undefined ? `t=${encodeURIComponent(at.time)}` : `session=${at.rank}`);
export const whenId = (at) => (at.time !== undefined ? at.time : `session ${at.rank}`);

function snapshotFrom(p) {
  const h = p.header;
  return { level: h.level, count: h.cells, occupiedVoxels: h.occupied_voxels, rank: h.rank, bytes: p.bytes,
           keys: p.arrays.keys, levels: p.arrays.levels, colors: p.arrays.colors, changes: p.arrays.changes,
           since: p.arrays.since };
}

function base64ToBuffer(text) {
  const s = atob(text.trim());
  const out = new Uint8Array(s.length);
  for (let i = 0; i < s.length; ++i) out[i] = s.charCodeAt(i);
  return out.buffer;
}

/** The data inside a tour file: every cell ever occupied with its state per session. */
export class TourSource {
  /** A tour holds one level of detail: no finer cells in view. */
  get refines() { return false; }
  /** A tour holds no temporal models. */
  get predicts() { return false; }
  constructor(element) {
    this.kind = 'tour';
    this.packet = readPacket(base64ToBuffer(element.textContent));
    const a = this.packet.arrays;
    this.sessions = this.packet.header.map.sessions.length;
    this.stride = Math.ceil(this.sessions / 4);
    this.cells = this.packet.header.cells;
    this.states = a.states;
    this.snapshots = new Map();
  }
  state(cell, session) {
    return (this.states[cell * this.stride + (session >> 2)] >> (2 * (session & 3))) & 3;
  }
  async info() {
    return { ...this.packet.header.map, default_max_voxels: this.cells, tour_level: this.packet.header.level,
             occupied_voxels: this.packet.header.occupied_voxels };
  }
  async snapshot(rank) {
    if (this.snapshots.has(rank)) return this.snapshots.get(rank);
    const a = this.packet.arrays;
    const chosen = [];
    for (let c = 0; c < this.cells; ++c) if (this.state(c, rank) === 2) chosen.push(c);
    const n = chosen.length;
    const keys = new Uint16Array(3 * n), levels = new Uint8Array(n), colors = new Uint8Array(3 * n);
    const changes = new Uint8Array(n), since = new Uint16Array(n);
    chosen.forEach((c, i) => {
      keys.set(a.keys.subarray(3 * c, 3 * c + 3), 3 * i);
      colors.set(a.colors.subarray(3 * c, 3 * c + 3), 3 * i);
      levels[i] = a.levels[c];
      let s = rank, count = 0;
      while (s > 0 && this.state(c, s - 1) === 2) --s;
      since[i] = s;
      for (let k = 1; k <= rank; ++k) if (this.state(c, k) !== this.state(c, k - 1) && this.state(c, k - 1) !== 0) ++count;
      changes[i] = count;
    });
    const snap = { level: this.packet.header.level, count: n, rank, bytes: 0, keys, levels, colors, changes, since,
                   occupiedVoxels: this.packet.header.occupied_voxels[rank], cellIds: chosen };
    this.snapshots.set(rank, snap);
    return snap;
  }
  async diff(from, to) {
    const d = this.packet.header.diffs.find((x) => x.from === from && x.to === to);
    if (!d) throw new Error('this tour holds the objects between consecutive sessions and from the first to the last; ' +
                            '`chronomap view` compares any two');
    const a = this.packet.arrays, s = d.first, e = d.first + d.count;
    return { ...d, cells_sent: d.count, keys: a.diff_keys.subarray(3 * s, 3 * e), levels: a.diff_levels.subarray(s, e),
             kinds: a.diff_kinds.subarray(s, e), component: a.diff_component.subarray(s, e), bytes: 0 };
  }
  async history(key, level) {
    const a = this.packet.arrays;
    let cell = -1;
    for (let c = 0; c < this.cells && cell < 0; ++c) {
      if (a.keys[3 * c] === key[0] && a.keys[3 * c + 1] === key[1] && a.keys[3 * c + 2] === key[2] && a.levels[c] === level) cell = c;
    }
    const info = this.packet.header.map;
    const entries = [];
    const names = ['unknown', 'free', 'occupied'];
    for (let s = 0; cell >= 0 && s < this.sessions; ++s) {
      const st = this.state(cell, s);
      if (st === 0 || (s > 0 && st === this.state(cell, s - 1))) continue;
      entries.push({ time_s: info.sessions[s].time_s, time: info.sessions[s].time, session: s, state: names[st],
                     color: st === 2 ? Array.from(a.colors.subarray(3 * cell, 3 * cell + 3)) : [0, 0, 0], level });
    }
    // The centre of the cell in metres, as the server gives a voxel's (historyJson's center_m).
    const centre = key.map((k) => (k - info.key_origin + (1 << level) / 2) * info.resolution_m);
    return { key, level, entries, approximate: level > 0, center_m: cell >= 0 ? centre : undefined };
  }
}
