// sonar3d scene page: a map directory with its placed models, a world model (seabed levels of
// detail, placed models, connections), a change directory or a PLY cloud/mesh, drawn in one
// three.js viewer with its tables. Everything it shows is in the JSON element #sonar3d-data
// written by `sonar3d report` (layout: docs/report.md, "Scene pages"); the page fetches nothing.
// window.sonar3dReport exposes the state for the headless test (test_report.mjs --expect).
(function () {
  'use strict';

  const D = JSON.parse(document.getElementById('sonar3d-data').textContent);
  const { el, select, fmtNum, decodeU8, decodeF32, decodeU32, COLORMAPS, hexToRgb, colormap,
    createViewer } = window.sonar3dWeb;
  const LAYERS = D.layers || [];
  const api = (window.sonar3dReport = { ready: false, viewerReady: false, kind: D.kind });
  const KIND_TEXT = {
    map: 'Map: the merged cloud by height, placed models over it',
    ply: 'Cloud or mesh',
    world: 'World model: seabed, placed models and their connections',
    changes: 'Changes between two surveys (survey B in survey A\'s frame)',
  };

  // ---------------------------------------------------------------- header and tables
  function fmtCell(v) {
    if (v === null || v === undefined) return '–';
    if (typeof v === 'number') return fmtNum(v, 4);
    if (Array.isArray(v)) return v.map(fmtCell).join(', ');
    return String(v);
  }
  // The page template is the sweep report's (web/report_template.html): its sweep-only sections
  // go, a container for the tables comes after the viewer.
  function initLayout() {
    for (const id of ['plots-section', 'table-section', 'sweep-section']) {
      const e = document.getElementById(id);
      if (e) e.remove();
    }
    const viewer = document.getElementById('viewer-section');
    viewer.querySelector('h2').id = 'viewer-heading';
    viewer.after(el('div', { id: 'tables' }));
  }
  function initHeader() {
    document.getElementById('title').textContent = D.title || 'sonar3d';
    document.getElementById('subtitle').textContent =
      `${D.source || ''} · generated ${D.generated || ''}`;
    document.getElementById('viewer-heading').textContent = KIND_TEXT[D.kind] || '3D view';
    const cards = document.getElementById('cards');
    for (const c of D.cards || []) {
      cards.append(el('div', { class: 'card' }, el('div', { class: 'k', text: c.k }),
        el('div', { class: 'v', text: fmtCell(c.v) })));
    }
    const warn = document.getElementById('warnings');
    for (const w of D.warnings || []) warn.append(el('div', { class: 'warning', text: w }));
    document.getElementById('footer').textContent =
      'Written by sonar3d report. World frame: local ENU (x East, y North, z up), metres. ' +
      'three.js is inlined: this file works offline.';
  }
  function drawTables() {
    const box = document.getElementById('tables');
    // Pictures sonar3d drew (SVG: the map's navigation before and after correction, with axes in
    // metres, a scale bar and a north arrow), above the tables.
    for (const f of D.figures || []) {
      const pic = el('div', { class: 'figure', id: 'figure-' + f.id });
      pic.innerHTML = f.svg;
      box.append(el('section', { id: 'section-figure-' + f.id }, el('h2', { text: f.title }), pic,
        el('p', { class: 'hint', text: f.caption || '' })));
    }
    for (const t of D.tables || []) {
      const table = el('table', { id: 'table-' + t.id, class: 'results scene-table' });
      table.append(el('thead', {}, el('tr', {}, ...t.columns.map((c) => el('th', { text: c })))));
      const body = el('tbody');
      for (const [i, r] of t.rows.entries()) {
        // A row naming a layer brings it into view when clicked.
        const focus = t.focus && t.focus[i];
        const attrs = focus ? { class: 'focusable', title: 'click: show it in the 3D view',
          onclick: () => api.focus && api.focus(focus) } : {};
        body.append(el('tr', attrs, ...r.map((v) => el('td',
          { class: typeof v === 'number' || v === null ? 'num' : '', text: fmtCell(v) }))));
      }
      table.append(body);
      const section = el('section', { id: 'section-' + t.id }, el('h2', { text: t.title }));
      if (!t.rows.length) section.append(el('p', { class: 'hint', text: 'none' }));
      else section.append(el('div', { class: 'table-wrap' }, table));
      box.append(section);
    }
  }

  // ---------------------------------------------------------------- 3D viewer
  function initViewer() {
    const box = document.getElementById('viewer');
    const V = createViewer(box, LAYERS.length ? null : 'Nothing to draw.', true);
    if (!V) {
      api.viewerReady = true;
      return;
    }
    const { T, scene, render, resize } = V;

    // Build every layer once; the whole scene's box and height range set colours and camera.
    const objs = new Map();
    const bbox = new T.Box3();
    for (const L of LAYERS) {
      const g = new T.BufferGeometry();
      const pos = decodeF32(L.xyz);
      g.setAttribute('position', new T.BufferAttribute(pos, 3));
      g.setAttribute('color', new T.BufferAttribute(new Float32Array(pos.length), 3));
      g.computeBoundingBox();
      if (pos.length) bbox.union(g.boundingBox);
      let obj;
      if (L.type === 'points') {
        obj = new T.Points(g, new T.PointsMaterial({ size: 0.01, vertexColors: true,
          sizeAttenuation: true }));
        obj.userData.change = L.change ? decodeF32(L.change) : null;
        obj.userData.intensity = L.intensity ? decodeF32(L.intensity) : null;
      } else if (L.type === 'mesh') {
        g.setIndex(new T.BufferAttribute(decodeU32(L.triangles), 1));
        g.computeVertexNormals();
        const transparent = L.opacity < 1;
        obj = new T.Mesh(g, new T.MeshPhongMaterial({ vertexColors: true, side: T.DoubleSide,
          transparent, opacity: L.opacity, depthWrite: !transparent, shininess: 20 }));
        if (transparent) obj.renderOrder = 1;  // after the opaque points, so they show through
      } else {
        obj = new T.LineSegments(g, new T.LineBasicMaterial({ vertexColors: true }));
        obj.renderOrder = 2;
      }
      obj.userData.rgb = L.rgb ? decodeU8(L.rgb) : null;
      obj.visible = !!L.visible;
      scene.add(obj);
      objs.set(L.id, obj);
    }
    // Height colours span the 1st to 99th percentile of the heights drawn by height (a few tall
    // structures would otherwise leave the whole seabed one colour).
    const zs = [];
    for (const L of LAYERS) {
      if (L.type === 'lines' || (L.type === 'mesh' && (L.rgb || L.color !== 'height'))) continue;
      const pos = objs.get(L.id).geometry.getAttribute('position').array;
      const step = Math.max(1, Math.floor(pos.length / 3 / 100000));
      for (let i = 0; i < pos.length / 3; i += step) zs.push(pos[3 * i + 2]);
    }
    zs.sort((a, b) => a - b);
    const zRange = zs.length ? [zs[Math.floor(0.01 * (zs.length - 1))],
      zs[Math.ceil(0.99 * (zs.length - 1))]] :
      bbox.isEmpty() ? [0, 1] : [bbox.min.z, bbox.max.z];
    const diag = bbox.isEmpty() ? 1 : bbox.getSize(new T.Vector3()).length();
    const baseSize = Math.max(diag / 150, 0.002);  // points in world units: they scale with zoom
    if (!bbox.isEmpty()) scene.add(V.grid(bbox, 1.4));

    // Point colour modes offered: those any cloud has, the first of change, own colours, height.
    const modes = [];
    for (const L of LAYERS) for (const m of L.color_modes || []) if (!modes.includes(m)) modes.push(m);
    const order = ['change', 'rgb', 'height', 'intensity'];
    modes.sort((a, b) => order.indexOf(a) - order.indexOf(b));
    const state = { mode: modes[0] || 'height', size: 1 };

    // Top of the change scale: the 95th percentile of |change| rounded up to 1-2-5.
    function changeTop() {
      const all = [];
      for (const L of LAYERS) {
        const c = objs.get(L.id).userData.change;
        if (c) for (const v of c) if (isFinite(v)) all.push(Math.abs(v));
      }
      if (!all.length) return 0.1;
      all.sort((a, b) => a - b);
      const p95 = Math.max(all[Math.floor(0.95 * (all.length - 1))], 1e-4);
      const e = Math.pow(10, Math.floor(Math.log10(p95)));
      for (const m of [1, 2, 5, 10]) if (m * e >= p95) return m * e;
      return 10 * e;
    }
    const cTop = changeTop();
    // Intensity colours span the 1st to 99th percentile of the intensities drawn.
    function intensityRange() {
      const all = [];
      for (const L of LAYERS) {
        const a = objs.get(L.id).userData.intensity;
        if (!a) continue;
        const step = Math.max(1, Math.floor(a.length / 100000));
        for (let i = 0; i < a.length; i += step) if (isFinite(a[i])) all.push(a[i]);
      }
      if (!all.length) return [0, 1];
      all.sort((a, b) => a - b);
      return [all[Math.floor(0.01 * (all.length - 1))], all[Math.ceil(0.99 * (all.length - 1))]];
    }
    const iRange = intensityRange();
    const magma = colormap('magma');
    const viridis = colormap('viridis');
    const diverging = colormap('diverging');
    const height = (z) => (z - zRange[0]) / Math.max(zRange[1] - zRange[0], 1e-9);

    function colorize() {
      for (const L of LAYERS) {
        const obj = objs.get(L.id);
        const pos = obj.geometry.getAttribute('position').array;
        const col = obj.geometry.getAttribute('color').array;
        const n = pos.length / 3;
        const rgb = obj.userData.rgb;
        let how = 'height';
        if (L.type === 'points') {
          how = (L.color_modes || []).includes(state.mode) ? state.mode : 'height';
        } else if (rgb) {
          how = 'rgb';
        } else if (L.color !== 'height') {
          how = 'flat';
        }
        const flat = how === 'flat' ? hexToRgb(L.color) : null;
        for (let i = 0; i < n; i++) {
          if (how === 'rgb') {
            for (let c = 0; c < 3; c++) col[3 * i + c] = rgb[3 * i + c] / 255;
          } else if (how === 'intensity') {
            magma((obj.userData.intensity[i] - iRange[0]) / Math.max(iRange[1] - iRange[0], 1e-12),
              col, 3 * i);
          } else if (how === 'change') {
            diverging(0.5 + 0.5 * obj.userData.change[i] / cTop, col, 3 * i);
          } else if (flat) {
            col[3 * i] = flat[0]; col[3 * i + 1] = flat[1]; col[3 * i + 2] = flat[2];
          } else {
            viridis(height(pos[3 * i + 2]), col, 3 * i);
          }
        }
        obj.geometry.getAttribute('color').needsUpdate = true;
        obj.userData.how = how;
      }
      drawColorbar();
      render();
    }

    function drawColorbar() {
      const cb = document.getElementById('colorbar');
      cb.innerHTML = '';
      const bar = (name) => el('div', { class: 'bar',
        style: `background:linear-gradient(to right, ${COLORMAPS[name].join(', ')})` });
      const anyHeight = LAYERS.some((L) => objs.get(L.id).visible &&
        objs.get(L.id).userData.how === 'height');
      if (state.mode === 'change' && modes.includes('change')) {
        cb.append(el('span', { class: 'lab', text: `change z_B − z_A: −${fmtNum(cTop * 100)} cm` }),
          bar('diverging'), el('span', { class: 'lab', text: `+${fmtNum(cTop * 100)} cm` }));
      } else if (state.mode === 'intensity' && modes.includes('intensity')) {
        cb.append(el('span', { class: 'lab', text: `intensity: ≤ ${fmtNum(iRange[0])}` }),
          bar('magma'), el('span', { class: 'lab', text: `≥ ${fmtNum(iRange[1])}` }));
      } else if (state.mode === 'rgb') {
        cb.append(el('span', { class: 'lab',
          text: 'points in their own colours (black: no camera saw them)' }));
      }
      if (anyHeight) {
        cb.append(el('span', { class: 'lab', text: `height z: ≤ ${fmtNum(zRange[0])} m` }),
          bar('viridis'), el('span', { class: 'lab', text: `≥ ${fmtNum(zRange[1])} m` }));
      }
    }

    function fit() {
      const b = new T.Box3();
      for (const o of objs.values()) {
        if (o.visible && o.geometry.boundingBox && !o.geometry.boundingBox.isEmpty()) {
          b.union(o.geometry.boundingBox);
        }
      }
      V.fit(b.isEmpty() ? bbox : b);
    }
    function setSize() {
      for (const L of LAYERS) {
        if (L.type === 'points') objs.get(L.id).material.size = baseSize * state.size;
      }
      render();
    }

    // Controls: point colouring, one selector per group (seabed levels of detail), point size.
    const controlsBox = document.getElementById('viewer-controls');
    const MODE_TEXT = { change: 'change (z_B − z_A)', rgb: 'own colours', height: 'height (z)',
      intensity: 'intensity (echo strength)' };
    if (modes.length) {
      controlsBox.append(select('scene-color', 'colour points by',
        modes.map((m) => ({ value: m, label: MODE_TEXT[m] })), state.mode,
        (v) => api.setColorMode(v)));
    }
    const groups = new Map();
    for (const L of LAYERS) {
      if (!L.group) continue;
      if (!groups.has(L.group)) groups.set(L.group, []);
      groups.get(L.group).push(L);
    }
    for (const [gname, members] of groups) {
      const shown = members.find((L) => L.visible);
      controlsBox.append(select('scene-group-' + gname, gname,
        [{ value: '', label: '(hidden)' }].concat(members.map((L) => ({ value: L.id,
          label: `${L.name} · ${fmtNum(L.count)} triangles` }))),
        shown ? shown.id : '', (v) => api.selectGroup(gname, v)));
    }
    if (LAYERS.some((L) => L.type === 'points')) {
      const sizeInput = el('input', { type: 'range', min: '0.25', max: '4', step: '0.05',
        value: '1', id: 'scene-size' });
      sizeInput.addEventListener('input', () => { state.size = Number(sizeInput.value); setSize(); });
      controlsBox.append(el('label', { for: 'scene-size' }, 'point size', sizeInput));
    }
    controlsBox.append(el('button', { type: 'button', text: 'reset view',
      onclick: () => { fit(); render(); } }));

    // Side panel: one checkbox per layer (group members are switched by their selector).
    const info = document.getElementById('viewer-info');
    info.append(el('h3', { text: 'Layers' }));
    const list = el('table', { id: 'scene-layers' });
    const boxes = new Map();
    for (const L of LAYERS) {
      const cb = el('input', { type: 'checkbox', id: 'layer-' + L.id });
      cb.checked = !!L.visible;
      cb.addEventListener('change', () => api.setVisible(L.id, cb.checked));
      boxes.set(L.id, cb);
      const what = L.type === 'points' ? `${fmtNum(L.count)} of ${fmtNum(L.num_total)} points` :
        L.type === 'mesh' ? `${fmtNum(L.count)} triangles` +
          (L.num_total > L.count ? ` (of ${fmtNum(L.num_total)})` : '') :
          `${fmtNum(L.count)} segments`;
      const swatch = L.type === 'mesh' && !L.rgb && L.color !== 'height' ?
        el('span', { class: 'swatch', style: `background:${L.color}` }) : null;
      list.append(el('tr', {}, el('td', {}, cb),
        el('th', {}, el('label', { for: 'layer-' + L.id }, swatch, ' ', L.name)),
        el('td', { class: 'num', text: what })));
    }
    info.append(list);
    if ((D.legend || []).length) {
      info.append(el('h3', { text: 'Markers and lines' }));
      const lg = el('div', { class: 'legend' });
      for (const item of D.legend) {
        lg.append(el('div', { class: 'item' },
          el('span', { class: 'swatch', style: `background:${item.color}` }), item.text));
      }
      info.append(lg);
    }

    Object.assign(api, {
      render,
      layers: () => LAYERS.map((L) => ({ id: L.id, name: L.name, type: L.type, count: L.count,
        group: L.group || null, visible: objs.get(L.id).visible,
        drawn: L.type === 'mesh' ? objs.get(L.id).geometry.index.count / 3 :
          objs.get(L.id).geometry.getAttribute('position').count / (L.type === 'lines' ? 2 : 1),
        coloring: objs.get(L.id).userData.how })),
      // The colour the page gave vertex i of a layer, as 0-255 RGB.
      colorOf(id, i) {
        const a = objs.get(id).geometry.getAttribute('color').array;
        return [0, 1, 2].map((c) => Math.round(a[3 * i + c] * 255));
      },
      setVisible(id, v) {
        objs.get(id).visible = v;
        boxes.get(id).checked = v;
        drawColorbar();
        render();
      },
      selectGroup(gname, id) {
        for (const L of groups.get(gname) || []) api.setVisible(L.id, L.id === id);
        const s = document.getElementById('scene-group-' + gname);
        if (s) s.value = id;
      },
      // Looks at one layer from close by (a structure in a large field).
      focus(id) {
        const o = objs.get(id);
        if (!o) return;
        if (!o.visible) api.setVisible(id, true);
        const b = o.geometry.boundingBox.clone();
        const c = b.getCenter(new T.Vector3());
        const r = Math.max(b.getSize(new T.Vector3()).length(), 0.5);
        V.fit(b.expandByVector(new T.Vector3(r, r, r * 0.25)));
        render();
        api.focused = id;
        document.getElementById('viewer').scrollIntoView({ block: 'nearest' });
        return c;
      },
      setColorMode(m) {
        state.mode = m;
        const s = document.getElementById('scene-color');
        if (s) s.value = m;
        colorize();
      },
      changeTop: cTop,
      intensityRange: iRange,
      colorModes: modes,
      // The north arrow's angle on screen (degrees clockwise from up), the scale bar's length in
      // metres and pixels, the number of axis labels in metres.
      overlay() { return Object.assign({}, V.overlay); },
    });
    resize();
    setSize();
    colorize();
    fit();
    render();
    api.viewerReady = true;
  }

  // ---------------------------------------------------------------- start
  initLayout();
  initHeader();
  drawTables();
  initViewer();
  api.ready = true;
})();
