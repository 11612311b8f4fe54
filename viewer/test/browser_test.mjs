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
// What the command line reports: occupied voxels per session, objects between sessions 1 and 2.
const occupied = sessions.map((s, i) => json('snapshot', map, '--at', String(s.time_s), '-o', path.join(work, `snap${i}.cmap`)).occupied);
const diffFile = path.join(work, 'diff01.cmap');
run('diff', `${map}@${sessions[0].time_s}`, `${map}@${sessions[1].time_s}`, '--mode', 'band', '--neighbourhood', '1',
    '--min-shift', '0.5', '--kept-surface', '3', '-o', diffFile);
const objects = json('segment', diffFile, '--connectivity', 'vertex', '--min-voxels', '20').components;

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
  const predicted = path.join(work, 'predicted.cmap'), single = path.join(work, 'predicted4d.cmap');
  fs.rmSync(single, { force: true });
  run('predict', map, '--at', String(sessions[rank].time_s), '-o', predicted);
  run('add', single, predicted, '--time', String(sessions[rank].time_s));
  let worst = 0;
  for (const v of shown.picks) {
    const point = v.key.map((k) => ((k - shown.origin + 0.5) * shown.res).toFixed(4)).join(',');
    const h = json('history', single, '--point', point);
    const cli = h.entries.length ? h.entries[h.entries.length - 1].probability : NaN;
    worst = Math.max(worst, Number.isNaN(cli) ? Infinity : Math.abs(cli - v.p));
  }
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
    return { components: d.components.map((c) => [c.kind, c.voxels]), rows: document.querySelectorAll('#objects .obj').length,
             tags: document.querySelectorAll('#tags .tag').length };
  });
  const expected = objects.map((c) => [c.kind, c.voxels]);
  check(JSON.stringify(diff.components) === JSON.stringify(expected),
        `${label}: the diff of sessions 1 and 2 shows ${diff.components.length} objects ${JSON.stringify(diff.components)}; chronomap segment reports ${JSON.stringify(expected)}`);
  check(diff.rows === expected.length && diff.tags === expected.length, `${label}: each object listed (${diff.rows}) and numbered (${diff.tags})`);
  await page.screenshot({ path: path.join(work, `${label}-diff.png`) });
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
  if (label === 'server') await checkPrediction(page);
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
