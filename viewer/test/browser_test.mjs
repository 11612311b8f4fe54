// The viewer in a real browser (headless Chromium): the tour file from file:// and the page of
// `chronomap view`, on a small simulated map, checked against the command line's own answers.
//   node test/browser_test.mjs CHRONOMAP WORKDIR
// Exits non-zero with a message on the first difference.
import { execFileSync, spawn } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import { pathToFileURL } from 'node:url';
import puppeteer from 'puppeteer-core';

const [cli, work] = process.argv.slice(2);
fs.mkdirSync(work, { recursive: true });
const run = (...args) => execFileSync(cli, args, { encoding: 'utf8', stdio: ['ignore', 'pipe', 'pipe'] });
const json = (...args) => JSON.parse(run(...args, '--json'));
let failures = 0;
function check(ok, what) {
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${what}`);
  if (!ok) failures += 1;
}

// A map of the tiny simulated room: three sessions.
const map = path.join(work, 'tiny.cmap');
if (!fs.existsSync(map)) {
  run('simulate', '--preset', 'tiny', '-o', path.join(work, 'sim'), '--resolution-scale', '0.25');
  const sessions = fs.readdirSync(path.join(work, 'sim')).filter((n) => n.startsWith('session_')).sort();
  run('build', map, ...sessions.map((s) => path.join(work, 'sim', s)), '--fast');
}
const sessions = json('stats', map).per_session;
// What the command line reports: occupied voxels per session, the objects `chronomap diff` (its
// defaults: the one call) lists between sessions 1 and 2 and between 1 and 3.
const occupied = sessions.map((s, i) => json('snapshot', map, '--at', String(s.time_s), '-o', path.join(work, `snap${i}.cmap`)).occupied);
const cliObjects = (from, to) => json('diff', `${map}@${sessions[from].time_s}`, `${map}@${sessions[to].time_s}`,
                                      '-o', path.join(work, `diff${from}${to}.cmap`)).objects;
const objects = cliObjects(0, 1), objects02 = cliObjects(0, 2);
const brief = (list) => JSON.stringify(list.map((o) => [o.id, o.kind, o.voxels, o.size.map((v) => v.toFixed(3))]));

const tour = path.join(work, 'tour.html');
run('export', map, '-o', tour);

const browser = await puppeteer.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist',
         '--allow-file-access-from-files'],
});

// Share of the canvas's pixels that differ from the background: a blank scene has none.
const coverage = () => {
  const c = document.querySelector('#scene canvas');
  const g = document.createElement('canvas');
  g.width = c.width; g.height = c.height;
  const x = g.getContext('2d');
  x.drawImage(c, 0, 0);
  const d = x.getImageData(0, 0, g.width, g.height).data;
  let n = 0;
  for (let i = 0; i < d.length; i += 4) if (Math.abs(d[i] - 0x14) + Math.abs(d[i + 1] - 0x17) + Math.abs(d[i + 2] - 0x1c) > 24) ++n;
  return n / (d.length / 4);
};

// The picture of the last session from the first view, against viewer/test/reference/LABEL.png
// (written when missing, except under CI=true, or with UPDATE_REFERENCE=1): at most 3% of the pixels may differ by more
// than 48 in a channel (software rendering of the same map, a different machine or browser build).
async function compareWithReference(page, label) {
  await page.evaluate(async (last) => {
    await window.chronomap.setSession(last);
    document.getElementById('reset').click();
    await window.chronomap.nextFrame();
  }, sessions.length - 1);
  const shot = await page.screenshot({ type: 'png' });
  const reference = path.join(path.dirname(new URL(import.meta.url).pathname), 'reference', `${label}.png`);
  if (!fs.existsSync(reference) && process.env.CI === 'true') {
    check(false, `${label}: no reference picture ${reference}`);
    return;
  }
  if (!fs.existsSync(reference) || process.env.UPDATE_REFERENCE === '1') {
    fs.mkdirSync(path.dirname(reference), { recursive: true });
    fs.writeFileSync(reference, shot);
    console.log(`wrote the reference ${reference}`);
    return;
  }
  const differing = await page.evaluate(async (a, b) => {
    const load = (data) => new Promise((resolve, reject) => {
      const img = new Image();
      img.onload = () => resolve(img);
      img.onerror = reject;
      img.src = `data:image/png;base64,${data}`;
    });
    const [x, y] = await Promise.all([load(a), load(b)]);
    if (x.width !== y.width || x.height !== y.height) return 1;
    const pixels = (img) => {
      const c = document.createElement('canvas');
      c.width = img.width; c.height = img.height;
      const g = c.getContext('2d');
      g.drawImage(img, 0, 0);
      return g.getImageData(0, 0, c.width, c.height).data;
    };
    const p = pixels(x), q = pixels(y);
    let n = 0;
    for (let i = 0; i < p.length; i += 4) {
      if (Math.max(Math.abs(p[i] - q[i]), Math.abs(p[i + 1] - q[i + 1]), Math.abs(p[i + 2] - q[i + 2])) > 48) ++n;
    }
    return n / (p.length / 4);
  }, Buffer.from(shot).toString('base64'), fs.readFileSync(reference).toString('base64'));
  fs.writeFileSync(path.join(work, `${label}-last.png`), shot);
  check(differing <= 0.03, `${label}: the last session from the first view differs from the reference in ${(differing * 100).toFixed(2)}% of the pixels`);
}

// The largest difference between the page's probabilities of `shown.picks` and those of
// `chronomap predict` at time_s (its map, added to a 4D map of its own, read back with
// `chronomap history`).
function differenceFromPredict(shown, time_s) {
  const predicted = path.join(work, 'predicted.cmap'), single = path.join(work, 'predicted4d.cmap');
  fs.rmSync(single, { force: true });
  run('predict', map, '--at', String(time_s), '-o', predicted);
  run('add', single, predicted, '--time', String(time_s));
  let worst = 0;
  for (const v of shown.picks) {
    const point = v.key.map((k) => ((k - shown.origin + 0.5) * shown.res).toFixed(4)).join(',');
    const h = json('history', single, '--point', point);
    const cli = h.entries.length ? h.entries[h.entries.length - 1].probability : NaN;
    worst = Math.max(worst, Number.isNaN(cli) ? Infinity : Math.abs(cli - v.p));
  }
  return worst;
}

// The prediction layer at a date and hour of the field rather than a session: two days and a few
// hours after the last session, equal to chronomap predict at that time; more than a week after
// it, the server's refusal is said beside the field.
async function checkPredictionAnyTime(page) {
  const later = new Date(Math.floor(sessions[sessions.length - 1].time_s / 3600 + 2 * 24 + 5) * 3600e3).toISOString().slice(0, 16);
  const tooLate = new Date(Math.floor(sessions[sessions.length - 1].time_s / 3600 + 8 * 24) * 3600e3).toISOString().slice(0, 16);
  const set = async (value) => page.evaluate(async (v) => {
    const c = window.chronomap, field = document.getElementById('predictat');
    if (!field) return null;
    await c.setColorMode('predicted');
    field.value = v;
    field.dispatchEvent(new Event('change'));
    await new Promise((resolve) => setTimeout(resolve, 50));
    while (document.getElementById('busy').style.display !== 'none') await new Promise((resolve) => setTimeout(resolve, 50));
    await c.nextFrame();
    const p = c.prediction, picks = [];
    for (let k = 0; p && k < p.levels.length && picks.length < 6; k += Math.max(1, Math.floor(p.levels.length / 6))) {
      if (p.levels[k] === 0) picks.push({ key: Array.from(p.keys.subarray(3 * k, 3 * k + 3)), p: p.p[k] });
    }
    let coloured = 0;
    for (let i = 0; c.cellP && i < c.shown.count; ++i) if (!Number.isNaN(c.cellP[i])) ++coloured;
    return { time_s: p ? p.time_s : null, picks, coloured, origin: c.info.key_origin, res: c.info.resolution_m,
             legend: document.getElementById('legend').textContent, note: document.getElementById('predictnote').textContent,
             errors: c.errors.length };
  }, value);
  const at = await set(later);
  const expected = Date.parse(`${later}:00Z`) / 1000;
  const worst = at && at.time_s === expected ? differenceFromPredict(at, expected) : Infinity;
  check(at !== null && at.time_s === expected && at.coloured > 0 && worst < 1e-3 && at.legend.includes(later.replace('T', ' ')),
        `server: predicted occupancy at ${later} UTC (2 days past the last session): ${at && at.coloured} cells coloured, largest difference from chronomap predict ${worst}`);
  const refused = await set(tooLate);
  check(refused !== null && /more than a week past/.test(refused.note) && refused.errors === 0,
        `server: ${tooLate} (8 days past) is refused beside the field: '${refused && refused.note}'`);
  await page.evaluate(async () => {
    if (window.chronomap.setPredictionTime) await window.chronomap.setPredictionTime('');
    await window.chronomap.setColorMode('color');
  });
}

// Colour by predicted occupancy at session 2: the page's probabilities of a few modelled voxels
// equal those of `chronomap predict` at that time (its map, added to a 4D map of its own, read
// back with `chronomap history`), and every drawn cell with a model is coloured by one.
async function checkPrediction(page) {
  const rank = 1;
  const shown = await page.evaluate(async (r) => {
    const c = window.chronomap;
    await c.setSession(r);
    await c.setColorMode('predicted');
    await c.nextFrame();
    const p = c.prediction, picks = [];
    // Unit voxels spread over the list, some predicted occupied and some free.
    for (let k = 0; k < p.levels.length && picks.length < 6; k += Math.max(1, Math.floor(p.levels.length / 6))) {
      if (p.levels[k] === 0) picks.push({ key: Array.from(p.keys.subarray(3 * k, 3 * k + 3)), p: p.p[k] });
    }
    let coloured = 0;
    for (let i = 0; i < c.shown.count; ++i) if (!Number.isNaN(c.cellP[i])) ++coloured;
    return { rank: p.rank, cubes: p.levels.length, picks, coloured, origin: c.info.key_origin, res: c.info.resolution_m,
             legend: document.getElementById('legend').textContent };
  }, rank);
  check(shown.rank === rank && shown.cubes > 0 && shown.picks.length >= 3 && shown.coloured > 0 && /predicted/.test(shown.legend),
        `server: predicted occupancy at session ${rank + 1}: ${shown.cubes} modelled cubes, ${shown.coloured} drawn cells coloured by one`);
  const worst = differenceFromPredict(shown, sessions[rank].time_s);
  check(worst < 1e-3, `server: the page's predicted probabilities of ${shown.picks.length} voxels equal chronomap predict's (largest difference ${worst})`);
  // The cost map layer: the server's grid, drawn on the floor, in the legend.
  const cost = await page.evaluate(async () => {
    const c = window.chronomap;
    await c.setCostmap(true);
    await c.nextFrame();
    const m = c.costmap;
    let known = 0;
    for (const v of m.cost) if (v !== 255) ++known;
    return { cells: m.width * m.height, known, rank: m.rank, legend: document.getElementById('legend').textContent };
  });
  check(cost.rank === rank && cost.known > 0 && /navigation cost/.test(cost.legend),
        `server: the cost map layer at session ${rank + 1}: ${cost.known} of ${cost.cells} cells known`);
  await page.screenshot({ path: path.join(work, 'server-predicted.png') });
  await page.evaluate(async () => { await window.chronomap.setCostmap(false); await window.chronomap.setColorMode('color'); });
}

// The "What changed" panel's controls: a new "to" shows its changes at once (the objects of
// chronomap diff --json, the slider at "to"), the button hides and says so, the changed voxels
// obey the height cut, and the labels of objects close together on screen (seen from afar) do
// not overlap (leader lines).
async function checkChangesPanel(page, label) {
  await page.select('#to', '2');
  const shown = await page.waitForFunction(() => {
    const c = window.chronomap;
    return c.diff && c.diff.to === 2 && c.rank === 2 && c.loadedRank === 2 ?
      { objects: c.diff.objects, slider: document.getElementById('time').value } : null;
  }, { timeout: 5000 }).then((h) => h.jsonValue()).catch(() => null);
  check(shown !== null && brief(shown.objects) === brief(objects02) && shown.slider === '2',
        `${label}: choosing 'to' session 3 shows its changes at once: ${shown ? brief(shown.objects) : 'nothing'}; chronomap diff --json lists ${brief(objects02)}`);
  const cut = await page.evaluate(async () => {
    const c = window.chronomap, d = c.diff;
    if (!d) return null;
    const n = d.keys.length / 3, zs = [];
    for (let i = 0; i < n; ++i) zs.push(d.keys[3 * i + 2]);
    zs.sort((a, b) => a - b);
    const r = c.info.resolution_m, o = c.info.key_origin;
    c.setCut((zs[Math.floor(n / 2)] - o) * r);
    await c.nextFrame();
    const b = c.bounds, key = b.zmin + c.cut * (b.zmax - b.zmin);
    const below = zs.filter((z) => z < key).length;
    const result = { total: n, below, drawn: c.diffDrawn };
    c.setCut(100);
    return result;
  });
  check(cut !== null && cut.drawn === cut.below && cut.below > 0 && cut.below < cut.total,
        `${label}: with the height cut through the changes, ${cut && cut.drawn} changed cells drawn; ${cut && cut.below} of ${cut && cut.total} lie below it`);
  const labels = await page.evaluate(async () => {
    const c = window.chronomap;
    // From afar (16 times the map's extent), the objects stand close together on screen.
    await c.showDiff(0, 1);
    const far = 4 * c.extent;
    c.focusOn({ centroid_m: [c.center.x, c.center.y, c.center.z], bbox_min_m: [0, 0, 0], bbox_max_m: [far, far, far] });
    await c.nextFrame();
    await c.nextFrame();
    const rects = [...document.querySelectorAll('#tags .tag')].filter((t) => t.style.display !== 'none')
      .map((t) => t.getBoundingClientRect());
    let overlapping = 0;
    for (let i = 0; i < rects.length; ++i) {
      for (let j = i + 1; j < rects.length; ++j) {
        const a = rects[i], b = rects[j];
        if (a.left < b.right && b.left < a.right && a.top < b.bottom && b.top < a.bottom) ++overlapping;
      }
    }
    // Where each label would stand just above its object: some of those spots overlap.
    const homes = (c.labels || []).map((l) => ({ ...l, x: l.anchor[0] - l.w / 2, y: l.anchor[1] - l.h - 4 }));
    let crowded = 0, away = 0;
    homes.forEach((a, i) => {
      if (Math.hypot(a.x - c.labels[i].x, a.y - c.labels[i].y) > 1) ++away;
      for (const b of homes.slice(i + 1)) if (a.x < b.x + b.w && b.x < a.x + a.w && a.y < b.y + b.h && b.y < a.y + a.h) ++crowded;
    });
    return { shown: rects.length, overlapping, crowded, away, leaders: document.querySelectorAll('#leaders line').length };
  });
  await page.screenshot({ path: path.join(work, `${label}-labels.png`) });
  await page.evaluate(() => document.getElementById('reset').click());
  check(labels.shown === objects.length && labels.crowded > 0 && labels.overlapping === 0 && labels.away > 0 &&
        labels.leaders === labels.away,
        `${label}: seen from afar, ${labels.shown} labels (${labels.crowded} pairs would overlap above their objects): ` +
        `${labels.overlapping} pairs overlap, ${labels.away} moved away with ${labels.leaders} leader lines`);
  const hidden = await page.evaluate(async () => {
    document.getElementById('showdiff').click();
    await window.chronomap.nextFrame();
    return { button: document.getElementById('showdiff').textContent, diff: window.chronomap.diff,
             tags: document.querySelectorAll('#tags .tag').length };
  });
  check(hidden.button === 'Show changes' && hidden.diff === null && hidden.tags === 0,
        `${label}: the button hides the changes and then says '${hidden.button}'`);
}

// A move, as the server lists one (the vanished and the appeared object of sessions 1 to 2 made
// one moved object, answered in place of /api/diff?format=json): drawn as an arrow from the
// old centroid to the new, listed with its distance.
async function checkMove(page) {
  const real = await page.evaluate(async () => (await fetch('api/diff?from=0&to=1&format=json')).json());
  const a = real.objects.find((o) => o.kind === 'appeared'), v = real.objects.find((o) => o.kind === 'vanished');
  const place = (o) => ({ voxels: o.voxels, centroid: o.centroid, size: o.size });
  const move = { ...a, id: 1, kind: 'moved', voxels: a.voxels + v.voxels, components: [v.components[0], a.components[0]],
                 from: place(v), to: place(a), distance_m: Math.hypot(...a.centroid.map((x, k) => x - v.centroid[k])) };
  const rest = real.objects.filter((o) => o !== a && o !== v).map((o, k) => ({ ...o, id: k + 2 }));
  const answer = JSON.stringify({ ...real, objects: [move, ...rest] });
  await page.setRequestInterception(true);
  const respond = (r) => (/api\/diff\?from=0&to=1&format=json$/.test(r.url()) ?
    r.respond({ status: 200, contentType: 'application/json', body: answer }) : r.continue());
  page.on('request', respond);
  const drawn = await page.evaluate(async () => {
    const c = window.chronomap;
    await c.showDiff(0, 1);
    await c.nextFrame();
    return { arrows: (c.arrows || []).map((x) => ({ id: x.id, tail: x.tail, tip: x.tip })),
             row: document.querySelector('#objects .obj') ? document.querySelector('#objects .obj').textContent : '' };
  });
  page.off('request', respond);
  await page.setRequestInterception(false);
  await page.screenshot({ path: path.join(work, 'server-move.png') });
  await page.evaluate(() => window.chronomap.clearDiff());
  const near = (p, q) => p && q && Math.hypot(...p.map((x, k) => x - q[k])) < 1e-4;
  // One arrow per move: the one made here (id 1) and any the server's list held already.
  const arrow = drawn.arrows.find((x) => x.id === 1);
  const moves = 1 + rest.filter((o) => o.kind === 'moved').length;
  check(drawn.arrows.length === moves && arrow && near(arrow.tail, v.centroid) && near(arrow.tip, a.centroid) &&
        drawn.row.includes(`moved ${move.distance_m.toFixed(2)} m`),
        `server: a moved object is drawn as an arrow from ${JSON.stringify(v.centroid)} to ${JSON.stringify(a.centroid)}: ${JSON.stringify(drawn.arrows)}; listed as '${drawn.row}'`);
}

// The history panel gives the voxel's position in metres (the centre of the selected cell).
async function checkHistoryPosition(page, label) {
  const h = await page.evaluate(async () => {
    const c = window.chronomap, s = c.shown;
    let i = 0;
    while (i < s.count && s.levels[i] !== 0) ++i;
    await c.selectCell(i);
    const r = c.info.resolution_m, o = c.info.key_origin;
    return { expected: [0, 1, 2].map((a) => (s.keys[3 * i + a] - o + 0.5) * r),
             text: document.getElementById('histsub').textContent };
  });
  const m = h.text.match(/at (-?[\d.]+), (-?[\d.]+), (-?[\d.]+) m/);
  const said = m ? m.slice(1).map(Number) : null;
  check(said !== null && said.every((v, a) => Math.abs(v - h.expected[a]) < 0.0051),
        `${label}: the history panel says where the voxel is: '${h.text}' (its centre: ${h.expected.map((v) => v.toFixed(3)).join(', ')} m)`);
}

async function checkPage(url, label) {
  const page = await browser.newPage();
  await page.setViewport({ width: 900, height: 600 });
  const errors = [];
  page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
  page.on('pageerror', (e) => errors.push(e.message));
  page.on('requestfailed', (r) => errors.push(`request failed: ${r.url()}`));
  await page.goto(url);
  await page.waitForFunction('window.chronomap && (window.chronomap.ready || window.chronomap.errors.length)', { timeout: 60000 });
  for (let r = 0; r < sessions.length; ++r) {
    const drawn = await page.evaluate(async (rank) => {
      await window.chronomap.setSession(rank);
      await window.chronomap.nextFrame();
      return { count: window.chronomap.snap.count, drawn: window.chronomap.drawn, level: window.chronomap.snap.level };
    }, r);
    check(drawn.level === 0 && drawn.drawn === occupied[r],
          `${label}: session ${r + 1} draws ${drawn.drawn} voxels (level ${drawn.level}); chronomap snapshot reports ${occupied[r]} occupied`);
    const covered = await page.evaluate(coverage);
    check(covered > 0.03, `${label}: session ${r + 1}: ${(covered * 100).toFixed(1)}% of the picture is not background`);
  }
  await compareWithReference(page, label);
  const diff = await page.evaluate(async () => {
    const d = await window.chronomap.showDiff(0, 1);
    await window.chronomap.nextFrame();
    return { objects: d.objects || [], rows: document.querySelectorAll('#objects .obj').length,
             tags: document.querySelectorAll('#tags .tag').length, button: document.getElementById('showdiff').textContent,
             rank: window.chronomap.rank, slider: document.getElementById('time').value };
  });
  check(brief(diff.objects) === brief(objects),
        `${label}: the changes of sessions 1 to 2 list ${brief(diff.objects)}; chronomap diff --json lists ${brief(objects)}`);
  check(diff.rows === objects.length && diff.tags === objects.length, `${label}: each object listed (${diff.rows}) and numbered (${diff.tags})`);
  check(diff.button === 'Hide changes' && diff.rank === 1 && diff.slider === '1',
        `${label}: with the changes shown the button says '${diff.button}' and the slider is at session ${diff.rank + 1} (the 'to' session is 2)`);
  await page.screenshot({ path: path.join(work, `${label}-diff.png`) });
  await checkChangesPanel(page, label);
  const history = await page.evaluate(async () => {
    const c = window.chronomap;
    c.clearDiff();
    let busiest = 0;
    for (let i = 0; i < c.shown.count; ++i) if (c.shown.changes[i] > c.shown.changes[busiest]) busiest = i;
    const h = await c.selectCell(busiest);
    return { entries: h.entries.length, shown: getComputedStyle(document.getElementById('history')).display !== 'none',
             rows: document.querySelectorAll('#histtable tr').length };
  });
  check(history.entries >= 2 && history.shown && history.rows === history.entries,
        `${label}: selecting the busiest voxel shows its history (${history.entries} entries, ${history.rows} rows)`);
  await checkHistoryPosition(page, label);
  // Real clicks on the canvas (points of the first view, until one lands on a voxel rather than a
  // hole in the floor) pick a voxel and show its history.
  await page.evaluate(async () => {
    window.chronomap.selected = null;
    document.getElementById('reset').click();
    await window.chronomap.nextFrame();
  });
  let clicked = null;
  for (const [x, y] of [[450, 330], [600, 450], [330, 450], [450, 250], [700, 300], [250, 300]]) {
    await page.mouse.click(x, y);
    clicked = await page.waitForFunction(() => {
      const c = window.chronomap;
      return c.selected && c.history && c.history.key.join() === c.selected.key.join() &&
        document.querySelectorAll('#histtable tr').length >= 1 ? c.selected.key.join() : null;
    }, { timeout: 3000 }).then((h) => h.jsonValue()).catch(() => null);
    if (clicked) break;
  }
  check(clicked !== null, `${label}: a click on the canvas picks voxel ${clicked} and shows its history`);
  if (label === 'server') {
    await checkPrediction(page);
    await checkPredictionAnyTime(page);
    await checkMove(page);
  }
  check(errors.length === 0, `${label}: no console errors${errors.length ? `: ${errors.join(' | ')}` : ''}`);
  await page.close();
}

let server = null;
try {
  await checkPage(pathToFileURL(tour).href, 'tour');
  server = spawn(cli, ['view', map, '--port', '0'], { stdio: ['ignore', 'pipe', 'inherit'] });
  const url = await new Promise((resolve, reject) => {
    let out = '';
    server.stdout.on('data', (d) => { out += d; const m = out.match(/http:\/\/127\.0\.0\.1:\d+\//); if (m) resolve(m[0]); });
    server.on('exit', () => reject(new Error(`chronomap view exited: ${out}`)));
  });
  await checkPage(url, 'server');
} finally {
  if (server) server.kill();
  await browser.close();
}
console.log(failures ? `${failures} check(s) failed` : 'every check passed');
process.exit(failures ? 1 : 0);
