// Headless-Chromium test of a page written by `sonar3d report`:
//   node web/test_report.mjs REPORT.html [--screenshot PAGE.png] [--chromium /usr/bin/chromium]
// Opens the page from file://, blocks and records every request that is not file:, data: or
// blob:, and checks: no console error, no page error, no network request; the six metric plots
// drew traces; the 3D canvas is not blank and changes with the colour mode; the selector shows
// another configuration; clicking a table header sorts the rows (and again reverses them).
// Exits 0 when every check passed, 1 otherwise (each failure on its own line).
// Every x axis the selector offers is tried: numeric axes must plot on a linear axis at their
// values, string/boolean axes as categories, mixed axes (numbers plus levels such as null =
// "none") with the numbers to scale and the levels as extra ticks beyond one end.
// Run by tests/test_report.cpp (BrowserTest) after it writes a fixture report.
// --expect EXPECT.json: the page is a scene page (map, world, changes, PLY; scene.js) and
// EXPECT.json says what it must draw: {"kind", "layers": [{"id", "type", "count", "visible"}]
// (exactly these, in this order), "tables": {id: rows}, "groups": {name: [layer ids]} (one shown
// at a time), "colors": [{"layer", "index", "rgb": [r, g, b]} or {..., "hue": "red"|"blue"|
// "white"}], "mode_change": whether another point colouring repaints the canvas, "focus":
// {"table", "layer"}: clicking the table's first row brings that layer into view, "figures":
// [id]: an SVG picture drawn under #figure-<id> with its north arrow and scale bar}.
import { chromium } from 'playwright-core';
import { PNG } from 'pngjs';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { pathToFileURL } from 'node:url';

const args = process.argv.slice(2);
const opt = (name, dflt) => {
  const i = args.indexOf(name);
  if (i < 0) return dflt;
  const v = args[i + 1];
  args.splice(i, 2);
  return v;
};
const screenshotPath = opt('--screenshot', null);
// --mixed-axis NAME: NAME mixes numbers and other levels (e.g. snr_db: [none, 30, 20]); it must be
// offered as x axis and plotted to scale with its levels apart. --all-failed: no configuration
// finished; the page must say so instead of drawing plots.
const mixedAxes = [];
for (let m; (m = opt('--mixed-axis', null)) !== null;) mixedAxes.push(m);
const expectPath = opt('--expect', null);
const allFailed = args.includes('--all-failed');
if (allFailed) args.splice(args.indexOf('--all-failed'), 1);
const chromiumPath = opt('--chromium', process.env.SONAR3D_CHROMIUM || '/usr/bin/chromium');
const reportPath = args[0];
if (!reportPath || !fs.existsSync(reportPath)) {
  console.error(`usage: node test_report.mjs REPORT.html [--screenshot OUT.png]` +
    (reportPath ? ` (no such file: ${reportPath})` : ''));
  process.exit(2);
}
if (!fs.existsSync(chromiumPath)) {
  console.error(`test_report.mjs: Chromium not found at ${chromiumPath}: install Debian's ` +
    'chromium (scripts/install-deps.sh) or set SONAR3D_CHROMIUM');
  process.exit(2);
}

const failures = [];
let passed = 0;
function check(cond, what) {
  if (cond) { passed++; console.log(`  ok    ${what}`); } else {
    failures.push(what); console.log(`  FAIL  ${what}`);
  }
}

// Mean and variance of the luminance, and the number of distinct colours, of a PNG buffer.
function pixelStats(buf) {
  const png = PNG.sync.read(buf);
  const n = png.width * png.height;
  let sum = 0, sum2 = 0;
  const colours = new Set();
  for (let i = 0; i < n; i++) {
    const r = png.data[4 * i], g = png.data[4 * i + 1], b = png.data[4 * i + 2];
    const y = 0.2126 * r + 0.7152 * g + 0.0722 * b;
    sum += y; sum2 += y * y;
    if (colours.size < 5000) colours.add((r << 16) | (g << 8) | b);
  }
  const mean = sum / n;
  return { mean, variance: sum2 / n - mean * mean, colours: colours.size, png };
}
function differingPixels(a, b) {
  if (a.width !== b.width || a.height !== b.height) return Infinity;
  let d = 0;
  for (let i = 0; i < a.data.length; i += 4) {
    if (Math.abs(a.data[i] - b.data[i]) + Math.abs(a.data[i + 1] - b.data[i + 1]) +
        Math.abs(a.data[i + 2] - b.data[i + 2]) > 30) d++;
  }
  return d;
}

const userDataDir = fs.mkdtempSync(path.join(os.tmpdir(), 'sonar3d-chromium-'));
let context;
try {
  // The launch flags known to work on this workplace's machines (no GPU, closed network).
  context = await chromium.launchPersistentContext(userDataDir, {
    executablePath: chromiumPath,
    headless: true,
    viewport: { width: 1440, height: 1000 },
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
      '--disable-background-networking', '--disable-component-update', '--disable-sync',
      // WebGL on the CPU (SwiftShader), since there is no GPU.
      '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
  });
  const external = [];
  await context.route('**/*', (route) => {
    const url = route.request().url();
    if (/^(file|data|blob):/.test(url)) return route.continue();
    external.push(url);
    return route.abort();
  });
  const page = context.pages()[0] || await context.newPage();
  const consoleErrors = [];
  const pageErrors = [];
  page.on('console', (m) => { if (m.type() === 'error') consoleErrors.push(m.text()); });
  page.on('pageerror', (e) => pageErrors.push(String(e)));

  const url = pathToFileURL(path.resolve(reportPath)).href;
  const t0 = Date.now();
  await page.goto(url, { waitUntil: 'load', timeout: 60000 });
  await page.waitForFunction(() => window.sonar3dReport && window.sonar3dReport.ready,
    null, { timeout: 60000 }).catch(() => {});
  const loadMs = Date.now() - t0;
  check(await page.evaluate(() => !!(window.sonar3dReport && window.sonar3dReport.ready)),
    `page reports ready (${loadMs} ms)`);

  const data = await page.evaluate(() => JSON.parse(
    document.getElementById('sonar3d-data').textContent));
  if (expectPath) {
    await checkScene(page, JSON.parse(fs.readFileSync(expectPath, 'utf8')));
  } else {
    const points = data.results.points;
    if (allFailed) {
      await checkAllFailed(page, points);
    } else {
      await checkPlots(page, data);
      await checkViewer(page);
    }
    await checkTable(page, points);
  }

  check(external.length === 0, `no network request (${external.slice(0, 3).join(', ')})`);
  check(pageErrors.length === 0, `no page error ${pageErrors.slice(0, 3).join(' | ')}`);
  check(consoleErrors.length === 0, `no console error ${consoleErrors.slice(0, 3).join(' | ')}`);

  if (screenshotPath) {
    await page.evaluate(() => window.scrollTo(0, 0));
    await page.waitForTimeout(200);
    await page.screenshot({ path: screenshotPath, fullPage: true });
    console.log(`  screenshot: ${screenshotPath}`);
  }
} catch (e) {
  failures.push(`exception: ${e && e.stack ? e.stack : e}`);
  console.log(`  FAIL  exception: ${e && e.stack ? e.stack : e}`);
} finally {
  if (context) await context.close().catch(() => {});
  fs.rmSync(userDataDir, { recursive: true, force: true });
}
console.log(`test_report.mjs: ${passed} checks passed, ${failures.length} failed`);
process.exit(failures.length ? 1 : 0);

async function checkAllFailed(page, points) {
  check(points.length > 0 && points.every((p) => p.status !== 'ok'),
    `fixture: no configuration is ok (${points.length} points)`);
  const msg = await page.$eval('#plots-empty', (e) => e.textContent).catch(() => '');
  const failed = points.filter((p) => p.status === 'failed').length;
  check(/No configuration finished/.test(msg) && msg.includes(`${failed} of ${points.length}`),
    `the plots section says no configuration finished: "${msg}"`);
  const plots = await page.$$eval('#plots .plot', (d) => d.length);
  check(plots === 0, `no empty plot frames (${plots})`);
  const viewerMsg = await page.$eval('#viewer .message', (e) => e.textContent).catch(() => '');
  check(/No reconstructed cloud/.test(viewerMsg), `the viewer says there is no cloud`);
}

// What the test expects of axis a, computed from the data independently of the page.
function expectedKind(values) {
  const isNum = (v) => typeof v === 'number' && isFinite(v);
  if (values.every(isNum)) return 'numeric';
  return new Set(values.filter(isNum)).size >= 2 ? 'mixed' : 'category';
}

async function checkPlots(page, data) {
  // Plots: six Plotly graphs, each with an SVG and at least one line trace.
  const plots = await page.evaluate(() => Array.from(document.querySelectorAll('#plots .plot'))
    .map((d) => ({ id: d.id, svg: d.querySelectorAll('.main-svg').length,
      traces: d.querySelectorAll('.scatterlayer .trace').length,
      points: d.querySelectorAll('.scatterlayer .point').length })));
  check(plots.length === 6, `6 metric plots (found ${plots.length})`);
  check(plots.length > 0 && plots.every((p) => p.svg > 0 && p.traces > 0 && p.points > 0),
    'every plot rendered traces with markers: ' +
    plots.map((p) => `${p.id.replace('plot-', '')}=${p.traces}`).join(' '));
  const axisTitles = await page.evaluate(() => Array.from(
    document.querySelectorAll('#plot-median_error_m .g-xtitle, #plot-median_error_m .g-ytitle'))
    .map((e) => e.textContent));
  check(axisTitles.length === 2 && axisTitles.every((t) => /\[.+\]/.test(t)),
    `axis titles carry units: ${JSON.stringify(axisTitles)}`);

  // Changing the x axis and the series redraws without errors.
  const xOptions = await page.$$eval('#plot-x option', (os) => os.map((o) => o.value));
  const seriesBefore = await page.evaluate(() => window.sonar3dReport.lastTraces);
  if (xOptions.length > 1) {
    const cur = await page.$eval('#plot-x', (s) => s.value);
    await page.selectOption('#plot-x', xOptions.find((v) => v !== cur));
    await page.waitForTimeout(300);
    const traces = await page.$$eval('#plot-coverage .scatterlayer .trace', (t) => t.length);
    check(traces > 0, `plots redraw after choosing another x axis (${traces} traces)`);
    await page.selectOption('#plot-x', cur);
  }
  await page.selectOption('#plot-series', '');
  await page.waitForTimeout(200);
  const oneLine = await page.evaluate(() => window.sonar3dReport.lastTraces);
  check(oneLine === 1 && seriesBefore >= 1,
    `"one line" shows a single trace (${oneLine}; ${seriesBefore} by series before)`);
  const seriesOptions = await page.$$eval('#plot-series option', (os) => os.map((o) => o.value));
  if (seriesOptions.length > 1) await page.selectOption('#plot-series', seriesOptions[1]);

  await checkAxes(page, data);
}

// Values of axis a in sweep order, then any value seen only in the points (as the page does).
function axisValues(axes, points, a) {
  const vals = (axes[a] || []).slice();
  const seen = new Set(vals.map((v) => JSON.stringify(v)));
  for (const p of points) {
    const v = (p.params || {})[a] === undefined ? null : p.params[a];
    if (!seen.has(JSON.stringify(v))) { seen.add(JSON.stringify(v)); vals.push(v); }
  }
  return vals;
}

// Chooses each offered x axis in turn (one line) and checks the coverage plot against the data:
// the axis type, one marker per value that has an ok configuration, at the right place.
async function checkAxes(page, data) {
  const axes = data.results.axes || {};
  const points = data.results.points;
  const offered = await page.$$eval('#plot-x option', (os) => os.map((o) => o.value));
  for (const m of mixedAxes) {
    check(offered.includes(m), `the x axis selector offers ${m} (${offered.join(', ')})`);
  }
  const xBefore = await page.$eval('#plot-x', (s) => s.value);
  const seriesBefore = await page.$eval('#plot-series', (s) => s.value);
  const isNum = (v) => typeof v === 'number' && isFinite(v);
  for (const a of offered) {
    const values = axisValues(axes, points, a);
    const kind = expectedKind(values);
    if (mixedAxes.includes(a)) {
      check(kind === 'mixed', `fixture: ${a} mixes numbers and other levels`);
    }
    const withData = [];
    for (const p of points) {
      const v = (p.params || {})[a] === undefined ? null : p.params[a];
      const cov = (p.metrics || {}).coverage;
      if (p.status === 'ok' && isNum(cov) && !withData.some((w) => JSON.stringify(w) ===
        JSON.stringify(v))) withData.push(v);
    }
    await page.selectOption('#plot-x', a);
    await page.selectOption('#plot-series', '');
    await page.waitForTimeout(150);
    const got = await page.evaluate(() => {
      const d = document.getElementById('plot-coverage');
      const xa = d.layout.xaxis;
      return { type: xa.type, ticktext: xa.ticktext || null, tickvals: xa.tickvals || null,
        categoryarray: xa.categoryarray || null, kind: window.sonar3dReport.xKind,
        traces: d.data.map((t) => ({ x: t.x, y: t.y, symbol: (t.marker || {}).symbol })),
        markers: d.querySelectorAll('.scatterlayer .point').length };
    });
    const xs = got.traces.length === 1 ? got.traces[0].x : [];
    const drawn = xs.filter((v) => v !== null && v !== undefined);
    const what = `x = ${a} (${kind}, ${withData.length} values with data)`;
    check(got.kind === kind && got.traces.length === 1 && drawn.length === withData.length &&
      got.markers === withData.length,
    `${what}: one marker per value (${drawn.length} points, ${got.markers} markers drawn)`);
    if (kind === 'category') {
      check(got.type === 'category' && got.categoryarray &&
        got.categoryarray.length === values.length &&
        drawn.every((v) => got.categoryarray.includes(v)) &&
        values.filter((v) => typeof v === 'string').every((v) => got.categoryarray.includes(v)) &&
        values.filter((v) => typeof v === 'boolean').every((v) =>
          got.categoryarray.includes(String(v))),
      `${what}: category axis in sweep order ${JSON.stringify(got.categoryarray)}`);
      continue;
    }
    const nums = withData.filter(isNum).sort((u, w) => u - w);
    const sym = (i) => (Array.isArray(got.traces[0].symbol) ? got.traces[0].symbol[i] : 'circle');
    const drawnNums = xs.filter((v, i) => isNum(v) && sym(i) !== 'diamond')
      .sort((u, w) => u - w);
    check(got.type === 'linear' && JSON.stringify(drawnNums) === JSON.stringify(nums),
      `${what}: numbers plotted to scale at ${JSON.stringify(drawnNums)}`);
    if (kind !== 'mixed') continue;
    // The levels: each one with data is a diamond beyond the numbers' range, at a tick that
    // carries its label ("none" for null).
    const allNums = values.filter(isNum);
    const lo = Math.min(...allNums), hi = Math.max(...allNums);
    const levels = values.filter((v) => !isNum(v));
    const labels = levels.map((v) => (v === null ? 'none' : String(v)));
    check(labels.every((l) => (got.ticktext || []).includes(l)),
      `${what}: tick labels include ${JSON.stringify(labels)} (${JSON.stringify(got.ticktext)})`);
    const diamonds = xs.map((v, i) => ({ v, s: sym(i) }))
      .filter((q) => q.s === 'diamond' && q.v !== null);
    const levelsWithData = withData.filter((v) => !isNum(v)).length;
    check(diamonds.length === levelsWithData && diamonds.every((q) => q.v > hi || q.v < lo) &&
      diamonds.every((q) => {
        const t = got.tickvals.indexOf(q.v);
        return t >= 0 && labels.includes(got.ticktext[t]);
      }),
    `${what}: ${diamonds.length} level marker(s) apart from the numbers, at their labelled tick`);
  }
  await page.selectOption('#plot-x', xBefore);
  await page.selectOption('#plot-series', seriesBefore);
  await page.waitForTimeout(150);
}

async function checkViewer(page) {
  // 3D viewer: a canvas whose pixels vary (cloud + model drawn on the background).
  await page.waitForTimeout(300);
  const canvas = await page.$('#viewer canvas');
  check(!!canvas, '3D viewer has a canvas');
  let errorShot = null;
  if (canvas) {
    await canvas.scrollIntoViewIfNeeded();
    const box = await canvas.boundingBox();
    check(box && box.width > 300 && box.height > 300,
      `canvas is large (${box && Math.round(box.width)}x${box && Math.round(box.height)})`);
    errorShot = pixelStats(await page.screenshot({ clip: box }));
    check(errorShot.variance > 50 && errorShot.colours > 50,
      `canvas is not blank (luminance variance ${errorShot.variance.toFixed(0)}, ` +
      `${errorShot.colours} colours)`);
    const mode = await page.evaluate(() => window.sonar3dReport.colorMode);
    check(mode === 'error', `cloud coloured by error by default (${mode})`);
    await page.selectOption('#viewer-color', 'height');
    await page.waitForTimeout(200);
    const heightShot = pixelStats(await page.screenshot({ clip: box }));
    const diff = differingPixels(errorShot.png, heightShot.png);
    check(diff > 500, `colour by height repaints the cloud (${diff} pixels changed)`);
    await page.selectOption('#viewer-color', 'error');
    const ids = await page.$$eval('#viewer-point option', (os) => os.map((o) => o.value));
    if (ids.length > 1) {
      await page.selectOption('#viewer-point', ids[ids.length - 1]);
      await page.waitForTimeout(200);
      const shown = await page.evaluate(() => window.sonar3dReport.shownPoint);
      check(shown === ids[ids.length - 1], `viewer shows the chosen configuration (${shown})`);
      await page.selectOption('#viewer-point', ids[0]);
    }
  }
}

async function checkTable(page, points) {
  // Table: one row per configuration, failed rows with their message, sortable headers.
  const rows = await page.$$eval('#results-table tbody tr', (r) => r.length);
  const expected = await page.evaluate(() => JSON.parse(
    document.getElementById('sonar3d-data').textContent).results.points.length);
  check(rows === expected, `table has one row per configuration (${rows}/${expected})`);
  const failedMsgs = await page.$$eval('#results-table tr.row-failed td[data-col="message-span"]',
    (t) => t.map((e) => e.textContent));
  const expectedFailed = await page.evaluate(() => JSON.parse(
    document.getElementById('sonar3d-data').textContent).results.points
    .filter((p) => p.status === 'failed').length);
  check(failedMsgs.length === expectedFailed && failedMsgs.every((m) => m.length > 0),
    `failed configurations shown with their message (${failedMsgs.length})`);
  const colValues = () => page.$$eval('#results-table tbody td[data-col="median_error_m"]',
    (tds) => tds.map((td) => td.textContent).filter((s) => s !== '–').map(Number));
  const okCount = points.filter((p) => p.status === 'ok' && p.metrics &&
    typeof p.metrics.median_error_m === 'number').length;
  if (okCount < 2) return;
  await page.click('#results-table th[data-col="median_error_m"]');
  const asc = await colValues();
  check(asc.length > 1 && asc.every((v, i) => i === 0 || asc[i - 1] <= v),
    `clicking "Median error" sorts ascending (${asc.slice(0, 4).join(', ')}, …)`);
  await page.click('#results-table th[data-col="median_error_m"]');
  const desc = await colValues();
  check(desc.length > 1 && desc.every((v, i) => i === 0 || desc[i - 1] >= v),
    `clicking it again sorts descending (${desc.slice(0, 4).join(', ')}, …)`);
  await page.click('#results-table th[data-col="rank"]');
}


// A scene page (scene.js) against the expectations the C++ test derived from its fixture.
async function checkScene(page, ex) {
  const kind = await page.evaluate(() => window.sonar3dReport.kind);
  check(kind === ex.kind, `page kind is ${ex.kind} (${kind})`);
  const layers = await page.evaluate(() => window.sonar3dReport.layers());
  check(layers.length === ex.layers.length,
    `${ex.layers.length} layers drawn (${layers.map((l) => l.id).join(', ')})`);
  ex.layers.forEach((e, i) => {
    const l = layers[i] || {};
    check(l.id === e.id && l.type === e.type,
      `layer ${i} is ${e.type} ${e.id} (${l.type} ${l.id})`);
    check(l.count === e.count && l.drawn === e.count,
      `layer ${e.id}: ${e.count} ${e.type === 'mesh' ? 'triangles' : e.type === 'lines' ?
        'segments' : 'points'} in its geometry (${l.drawn} drawn, ${l.count} listed)`);
    check(l.visible === e.visible, `layer ${e.id} ${e.visible ? 'shown' : 'hidden'} at first`);
  });
  for (const id of ex.figures || []) {
    const parts = await page.$$eval(`#figure-${id} svg .north-arrow, #figure-${id} svg .scale-bar`,
      (e) => e.length).catch(() => -1);
    check(parts === 2, `figure ${id} is drawn with its north arrow and scale bar (${parts})`);
  }
  for (const [id, n] of Object.entries(ex.tables || {})) {
    const rows = await page.$$eval(`#table-${id} tbody tr`, (r) => r.length).catch(() => -1);
    check(rows === n, `table ${id} has ${n} rows (${rows})`);
  }
  for (const c of ex.colors || []) {
    const rgb = await page.evaluate(([id, i]) => window.sonar3dReport.colorOf(id, i),
      [c.layer, c.index]);
    const [r, g, b] = rgb;
    let ok;
    if (c.rgb) ok = rgb.every((v, k) => Math.abs(v - c.rgb[k]) <= 1);
    else if (c.hue === 'red') ok = r > b + 40;
    else if (c.hue === 'blue') ok = b > r + 40;
    else ok = Math.min(r, g, b) > 220;
    check(ok, `${c.layer}[${c.index}] coloured ${c.rgb ? c.rgb.join(',') : c.hue} (${rgb})`);
  }
  const canvas = await page.$('#viewer canvas');
  check(!!canvas, '3D viewer has a canvas');
  if (!canvas) return;
  // The view's north arrow, scale bar and axes in metres. The first view looks from the
  // south-west and above: North points up and to the left on screen.
  const ov = await page.evaluate(() => window.sonar3dReport.overlay());
  const overlayParts = await page.$$eval('#viewer .north-arrow-3d, #viewer .scale-bar-3d',
    (e) => e.length);
  check(overlayParts === 2, `3D view has its north arrow and scale bar (${overlayParts})`);
  check(ov.northDeg < 0 && ov.northDeg > -90,
    `north arrow points up-left in the first view (${ov.northDeg.toFixed(1)} deg)`);
  const mant = ov.scaleMetres / Math.pow(10, Math.floor(Math.log10(ov.scaleMetres)));
  check(ov.scaleMetres > 0 && [1, 2, 5].some((m) => Math.abs(mant - m) < 1e-6) &&
    ov.scalePx > 40 && ov.scalePx < 250,
    `scale bar is a round length (${ov.scaleMetres} m over ${ov.scalePx.toFixed(0)} px)`);
  check(ov.axisLabels >= 6, `axes labelled in metres (${ov.axisLabels} labels)`);
  if (ex.intensity) {
    const modes = await page.evaluate(() => window.sonar3dReport.colorModes);
    check(modes.includes('intensity'), `points can be coloured by intensity (${modes})`);
    await page.evaluate(() => window.sonar3dReport.setColorMode('intensity'));
    const c = ex.intensity;
    const lo = await page.evaluate(([id, i]) => window.sonar3dReport.colorOf(id, i),
      [c.layer, c.low]);
    const hi = await page.evaluate(([id, i]) => window.sonar3dReport.colorOf(id, i),
      [c.layer, c.high]);
    const lum = (v) => 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2];
    check(lum(hi) > lum(lo) + 60,
      `by intensity, the strongest echo is brighter than the weakest (${hi} vs ${lo})`);
    await page.evaluate((m) => window.sonar3dReport.setColorMode(m), modes[0]);
  }
  await canvas.scrollIntoViewIfNeeded();
  const box = await canvas.boundingBox();
  const shot = pixelStats(await page.screenshot({ clip: box }));
  check(shot.variance > 50 && shot.colours > 20,
    `canvas is not blank (luminance variance ${shot.variance.toFixed(0)}, ` +
    `${shot.colours} colours)`);
  for (const [g, ids] of Object.entries(ex.groups || {})) {
    for (const id of ids) {
      await page.evaluate(([gn, i]) => window.sonar3dReport.selectGroup(gn, i), [g, id]);
      const vis = (await page.evaluate(() => window.sonar3dReport.layers()))
        .filter((l) => l.group === g && l.visible).map((l) => l.id);
      check(vis.length === 1 && vis[0] === id, `${g}: choosing ${id} shows it alone (${vis})`);
    }
  }
  if (ex.focus) {
    // Clicking a table row brings its layer into view: the camera moves, the canvas repaints.
    const before = pixelStats(await page.screenshot({ clip: box })).png;
    await page.click(`#table-${ex.focus.table} tbody tr:first-child`);
    await page.waitForTimeout(200);
    const focused = await page.evaluate(() => window.sonar3dReport.focused);
    await canvas.scrollIntoViewIfNeeded();
    const after = pixelStats(await page.screenshot({ clip: box })).png;
    const d = differingPixels(before, after);
    check(focused === ex.focus.layer && d > 100,
      `clicking the first ${ex.focus.table} row shows ${ex.focus.layer} (${focused}, ` +
      `${d} pixels changed)`);
  }
  if (ex.mode_change) {
    const before = shot.png;
    await page.evaluate(() => window.sonar3dReport.setColorMode('height'));
    const after = pixelStats(await page.screenshot({ clip: box })).png;
    const d = differingPixels(before, after);
    check(d > 100, `colouring by height repaints the canvas (${d} pixels changed)`);
  }
}
