// sonar3d report page: metric-vs-parameter plots (Plotly), a sortable results table and a 3D
// viewer of the reconstructed clouds over the CAD models (three.js). Everything it shows is in
// the JSON element #sonar3d-data written by `sonar3d report` (layout: docs/report.md); the page
// fetches nothing. window.sonar3dReport exposes the state for the headless test (test_report.mjs).
(function () {
  'use strict';

  const D = JSON.parse(document.getElementById('sonar3d-data').textContent);
  const R = D.results || {};
  const AXES = R.axes || {};
  const AXIS_NAMES = Object.keys(AXES);
  const POINTS = R.points || [];
  const BY_ID = new Map(POINTS.map((p) => [p.id, p]));
  const api = (window.sonar3dReport = { ready: false, plotsReady: false, viewerReady: false });
  const { el, select, fmtNum, decodeF32, decodeU32, COLORMAPS, colormap, createViewer } =
    window.sonar3dWeb;

  // ---------------------------------------------------------------- formatting helpers
  // Units come from the parameter name's suffix (the project's convention: SI, _deg at edges).
  const SUFFIX_UNITS = [['_deg', '°'], ['_db', 'dB'], ['_hz', 'Hz'], ['_mb', 'MB'],
    ['_pct', '%'], ['_m', 'm'], ['_s', 's']];
  function splitUnit(name) {
    const lower = String(name).toLowerCase();
    for (const [suf, unit] of SUFFIX_UNITS) {
      if (lower.endsWith(suf) && lower.length > suf.length) {
        return { base: name.slice(0, -suf.length).replace(/_/g, ' '), unit };
      }
    }
    return { base: String(name).replace(/_/g, ' '), unit: '' };
  }
  function axisLabel(name) {
    const { base, unit } = splitUnit(name);
    return unit ? `${base} [${unit}]` : base;
  }
  function fmtValue(name, v) {
    if (v === null || v === undefined) return 'none';
    if (typeof v === 'number') {
      const { unit } = splitUnit(name);
      if (!unit) return fmtNum(v, 6);
      return unit === '°' ? `${fmtNum(v, 6)}°` : `${fmtNum(v, 6)} ${unit}`;
    }
    if (typeof v === 'string') return v;
    return JSON.stringify(v);
  }
  function seriesLabel(name, v) { return `${splitUnit(name).base} ${fmtValue(name, v)}`; }
  const key = (v) => JSON.stringify(v === undefined ? null : v);
  function paramSummary(p, sep = ', ') {
    return AXIS_NAMES.filter((a) => AXES[a].length > 1)
      .map((a) => seriesLabel(a, (p.params || {})[a])).join(sep);
  }

  // Metrics as the thesis plots them: median error in cm, coverage and outliers in %, the ratio
  // in cm per % (Fig. 4.18), plus the planner's cost figures.
  const METRICS = [
    { key: 'median_error_m', label: 'Median error [cm]', scale: 100, short: 'Median error' },
    { key: 'coverage', label: 'Coverage [%]', scale: 100, short: 'Coverage' },
    { key: 'outliers', label: 'Outliers [%]', scale: 100, short: 'Outliers' },
    { key: 'median_to_coverage', label: 'Median error / coverage [cm/%]', scale: 1,
      short: 'Median / coverage' },
    { key: 'runtime_s', label: 'Run time [s]', scale: 1, top: true, short: 'Run time' },
    { key: 'peak_rss_mb', label: 'Peak memory [MB]', scale: 1, top: true, short: 'Peak memory' },
  ];
  function metricValue(p, m) {
    const v = m.top ? p[m.key] : (p.metrics || {})[m.key];
    return typeof v === 'number' && isFinite(v) ? v * m.scale : null;
  }
  const PALETTE = ['#1f77b4', '#d62728', '#2ca02c', '#ff7f0e', '#9467bd', '#8c564b', '#e377c2',
    '#17becf', '#7f7f7f', '#bcbd22'];
  const DASHES = ['solid', 'dash', 'dot', 'dashdot'];

  // ---------------------------------------------------------------- header
  function initHeader() {
    document.getElementById('title').textContent = D.title || 'sonar3d sweep';
    const counts = {};
    for (const p of POINTS) counts[p.status] = (counts[p.status] || 0) + 1;
    const rankBy = R.rank_by || 'median_to_coverage';
    document.getElementById('subtitle').textContent =
      `${D.plan_dir || ''} · generated ${D.generated || ''} · ranked by ${rankBy}` +
      ` (${R.rank_order || 'ascending'})` +
      (R.constraints && R.constraints.length ? ` · constraints: ${R.constraints.join(', ')}` : '');
    const cards = document.getElementById('cards');
    const card = (k, v, cls) => cards.append(el('div', { class: 'card ' + (cls || '') },
      el('div', { class: 'k', text: k }), el('div', { class: 'v', text: String(v) })));
    card('configurations', POINTS.length);
    card('ok', counts.ok || 0);
    card('failed', counts.failed || 0);
    const other = POINTS.length - (counts.ok || 0) - (counts.failed || 0);
    if (other) card('skipped', other);
    card('swept axes', AXIS_NAMES.filter((a) => AXES[a].length > 1).length);
    const best = POINTS.filter((p) => p.rank === 1)[0];
    if (best) {
      const m = METRICS.find((x) => x.key === rankBy);
      const v = m ? metricValue(best, m) : (best.metrics || {})[rankBy];
      card(`best (${m ? m.short.toLowerCase() : rankBy} ${fmtNum(v)})`,
        `${best.id}: ${paramSummary(best)}`, 'best');
    }
    const warn = document.getElementById('warnings');
    for (const w of D.warnings || []) warn.append(el('div', { class: 'warning', text: w }));
    document.getElementById('sweep-yaml').textContent = D.sweep_yaml || '(no sweep.yaml)';
    document.getElementById('footer').textContent =
      'Written by sonar3d report. Metrics as in the thesis, sec. 4.5.2.1: unsigned median ' +
      'error, coverage of the model surface within r_c, outliers beyond r_o, median/coverage ' +
      'ratio. Plotly and three.js are inlined: this file works offline.';
  }

  // ---------------------------------------------------------------- plots
  const plotState = { x: null, series: null, stat: 'mean', filters: {}, hidden: new Set() };

  // How an axis is plotted. 'numeric': every value a number, to scale. 'mixed': at least two
  // distinct numbers plus other levels (null = "none", strings, booleans), e.g.
  // snr_db: [none, 30, 20, 10] where none is the noise-free case: the numbers to scale, the
  // other levels as separate markers beyond one end of the axis (see xAxisLayout). 'category':
  // anything else (strings, booleans, a single number with a level), in sweep order.
  const isNum = (v) => typeof v === 'number' && isFinite(v);
  function axisKind(a) {
    const vals = axisValues(a);
    if (!vals.length) return 'category';
    if (vals.every(isNum)) return 'numeric';
    return new Set(vals.filter(isNum)).size >= 2 ? 'mixed' : 'category';
  }
  function isNumericAxis(a) { return axisKind(a) === 'numeric'; }
  function defaultX() {
    const swept = AXIS_NAMES.filter((a) => axisValues(a).length > 1);
    const numeric = swept.filter(isNumericAxis);
    const mixed = swept.filter((a) => axisKind(a) === 'mixed');
    const prefer = numeric.concat(mixed).find((a) => /spacing|period|sampling|step/i.test(a));
    return prefer || numeric[0] || mixed[0] || swept[0] || AXIS_NAMES[0] || null;
  }
  function defaultSeries(x) {
    const swept = AXIS_NAMES.filter((a) => a !== x && AXES[a].length > 1);
    return swept.find((a) => /aperture/i.test(a)) || swept.find((a) => /method/i.test(a)) ||
      swept[0] || '';
  }
  // Values of axis a in sweep order, then any value seen only in the points.
  function axisValues(a) {
    const vals = (AXES[a] || []).slice();
    const seen = new Set(vals.map(key));
    for (const p of POINTS) {
      const v = (p.params || {})[a];
      if (!seen.has(key(v))) { seen.add(key(v)); vals.push(v === undefined ? null : v); }
    }
    return vals;
  }
  function reduce(values, stat) {
    if (!values.length) return null;
    if (stat === 'min') return Math.min(...values);
    if (stat === 'max') return Math.max(...values);
    if (stat === 'median') {
      const s = values.slice().sort((a, b) => a - b);
      const n = s.length;
      return n % 2 ? s[(n - 1) / 2] : 0.5 * (s[n / 2 - 1] + s[n / 2]);
    }
    return values.reduce((a, b) => a + b, 0) / values.length;
  }

  function buildPlotControls() {
    const box = document.getElementById('plot-controls');
    box.innerHTML = '';
    const axisOpts = AXIS_NAMES.map((a) => ({ value: a, label: axisLabel(a) }));
    box.append(select('plot-x', 'x axis', axisOpts, plotState.x, (v) => {
      plotState.x = v;
      if (plotState.series === v) plotState.series = '';
      buildPlotControls();
      drawPlots();
    }));
    const seriesOpts = [{ value: '', label: '(one line)' }].concat(
      AXIS_NAMES.filter((a) => a !== plotState.x).map((a) => ({ value: a, label: axisLabel(a) })));
    box.append(select('plot-series', 'one line per', seriesOpts, plotState.series, (v) => {
      plotState.series = v;
      plotState.hidden.clear();
      buildPlotControls();
      drawPlots();
    }));
    box.append(select('plot-stat', 'over the other parameters', [
      { value: 'mean', label: 'mean' }, { value: 'median', label: 'median' },
      { value: 'min', label: 'minimum' }, { value: 'max', label: 'maximum' }],
    plotState.stat, (v) => { plotState.stat = v; drawPlots(); }));
    const rest = AXIS_NAMES.filter((a) => a !== plotState.x && a !== plotState.series &&
      axisValues(a).length > 1);
    if (rest.length) {
      const group = el('div', { class: 'filter-group' });
      for (const a of rest) {
        const opts = [{ value: '*', label: 'all' }].concat(
          axisValues(a).map((v) => ({ value: key(v), label: fmtValue(a, v) })));
        if (!(a in plotState.filters)) plotState.filters[a] = '*';
        group.append(select('plot-filter-' + a, axisLabel(a), opts, plotState.filters[a], (v) => {
          plotState.filters[a] = v;
          drawPlots();
        }));
      }
      box.append(group);
    }
  }

  // Groups ok points by (series value, x value) and reduces each group of one metric.
  function seriesData(m) {
    const { x, series, stat, filters } = plotState;
    const xs = axisValues(x);
    const ss = series ? axisValues(series) : [null];
    const groups = new Map();
    for (const p of POINTS) {
      if (p.status !== 'ok') continue;
      const params = p.params || {};
      let keep = true;
      for (const [a, f] of Object.entries(filters)) {
        if (a === x || a === series || f === '*') continue;
        if (key(params[a]) !== f) { keep = false; break; }
      }
      if (!keep) continue;
      const v = metricValue(p, m);
      if (v === null) continue;
      const g = key(series ? params[series] : null) + '|' + key(params[x]);
      if (!groups.has(g)) groups.set(g, []);
      groups.get(g).push(v);
    }
    const ax = xAxisLayout(x);
    return ss.map((sv, si) => {
      const tx = [], ty = [], tn = [], tt = [], sym = [];
      let gap = false;
      for (const xv of ax.order) {
        if (xv === GAP) { gap = true; continue; }
        const vals = groups.get(key(sv) + '|' + key(xv)) || [];
        if (!vals.length) continue;
        // A level plotted apart from the numbers is not joined to them by the line: the
        // distance between them means nothing.
        if (gap && tx.length) {
          tx.push(null); ty.push(null); tn.push(null); tt.push(''); sym.push('circle');
        }
        gap = false;
        tx.push(ax.pos(xv));
        ty.push(reduce(vals, stat));
        tn.push(vals.length);
        tt.push(fmtValue(x, xv));
        sym.push(ax.isLevel(xv) ? 'diamond' : 'circle');
      }
      return { sv, si, x: tx, y: ty, n: tn, text: tt, symbols: sym };
    });
  }

  // The x axis of the metric plots for parameter a: where each value is drawn, in which order
  // the line visits them, and the Plotly axis settings.
  const GAP = {};
  function xAxisLayout(a) {
    const vals = axisValues(a);
    const kind = axisKind(a);
    const base = { kind, isLevel: () => false, shapes: [] };
    if (kind === 'category') {
      return Object.assign(base, { order: vals, pos: (v) => fmtValue(a, v),
        xaxis: { type: 'category', categoryorder: 'array',
          categoryarray: vals.map((v) => fmtValue(a, v)) } });
    }
    // Numbers to scale; the line visits them in increasing order whatever the sweep order.
    const nums = vals.filter(isNum).sort((u, w) => u - w);
    if (kind === 'numeric') {
      return Object.assign(base, { order: nums, pos: (v) => v, xaxis: { type: 'linear' } });
    }
    // Mixed: the other levels sit beyond the end of the numbers they come next to in the sweep
    // (snr_db: [none, 30, 20, ...] puts "none" past 30: noise-free is the limit of high SNR),
    // one step apart, behind a dotted separator, drawn as diamonds and not joined by the line.
    const levels = vals.filter((v) => !isNum(v));
    const lo = nums[0], hi = nums[nums.length - 1];
    const firstNum = vals.findIndex(isNum);
    const firstLevel = vals.findIndex((v) => !isNum(v));
    const swNums = vals.filter(isNum);
    const neighbour = firstLevel < firstNum ? swNums[0] : swNums[swNums.length - 1];
    const high = neighbour !== lo;  // at the high end unless the levels neighbour the minimum
    const step = 0.15 * (hi - lo);
    const levelPos = new Map(levels.map((v, i) => [key(v),
      high ? hi + step * (i + 1) : lo - step * (levels.length - i)]));
    const sep = high ? hi + step / 2 : lo - step / 2;
    const edge = high ? hi + step * (levels.length + 0.5) : lo - step * (levels.length + 0.5);
    // Ticks: the swept numbers when they are few, else Plotly-like round steps between them.
    const tickNums = nums.length <= 12 ? nums : niceTicks(lo, hi);
    const tickvals = tickNums.concat(levels.map((v) => levelPos.get(key(v))));
    const ticktext = tickNums.map((v) => fmtNum(v, 6)).concat(levels.map((v) => fmtValue(a, v)));
    return Object.assign(base, {
      // GAP: the line breaks there (between the numbers and each level).
      order: high ? nums.concat(levels.flatMap((v) => [GAP, v])) :
        levels.flatMap((v) => [v, GAP]).concat(nums),
      pos: (v) => (isNum(v) ? v : levelPos.get(key(v))),
      isLevel: (v) => !isNum(v),
      levels: levels.map((v) => fmtValue(a, v)),
      xaxis: { type: 'linear', tickmode: 'array', tickvals, ticktext },
      shapes: [
        { type: 'rect', xref: 'x', yref: 'paper', x0: sep, x1: edge, y0: 0, y1: 1,
          fillcolor: '#f3f5f8', line: { width: 0 }, layer: 'below' },
        { type: 'line', xref: 'x', yref: 'paper', x0: sep, x1: sep, y0: 0, y1: 1,
          line: { color: '#9aa3b2', width: 1, dash: 'dot' } }],
    });
  }
  function niceTicks(lo, hi) {
    const raw = (hi - lo) / 6;
    const e = Math.pow(10, Math.floor(Math.log10(raw)));
    const step = [1, 2, 5, 10].map((m) => m * e).find((v) => v >= raw) || 10 * e;
    const out = [];
    for (let v = Math.ceil(lo / step) * step; v <= hi + 1e-9 * step; v += step) {
      out.push(Number(v.toPrecision(12)));
    }
    return out;
  }

  function drawLegend() {
    const box = document.getElementById('plot-legend');
    box.innerHTML = '';
    const s = plotState.series;
    if (!s) return;
    box.append(el('span', { class: 'title', text: axisLabel(s) + ':' }));
    axisValues(s).forEach((v, i) => {
      const k = key(v);
      const item = el('span', { class: 'item' + (plotState.hidden.has(k) ? ' off' : ''),
        title: 'click to hide or show', onclick: () => {
          if (plotState.hidden.has(k)) plotState.hidden.delete(k); else plotState.hidden.add(k);
          drawPlots();
        } },
      el('span', { class: 'swatch', style: `background:${PALETTE[i % PALETTE.length]}` }),
      fmtValue(s, v));
      box.append(item);
    });
  }

  function drawPlots() {
    const grid = document.getElementById('plots');
    const { x, series, stat } = plotState;
    drawLegend();
    const fixed = AXIS_NAMES.filter((a) => a !== x && a !== series && axisValues(a).length > 1);
    const filtered = fixed.filter((a) => plotState.filters[a] && plotState.filters[a] !== '*');
    const averaged = fixed.filter((a) => !filtered.includes(a));
    document.getElementById('plot-hint').textContent =
      (series ? `One line per ${splitUnit(series).base}. ` : '') +
      (averaged.length ? `Each marker is the ${stat} over ${averaged.map((a) => splitUnit(a).base)
        .join(', ')} (the hover gives how many configurations). ` : '') +
      (filtered.length ? `Fixed: ${filtered.map((a) => seriesLabel(a,
        JSON.parse(plotState.filters[a]))).join(', ')}. ` : '') +
      'Failed and skipped configurations are left out. The camera icon of each plot saves it ' +
      'as PNG.';
    const ax = xAxisLayout(x);
    const promises = [];
    METRICS.forEach((m, mi) => {
      let div = document.getElementById('plot-' + m.key);
      if (!div) {
        div = el('div', { id: 'plot-' + m.key, class: 'plot' });
        grid.append(div);
      }
      const traces = seriesData(m).filter((t) => !plotState.hidden.has(key(t.sv)))
        .map((t) => ({
          type: 'scatter', mode: 'lines+markers', x: t.x, y: t.y, customdata: t.n, text: t.text,
          name: series ? fmtValue(series, t.sv) : m.short,
          line: { color: PALETTE[t.si % PALETTE.length], width: 2,
            dash: DASHES[Math.floor(t.si / PALETTE.length) % DASHES.length] },
          marker: { size: t.symbols.map((k) => (k === 'circle' ? 7 : 10)), symbol: t.symbols },
          hovertemplate: (series ? `${seriesLabel(series, t.sv)}<br>` : '') +
            `${axisLabel(x)}: %{text}<br>${m.label}: %{y:.4g}<br>${stat} of %{customdata} ` +
            'configuration(s)<extra></extra>',
        }));
      const hasData = traces.some((t) => t.x.length);
      const layout = {
        title: { text: m.label, font: { size: 14 }, x: 0.02, xanchor: 'left' },
        margin: { l: 64, r: 16, t: 40, b: 52 },
        font: { family: 'system-ui, -apple-system, "Segoe UI", Roboto, "DejaVu Sans", sans-serif',
          size: 12, color: '#1d2433' },
        xaxis: Object.assign({ title: { text: axisLabel(x) }, gridcolor: '#e8ecf1',
          zeroline: false, automargin: true }, ax.xaxis),
        yaxis: { title: { text: m.label }, rangemode: 'tozero', gridcolor: '#e8ecf1',
          zeroline: false, automargin: true },
        shapes: hasData ? ax.shapes : [],
        showlegend: false, hovermode: 'closest', paper_bgcolor: '#fff', plot_bgcolor: '#fff',
        annotations: hasData ? [] : [{ text: 'no data for this selection', showarrow: false,
          xref: 'paper', yref: 'paper', x: 0.5, y: 0.5, font: { color: '#8a8f99' } }],
      };
      const config = { displaylogo: false, responsive: true,
        modeBarButtonsToRemove: ['select2d', 'lasso2d', 'autoScale2d'],
        toImageButtonOptions: { format: 'png', scale: 2,
          filename: `${m.key}_vs_${x}${series ? '_by_' + series : ''}` } };
      promises.push(window.Plotly.react(div, traces, layout, config));
      if (mi === 0) {
        api.lastTraces = traces.length;
        api.xKind = ax.kind;
      }
    });
    return Promise.all(promises);
  }

  function initPlots() {
    const box = document.getElementById('plots');
    if (!AXIS_NAMES.length || !POINTS.length) {
      box.append(el('p', { class: 'hint', id: 'plots-empty',
        text: 'No configurations in results.json.' }));
      return Promise.resolve();
    }
    // Without a single finished configuration there is nothing to plot: say so, rather than
    // six empty frames.
    const ok = POINTS.filter((p) => p.status === 'ok').length;
    if (!ok) {
      const failed = POINTS.filter((p) => p.status === 'failed').length;
      const other = POINTS.length - failed;
      box.classList.add('empty');
      box.append(el('p', { class: 'warning', id: 'plots-empty',
        text: `No configuration finished: ${failed} of ${POINTS.length} failed` +
          (other ? `, ${other} were not run (${[...new Set(POINTS.filter((p) =>
            p.status !== 'failed').map((p) => p.status))].join(', ')})` : '') +
          '. Nothing to plot; the table below gives each configuration\'s message.' }));
      api.plotsEmpty = true;
      return Promise.resolve();
    }
    plotState.x = defaultX();
    plotState.series = defaultSeries(plotState.x);
    buildPlotControls();
    return drawPlots();
  }

  // ---------------------------------------------------------------- table
  const tableState = { col: 'rank', dir: 1, selected: null };
  function columns() {
    const cols = [
      { id: 'rank', label: 'Rank', get: (p) => p.rank, num: true,
        fmt: (v) => (v === null || v === undefined ? '' : String(v)) },
      { id: 'id', label: 'Id', get: (p) => p.id },
      { id: 'status', label: 'Status', get: (p) => p.status, badge: true },
    ];
    for (const a of AXIS_NAMES) {
      cols.push({ id: 'param:' + a, label: axisLabel(a), get: (p) => (p.params || {})[a],
        num: axisKind(a) !== 'category', fmt: (v) => (v === null || v === undefined ? 'none' :
          typeof v === 'object' ? JSON.stringify(v) : String(v)) });
    }
    // The quality columns; a configuration without any (failed, skipped) shows its message
    // across them instead.
    for (const m of METRICS.slice(0, 4)) {
      cols.push({ id: m.key, label: m.label, get: (p) => metricValue(p, m), num: true,
        quality: true });
    }
    cols.push({ id: 'num_points', label: 'Points', num: true, quality: true,
      get: (p) => (p.metrics || {}).num_points, fmt: (v) => fmtNum(v) });
    cols.push({ id: 'runtime_s', label: 'Run time [s]', num: true, get: (p) => p.runtime_s });
    cols.push({ id: 'peak_rss_mb', label: 'Peak memory [MB]', num: true,
      get: (p) => p.peak_rss_mb });
    cols.push({ id: 'data_mb', label: 'Data [MB]', num: true,
      get: (p) => (typeof p.data_bytes === 'number' ? p.data_bytes / 1e6 : null) });
    cols.push({ id: 'message', label: 'Message', get: (p) => p.message || '', msg: true });
    return cols;
  }
  function compare(a, b) {
    const na = a === null || a === undefined || (typeof a === 'number' && !isFinite(a));
    const nb = b === null || b === undefined || (typeof b === 'number' && !isFinite(b));
    if (na || nb) return na && nb ? 0 : na ? 1 : -1;  // missing values last in both directions
    if (typeof a === 'number' && typeof b === 'number') return a - b;
    return String(a).localeCompare(String(b), 'en', { numeric: true });
  }
  function drawTable() {
    const cols = columns();
    const table = document.getElementById('results-table');
    table.className = 'results';
    table.innerHTML = '';
    const head = el('tr');
    for (const c of cols) {
      const arrow = tableState.col === c.id ? (tableState.dir > 0 ? '▲' : '▼') : '';
      head.append(el('th', { 'data-col': c.id, title: 'sort by ' + c.label,
        onclick: () => {
          if (tableState.col === c.id) tableState.dir = -tableState.dir;
          else { tableState.col = c.id; tableState.dir = 1; }
          drawTable();
        } }, c.label, el('span', { class: 'arrow', text: arrow })));
    }
    table.append(el('thead', {}, head));
    const col = cols.find((c) => c.id === tableState.col) || cols[0];
    const rows = POINTS.slice().sort((p, q) => compare(p.id, q.id));
    rows.sort((p, q) => {
      const a = col.get(p), b = col.get(q);
      const missA = a === null || a === undefined, missB = b === null || b === undefined;
      if (missA || missB) return compare(a, b);
      return tableState.dir * compare(a, b);
    });
    const body = el('tbody');
    for (const p of rows) {
      const cls = [p.status === 'failed' ? 'row-failed' : p.status === 'ok' ? '' : 'row-skipped',
        tableState.selected === p.id ? 'selected' : ''].join(' ').trim();
      const tr = el('tr', { 'data-id': p.id, class: cls, onclick: () => {
        if (D.clouds[p.id] && viewer) {
          viewer.select(p.id);
          document.getElementById('viewer-section').scrollIntoView({ behavior: 'smooth' });
        }
      } });
      const noQuality = p.status !== 'ok' &&
        cols.filter((c) => c.quality).every((c) => c.get(p) === null || c.get(p) === undefined);
      let spanned = false;
      for (const c of cols) {
        const v = c.get(p);
        if (noQuality && c.quality) {
          if (!spanned) {
            const span = String(cols.filter((x) => x.quality).length);
            tr.append(el('td', { class: 'msg', colspan: span, 'data-col': 'message-span',
              text: p.message || p.status }));
            spanned = true;
          }
          continue;
        }
        let content;
        if (c.badge) {
          content = el('span', { class: 'badge ' + (v === 'ok' ? 'ok' : v === 'failed' ? 'failed' :
            'other'), text: v });
        } else {
          content = c.fmt ? c.fmt(v) : typeof v === 'number' ? fmtNum(v) :
            v === null || v === undefined ? '–' : String(v);
        }
        const td = el('td', { class: c.num ? 'num' : c.msg ? 'msg' : '', 'data-col': c.id },
          noQuality && c.msg ? '' : content);
        if (c.id === 'rank' && v === 1) td.classList.add('rank1');
        if (c.id === 'message') {
          const ex = (D.extras || {})[p.id] || {};
          if (p.status === 'ok' && (ex.cloud_status === 'missing' || ex.cloud_status ===
            'unreadable')) td.textContent = (v ? v + ' · ' : '') + ex.cloud_message;
        }
        tr.append(td);
      }
      body.append(tr);
    }
    table.append(body);
    api.tableOrder = rows.map((p) => p.id);
  }

  // ---------------------------------------------------------------- 3D viewer

  let viewer = null;
  function initViewer() {
    const box = document.getElementById('viewer');
    const ids = POINTS.filter((p) => D.clouds && D.clouds[p.id]).map((p) => p.id)
      .sort((a, b) => compare(BY_ID.get(a).rank, BY_ID.get(b).rank) || compare(a, b));
    const V = createViewer(box, ids.length ? null :
      'No reconstructed cloud to show (no configuration finished with a cloud).');
    if (!V) {
      api.viewerReady = true;
      return;
    }
    const { T, scene, render, resize } = V;
    const meshCache = new Map();
    let cloudObj = null, grid = null, meshObjs = [];
    const state = { id: null, mode: D.color_mode === 'height' ? 'height' : 'error', size: 1,
      showMesh: true, errorMax: D.error_color_max_m > 0 ? String(D.error_color_max_m) : 'auto' };


    function meshFor(name) {
      if (meshCache.has(name)) return meshCache.get(name);
      const m = D.meshes[name];
      if (!m) return null;
      const g = new T.BufferGeometry();
      g.setAttribute('position', new T.BufferAttribute(decodeF32(m.vertices), 3));
      g.setIndex(new T.BufferAttribute(decodeU32(m.triangles), 1));
      g.computeVertexNormals();
      const mat = new T.MeshPhongMaterial({ color: 0x7d8aa0, transparent: true, opacity: 0.22,
        depthWrite: false, side: T.DoubleSide, shininess: 20 });
      const obj = new T.Mesh(g, mat);
      obj.renderOrder = 1;  // after the opaque points, so points show through
      meshCache.set(name, obj);
      return obj;
    }

    const controlsBox = document.getElementById('viewer-controls');
    const pointOpts = ids.map((id) => {
      const p = BY_ID.get(id);
      const rank = p.rank ? '#' + p.rank + ' · ' : '';
      return { value: id, label: `${rank}${id} · ${paramSummary(p)}` };
    });
    controlsBox.append(select('viewer-point', 'configuration', pointOpts, ids[0],
      (v) => api.viewer.select(v)));
    controlsBox.append(select('viewer-color', 'colour by', [
      { value: 'error', label: 'error (distance to CAD model)' },
      { value: 'height', label: 'height (z)' }], state.mode, (v) => api.viewer.setColorMode(v)));
    const scaleOpts = [{ value: 'auto', label: 'auto (95th percentile)' }].concat(
      [0.01, 0.02, 0.03, 0.05, 0.1, 0.2].map((v) => ({ value: String(v),
        label: `${fmtNum(v * 100)} cm${v === 0.03 ? ' (r_c)' : v === 0.1 ? ' (r_o)' : ''}` })));
    if (!scaleOpts.some((o) => o.value === state.errorMax)) {
      scaleOpts.push({ value: state.errorMax,
        label: `${fmtNum(Number(state.errorMax) * 100)} cm` });
    }
    controlsBox.append(select('viewer-scale', 'error colour scale top', scaleOpts, state.errorMax,
      (v) => { state.errorMax = v; colorize(); }));
    const sizeInput = el('input', { type: 'range', min: '0.25', max: '4', step: '0.05',
      value: '1', id: 'viewer-size' });
    sizeInput.addEventListener('input', () => {
      state.size = Number(sizeInput.value);
      if (cloudObj) { cloudObj.material.size = baseSize * state.size; render(); }
    });
    controlsBox.append(el('label', { for: 'viewer-size' }, 'point size', sizeInput));
    const meshBox = el('input', { type: 'checkbox', id: 'viewer-mesh' });
    meshBox.checked = true;
    meshBox.addEventListener('change', () => {
      state.showMesh = meshBox.checked;
      for (const o of meshObjs) o.visible = state.showMesh;
      render();
    });
    controlsBox.append(el('label', { class: 'inline', for: 'viewer-mesh' }, meshBox,
      'CAD model'));
    controlsBox.append(el('button', { type: 'button', text: 'reset view',
      onclick: () => { fit(); render(); } }));

    let baseSize = 0.01, bbox = null, zRange = [0, 1];
    function fit() { V.fit(bbox); }

    function colorize() {
      if (!cloudObj) return;
      const c = D.clouds[state.id];
      const pos = cloudObj.geometry.getAttribute('position').array;
      const n = pos.length / 3;
      const col = cloudObj.geometry.getAttribute('color').array;
      const errAvail = !!cloudObj.userData.err;
      const mode = state.mode === 'error' && errAvail ? 'error' : 'height';
      const cm = colormap(mode === 'error' ? 'turbo' : 'viridis');
      const emax = errorScaleTop();
      for (let i = 0; i < n; i++) {
        const t = mode === 'error' ? cloudObj.userData.err[i] / emax :
          (pos[3 * i + 2] - zRange[0]) / Math.max(zRange[1] - zRange[0], 1e-9);
        cm(t, col, 3 * i);
      }
      cloudObj.geometry.getAttribute('color').needsUpdate = true;
      drawColorbar(mode, emax, errAvail, c);
      if (state.id) infoPanel(state.id);
      api.colorMode = mode;
      render();
    }

    // Top of the error colour scale: the chosen one, or the cloud's 95th percentile rounded up
    // to 1, 2 or 5 times a power of ten (so the bar's labels stay round numbers).
    function errorScaleTop() {
      if (state.errorMax !== 'auto') return Number(state.errorMax);
      const err = cloudObj && cloudObj.userData.err;
      if (!err || !err.length) return 0.1;
      const finite = Array.from(err).filter((v) => isFinite(v)).sort((a, b) => a - b);
      if (!finite.length) return 0.1;
      const p95 = Math.max(finite[Math.floor(0.95 * (finite.length - 1))], 1e-4);
      const e = Math.pow(10, Math.floor(Math.log10(p95)));
      for (const m of [1, 2, 5, 10]) if (m * e >= p95) return m * e;
      return 10 * e;
    }

    function drawColorbar(mode, emax, errAvail) {
      const cb = document.getElementById('colorbar');
      cb.innerHTML = '';
      const stops = COLORMAPS[mode === 'error' ? 'turbo' : 'viridis'];
      const bar = el('div', { class: 'bar',
        style: `background:linear-gradient(to right, ${stops.join(', ')})` });
      if (mode === 'error') {
        cb.append(el('span', { class: 'lab', text: 'distance to CAD model: 0 cm' }), bar,
          el('span', { class: 'lab', text: `≥ ${fmtNum(emax * 100)} cm` }));
      } else {
        cb.append(el('span', { class: 'lab', text: `height z: ${fmtNum(zRange[0])} m` }), bar,
          el('span', { class: 'lab', text: `${fmtNum(zRange[1])} m` }));
        if (state.mode === 'error' && !errAvail) {
          cb.append(el('span', { class: 'lab',
            text: '(no CAD model for this cloud: height only)' }));
        }
      }
    }

    function infoPanel(id) {
      const p = BY_ID.get(id);
      const c = D.clouds[id];
      const ex = (D.extras || {})[id] || {};
      const info = document.getElementById('viewer-info');
      info.innerHTML = '';
      info.append(el('h3', { text: `${id}${p.rank ? ' · rank ' + p.rank : ''}` }));
      const t1 = el('table');
      for (const a of AXIS_NAMES) {
        t1.append(el('tr', {}, el('th', { text: axisLabel(a) }),
          el('td', { class: 'num', text: fmtValue(a, (p.params || {})[a]) })));
      }
      info.append(t1);
      const t2 = el('table');
      for (const m of METRICS) {
        t2.append(el('tr', {}, el('th', { text: m.label }),
          el('td', { class: 'num', text: fmtNum(metricValue(p, m)) })));
      }
      t2.append(el('tr', {}, el('th', { text: 'points shown' }), el('td', { class: 'num',
        text: `${fmtNum(c.num_shown)} of ${fmtNum(c.num_total)}` })));
      info.append(t2);
      const om = Array.isArray(ex.object_metrics) ? ex.object_metrics : [];
      if (om.length > 1) {
        const t3 = el('table', {}, el('tr', {}, el('th', { text: 'object' }),
          el('th', { text: 'median [cm]' }), el('th', { text: 'cov. [%]' }),
          el('th', { text: 'outl. [%]' })));
        for (const o of om) {
          const pct = (v) => fmtNum(typeof v === 'number' ? v * 100 : NaN);
          t3.append(el('tr', {}, el('td', { text: o.object || '' }),
            el('td', { class: 'num', text: pct(o.median_error_m) }),
            el('td', { class: 'num', text: pct(o.coverage) }),
            el('td', { class: 'num', text: pct(o.outliers) })));
        }
        info.append(el('h3', { text: 'Per object' }), t3);
      }
      if (cloudObj && cloudObj.userData.err) {
        const hist = el('div', { class: 'histo', id: 'viewer-histogram' });
        info.append(el('h3', { text: 'Error of the shown points' }), hist);
        // Plotly's basic bundle has no histogram trace: bin here, draw bars. The last bin holds
        // everything beyond 2x the colour scale top.
        const top = 2 * errorScaleTop() * 100, bins = 30, w = top / bins;
        const counts = new Array(bins).fill(0);
        for (const v of cloudObj.userData.err) {
          if (isFinite(v)) counts[Math.min(bins - 1, Math.floor(v * 100 / w))]++;
        }
        const centres = counts.map((_, i) => (i + 0.5) * w);
        window.Plotly.react(hist, [{ type: 'bar', x: centres, y: counts, width: w * 0.92,
          marker: { color: '#1f6fb2' },
          hovertemplate: '%{x:.2f} cm: %{y} points<extra></extra>' }],
        { margin: { l: 44, r: 8, t: 6, b: 42 }, bargap: 0.05,
          xaxis: { title: { text: 'distance to CAD [cm]' }, gridcolor: '#eef0f4' },
          yaxis: { title: { text: 'points' }, gridcolor: '#eef0f4' },
          font: { size: 11 }, paper_bgcolor: '#fff', plot_bgcolor: '#fff' },
        { displayModeBar: false, responsive: true });
      }
    }

    function selectPoint(id) {
      const c = D.clouds[id];
      if (!c) return false;
      state.id = id;
      document.getElementById('viewer-point').value = id;
      if (cloudObj) {
        scene.remove(cloudObj);
        cloudObj.geometry.dispose();
        cloudObj.material.dispose();
        cloudObj = null;
      }
      for (const o of meshObjs) scene.remove(o);
      meshObjs = [];
      const pos = decodeF32(c.xyz);
      const g = new T.BufferGeometry();
      g.setAttribute('position', new T.BufferAttribute(pos, 3));
      g.setAttribute('color', new T.BufferAttribute(new Float32Array(pos.length), 3));
      g.computeBoundingBox();
      bbox = g.boundingBox ? g.boundingBox.clone() : new T.Box3();
      if (!isFinite(bbox.min.x)) bbox = null;
      zRange = bbox ? [bbox.min.z, bbox.max.z] : [0, 1];
      for (const name of c.objects || []) {
        const o = meshFor(name);
        if (!o) continue;
        o.visible = state.showMesh;
        scene.add(o);
        meshObjs.push(o);
        o.geometry.computeBoundingBox();
        if (bbox) bbox.union(o.geometry.boundingBox); else bbox = o.geometry.boundingBox.clone();
      }
      const diag = bbox ? bbox.getSize(new T.Vector3()).length() : 1;
      // Points about 1/90 of the scene across, in world units so they scale with zoom.
      baseSize = Math.max(diag / 90, 0.002);
      const mat = new T.PointsMaterial({ size: baseSize * state.size, vertexColors: true,
        sizeAttenuation: true });
      cloudObj = new T.Points(g, mat);
      cloudObj.userData.err = c.err ? decodeF32(c.err) : null;
      scene.add(cloudObj);
      if (grid) scene.remove(grid);
      if (bbox) {
        grid = V.grid(bbox, 1.6);
        scene.add(grid);
      }
      fit();
      colorize();
      tableState.selected = id;
      for (const tr of document.querySelectorAll('#results-table tbody tr')) {
        tr.classList.toggle('selected', tr.getAttribute('data-id') === id);
      }
      api.shownPoint = id;
      return true;
    }

    viewer = api.viewer = {
      select: selectPoint,
      setColorMode(m) {
        state.mode = m;
        document.getElementById('viewer-color').value = m;
        colorize();
      },
      render,
    };
    resize();
    selectPoint(ids[0]);
    api.viewerReady = true;
  }

  // ---------------------------------------------------------------- start
  initHeader();
  drawTable();
  initViewer();
  initPlots().then(() => {
    api.plotsReady = true;
    api.ready = api.viewerReady;
  }, (e) => { console.error('sonar3d report: plots failed:', e); });
})();
