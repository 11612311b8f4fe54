// Screenshots of the viewer with headless Chromium, for docs/images and for looking at changes:
//   node test/shoot.mjs URL OUT_PREFIX
// writes OUT_PREFIX-map.png (last session), OUT_PREFIX-diff.png (objects between the first two
// sessions), OUT_PREFIX-history.png (coloured by change count, the busiest voxel's history) and
// OUT_PREFIX-top.png (top view, cut at 1.2 m), and prints timings as JSON (software WebGL).
import puppeteer from 'puppeteer-core';

const [url, prefix] = process.argv.slice(2);
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
  const steps = await page.evaluate(async () => {
    const c = window.chronomap, out = [];
    for (let r = 0; r < c.info.sessions.length; ++r) {
      const t = performance.now();
      await c.setSession(r);
      await c.nextFrame();
      out.push(performance.now() - t);
    }
    return out;
  });
  const objects = await page.evaluate(async () => {
    const c = window.chronomap;
    await c.setSession(1);
    const d = await c.showDiff(0, 1);
    return d.components.length;
  });
  await page.evaluate(() => window.chronomap.nextFrame());
  await page.screenshot({ path: `${prefix}-diff.png` });
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
  const memory = await page.evaluate(() => (performance.memory ? performance.memory.usedJSHeapSize : null));
  console.log(JSON.stringify({ first_picture_ms: firstPicture, slider_steps_ms: steps.map(Math.round), objects, zoom,
                               js_heap_bytes: memory }));
} finally {
  await browser.close();
}
