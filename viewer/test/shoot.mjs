// Screenshots of the viewer with headless Chromium, for docs/images and for looking at changes:
//   node test/shoot.mjs URL OUT_PREFIX
// writes OUT_PREFIX-map.png (last session), OUT_PREFIX-diff.png (objects between the first two
// sessions), OUT_PREFIX-move.png (the first moved object between consecutive sessions, if any), OUT_PREFIX-history.png (coloured by change count, the busiest voxel's history) and
// OUT_PREFIX-top.png (top view, cut at 1.2 m), OUT_PREFIX-zoom.png (a coarse map zoomed in),
// OUT_PREFIX-predicted.png (predicted occupancy and the cost map a day and a half past the last
// session, `chronomap view` only), and prints timings as JSON (software WebGL): a
// slider step's wall time split into fetch, building the mesh and drawing, and the processor
// time Chromium spent per step (all its processes).
import fs from 'node:fs';
import puppeteer from 'puppeteer-core';

const [url, prefix] = process.argv.slice(2);

// Processor seconds (user + system) used so far by a process and its descendants: the work of a
// step, which unlike its wall time does not depend on what else the machine runs.
function cpuSeconds(root) {
  const procs = new Map();
  for (const d of fs.readdirSync('/proc')) {
    if (!/^\d+$/.test(d)) continue;
    try {
      const f = fs.readFileSync(`/proc/${d}/stat`, 'utf8').split(') ')[1].split(' ');
      procs.set(Number(d), { ppid: Number(f[1]), ticks: Number(f[11]) + Number(f[12]) });
    } catch (e) { /* gone */ }
  }
  const inTree = (pid) => { for (let p = pid; p > 1; p = procs.get(p)?.ppid ?? 0) if (p === root) return true; return false; };
  let ticks = 0;
  for (const [pid, p] of procs) if (inTree(pid)) ticks += p.ticks;
  return ticks / 100;
}
const browser = await puppeteer.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist'],
});
try {
  const page = await browser.newPage();
  await page.setViewport({ width: 1400, height: 860 });
  page.on('console', (m) => { if (m.type() === 'error') console.error('console:', m.text()); });
  page.on('pageerror', (e) => console.error('page error:', e.message));
  const t0 = Date.now();
  await page.goto(url);
  await page.waitForFunction('window.chronomap && window.chronomap.ready', { timeout: 120000 });
  const firstPicture = Date.now() - t0;
  await page.evaluate(() => window.chronomap.nextFrame());
  await page.screenshot({ path: `${prefix}-map.png` });
  const cpu0 = cpuSeconds(browser.process().pid);
  const steps = await page.evaluate(async () => {
    const c = window.chronomap, out = [];
    // Reading a pixel back waits until the frames asked for are drawn (rendering is asynchronous).
    const gl = document.querySelector('#scene canvas').getContext('webgl2');
    const finish = () => gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4));
    // Twice through the sessions: the second pass finds the buffers grown and the neighbours fetched.
    for (let r = 0; r < 2 * c.info.sessions.length; ++r) {
      const t = performance.now();
      await c.setSession(r % c.info.sessions.length);
      const built = performance.now();
      await c.nextFrame();
      finish();
      const end = performance.now();
      out.push({ total: end - t, fetch: c.lastLoadMs, build: c.lastBuildMs, draw: end - built });
    }
    return out;
  });
  const stepCpuMs = (1000 * (cpuSeconds(browser.process().pid) - cpu0)) / steps.length;
  const objects = await page.evaluate(async () => {
    const c = window.chronomap;
    await c.setSession(1);
    const d = await c.showDiff(0, 1);
    return d.objects.length;
  });
  await page.evaluate(() => window.chronomap.nextFrame());
  await page.screenshot({ path: `${prefix}-diff.png` });
  // The first pair of consecutive sessions with a moved object, flown to.
  const moved = await page.evaluate(async () => {
    const c = window.chronomap;
    for (let r = 0; r + 1 < c.info.sessions.length; ++r) {
      const d = await c.showDiff(r, r + 1);
      const m = d.objects.find((o) => o.kind === 'moved');
      if (!m) continue;
      c.focusOn({ ...m, bbox_min: m.bbox_min.map((v, k) => Math.min(v, m.from.centroid[k] - m.from.size[k] / 2)),
                  bbox_max: m.bbox_max.map((v, k) => Math.max(v, m.from.centroid[k] + m.from.size[k] / 2)) });
      await c.nextFrame();
      return { from: r, to: r + 1, id: m.id, distance_m: m.distance_m };
    }
    return null;
  });
  if (moved) await page.screenshot({ path: `${prefix}-move.png` });
  await page.evaluate(() => document.getElementById('reset').click());
  await page.evaluate(async () => {
    const c = window.chronomap;
    c.clearDiff();
    await c.setSession(c.info.sessions.length - 1);
    c.setColorMode('changes');
    let best = 0;
    for (let i = 0; i < c.shown.count; ++i) if (c.shown.changes[i] > c.shown.changes[best]) best = i;
    await c.selectCell(best);
    await c.nextFrame();
  });
  await page.screenshot({ path: `${prefix}-history.png` });
  await page.evaluate(async () => {
    const c = window.chronomap;
    document.getElementById('history').style.display = 'none';
    c.setColorMode('color');
    c.setCut(1.2);
    c.toggleTopView();
    await c.nextFrame();
  });
  await page.screenshot({ path: `${prefix}-top.png` });
  // A map drawn in coarse cubes: fly close to its middle and let the page ask for finer cells.
  const zoom = await page.evaluate(async () => {
    const c = window.chronomap;
    if (!c.snap.level) return null;
    c.toggleTopView();
    c.setCut(2.5);
    c.focusOn({ centroid_m: [c.center.x, c.center.y, c.center.z], bbox_min_m: [0, 0, 0], bbox_max_m: [1.5, 1.5, 1.5] });
    const t = performance.now();
    await c.refine();
    await c.nextFrame();
    return { ms: performance.now() - t, cells: c.shown.detailCells, level: c.shown.detailLevel };
  });
  if (zoom) await page.screenshot({ path: `${prefix}-zoom.png` });
  // Colouring by predicted occupancy (the first request fits the models on the server) and the
  // cost map layer, where the server has them.
  const rhythm = await page.evaluate(async () => {
    const c = window.chronomap;
    if (!c.source.predicts || !c.setCostmap) return null;
    if (c.topView) c.toggleTopView();
    c.setCut(100);
    document.getElementById('reset').click();
    let t = performance.now();
    await c.setColorMode('predicted');
    await c.nextFrame();
    const first = performance.now() - t;
    const steps = [];
    for (let r = 0; r < Math.min(6, c.info.sessions.length); ++r) {
      t = performance.now();
      await c.setSession(r);
      await c.nextFrame();
      steps.push(Math.round(performance.now() - t));
    }
    // A day and a half past the last session, from the date and hour field.
    const last = c.info.sessions[c.info.sessions.length - 1].time_s;
    const later = new Date(Math.floor(last / 3600 + 36) * 3600e3).toISOString().slice(0, 16);
    const field = document.getElementById('predictat');
    field.value = later;
    field.dispatchEvent(new Event('change'));
    await new Promise((resolve) => setTimeout(resolve, 50));
    while (document.getElementById('busy').style.display !== 'none') await new Promise((resolve) => setTimeout(resolve, 50));
    t = performance.now();
    await c.setCostmap(true);
    await c.nextFrame();
    return { first_ms: Math.round(first), fit_s: c.prediction.fit_s, cubes: c.prediction.levels.length,
             prediction_bytes: c.prediction.bytes, steps_ms: steps, costmap_ms: Math.round(performance.now() - t),
             costmap_bytes: c.costmap.bytes };
  });
  if (rhythm) await page.screenshot({ path: `${prefix}-predicted.png` });
  const memory = await page.evaluate(() => (performance.memory ? performance.memory.usedJSHeapSize : null));
  console.log(JSON.stringify({ first_picture_ms: firstPicture, slider_steps_ms: steps.map((x) => Math.round(x.total)),
                               step_parts_ms: steps.map((x) => [x.fetch, x.build, x.draw].map(Math.round)),
                               step_cpu_ms: Math.round(stepCpuMs), objects, moved, zoom, rhythm,
                               js_heap_bytes: memory }));
} finally {
  await browser.close();
}
