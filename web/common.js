// Helpers shared by the pages of `sonar3d report` (report.js: sweeps; scene.js: maps, world
// models, changes, PLY files), exposed as window.sonar3dWeb. Inlined before the page's code.
(function () {
  'use strict';

  function fmtNum(v, digits = 3) {
    if (typeof v !== 'number' || !isFinite(v)) return '–';
    if (Math.abs(v) >= 1000) return Math.round(v).toLocaleString('en-US');
    if (v === 0) return '0';
    return String(Number(v.toPrecision(digits)));
  }
  function el(tag, attrs, ...children) {
    const e = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) {
      if (k === 'class') e.className = v;
      else if (k === 'text') e.textContent = v;
      else if (k.startsWith('on')) e.addEventListener(k.slice(2), v);
      else e.setAttribute(k, v);
    }
    for (const c of children) if (c !== null && c !== undefined) e.append(c);
    return e;
  }
  function select(id, label, options, value, onChange) {
    const s = el('select', { id });
    for (const o of options) s.append(el('option', { value: o.value, text: o.label }));
    s.value = value;
    s.addEventListener('change', () => onChange(s.value));
    return el('label', { for: id }, label, s);
  }
  // Binary arrays travel as base64 of little-endian bytes.
  function decodeU8(b64) {
    const bin = atob(b64);
    const bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    return bytes;
  }
  function decodeF32(b64) {
    return new Float32Array(decodeU8(b64).buffer);
  }
  function decodeU32(b64) {
    const f = decodeF32(b64);
    return new Uint32Array(f.buffer);
  }
  // Colour maps as stops in [0, 1] (matplotlib's viridis and turbo, sampled; diverging: ColorBrewer
  // RdBu reversed, blue below the white middle, red above).
  const COLORMAPS = {
    viridis: ['#440154', '#482878', '#3e4989', '#31688e', '#26828e', '#1f9e89', '#35b779',
      '#6ece58', '#b5de2b', '#fde725'],
    turbo: ['#30123b', '#4662d7', '#36aaf9', '#1ae4b6', '#72fe5e', '#c8ef34', '#faba39',
      '#f66b19', '#ca2a04', '#7a0403'],
    magma: ['#000004', '#1c1044', '#4f127b', '#812581', '#b5367a', '#e55964', '#fb8761',
      '#fec287', '#fcfdbf'],
    diverging: ['#2166ac', '#4393c3', '#92c5de', '#d1e5f0', '#f7f7f7', '#fddbc7', '#f4a582',
      '#d6604d', '#b2182b'],
  };
  function hexToRgb(h) {
    const n = parseInt(h.slice(1), 16);
    return [(n >> 16 & 255) / 255, (n >> 8 & 255) / 255, (n & 255) / 255];
  }
  function colormap(name) {
    const stops = COLORMAPS[name].map(hexToRgb);
    return (t, out, o) => {
      if (!isFinite(t)) { out[o] = out[o + 1] = out[o + 2] = 0.6; return; }
      const u = Math.min(1, Math.max(0, t)) * (stops.length - 1);
      const i = Math.min(stops.length - 2, Math.floor(u));
      const f = u - i;
      for (let c = 0; c < 3; c++) out[o + c] = stops[i][c] * (1 - f) + stops[i + 1][c] * f;
    };
  }

  // The 3D viewer both pages draw in: a WebGL renderer in `box`, a z-up camera with a head light,
  // orbit controls (drag rotates, right-drag pans, the wheel zooms), resizing with the box.
  // Returns null, with a message in the box instead of the viewer, when there is nothing to show
  // (`nothing`: what to say then) or the browser has no WebGL.
  // `dark`: a dark background (scene pages: white "no change" points and pale colours show).
  function createViewer(box, nothing, dark) {
    const message = (text) => {
      box.append(el('div', { class: 'message', text }));
      document.getElementById('viewer-info').style.display = 'none';
    };
    if (nothing) {
      message(nothing);
      return null;
    }
    const T = window.THREE;
    let renderer;
    try {
      renderer = new T.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    } catch (e) {
      console.warn('sonar3d report: WebGL unavailable:', e && e.message);
      message('This browser cannot draw 3D (WebGL is unavailable or disabled).');
      return null;
    }
    renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    box.append(renderer.domElement);
    box.append(el('div', { class: 'hud', text: 'drag: rotate · right-drag: pan · wheel: zoom' }));
    const scene = new T.Scene();
    scene.background = new T.Color(dark ? 0x22272e : 0xf0f3f7);
    const camera = new T.PerspectiveCamera(40, 1, 0.01, 1000);
    camera.up.set(0, 0, 1);  // world z up
    scene.add(camera);
    scene.add(new T.AmbientLight(0xffffff, 1.6));
    const sun = new T.DirectionalLight(0xffffff, 2.2);
    sun.position.set(0.5, 1, 1);
    camera.add(sun);  // a head light: the scene is lit from wherever it is seen
    const controls = new T.OrbitControls(camera, renderer.domElement);
    const v = { T, renderer, scene, camera, controls };
    // A north arrow and a scale bar over the view (SVG), redrawn with every frame: the arrow
    // points along world +y (North) as the camera shows it, the bar is a round length (1-2-5 ×
    // 10^k m) at the depth of the orbit's centre.
    const svgNs = 'http://www.w3.org/2000/svg';
    const svg = (tag, attrs) => {
      const e = document.createElementNS(svgNs, tag);
      for (const [k, val] of Object.entries(attrs || {})) e.setAttribute(k, val);
      return e;
    };
    const north = svg('svg', { class: 'north-arrow-3d', width: 44, height: 56,
      viewBox: '-22 -30 44 56' });
    const arrow = svg('g');
    arrow.append(svg('polygon', { points: '0,-24 8,2 0,-4 -8,2' }),
      svg('text', { x: 0, y: 20, 'text-anchor': 'middle' }));
    arrow.lastChild.textContent = 'N';
    north.append(arrow);
    const scaleBox = el('div', { class: 'scale-bar-3d' });
    const scaleBar = el('div', { class: 'bar' }), scaleLabel = el('span', { class: 'lab' });
    scaleBox.append(scaleBar, scaleLabel);
    box.append(north, scaleBox);
    v.overlay = { northDeg: 0, scaleMetres: 0, scalePx: 0, axisLabels: 0 };
    const updateOverlay = () => {
      const w = box.clientWidth, h = box.clientHeight;
      if (!w || !h) return;
      camera.updateMatrixWorld();
      const c = controls.target.clone();
      const dist = Math.max(camera.position.distanceTo(c), 1e-6);
      const toPx = (p) => {
        const q = p.clone().project(camera);
        return [(q.x + 1) * w / 2, (1 - q.y) * h / 2];
      };
      const c0 = toPx(c);
      const n1 = toPx(c.clone().add(new T.Vector3(0, dist * 0.05, 0)));
      const deg = Math.atan2(n1[0] - c0[0], -(n1[1] - c0[1])) * 180 / Math.PI;
      if (!isFinite(deg)) return;  // no camera yet
      arrow.setAttribute('transform', `rotate(${deg.toFixed(2)})`);
      const right = new T.Vector3().setFromMatrixColumn(camera.matrixWorld, 0).normalize();
      const r1 = toPx(c.clone().add(right));
      const pxPerM = Math.hypot(r1[0] - c0[0], r1[1] - c0[1]);
      let metres = 0;
      if (pxPerM > 0 && isFinite(pxPerM)) {
        const target = 100 / pxPerM;  // about 100 px long
        const e = Math.pow(10, Math.floor(Math.log10(target)));
        metres = [1, 2, 5, 10].map((m) => m * e).reduce((a, b) =>
          Math.abs(Math.log(b / target)) < Math.abs(Math.log(a / target)) ? b : a);
      }
      scaleBar.style.width = `${(metres * pxPerM).toFixed(1)}px`;
      scaleLabel.textContent = metres >= 1 ? `${fmtNum(metres)} m` : `${fmtNum(metres * 100)} cm`;
      v.overlay.northDeg = deg;
      v.overlay.scaleMetres = metres;
      v.overlay.scalePx = metres * pxPerM;
    };
    v.render = () => {
      updateOverlay();
      renderer.render(scene, camera);
    };
    controls.addEventListener('change', v.render);
    v.resize = () => {
      const w = box.clientWidth, h = box.clientHeight;
      if (!w || !h) return;
      renderer.setSize(w, h);
      camera.aspect = w / h;
      camera.updateProjectionMatrix();
      v.render();
    };
    new ResizeObserver(v.resize).observe(box);
    // Looks at the box from the south-west, above, far enough to see all of it.
    v.fit = (bbox) => {
      if (!bbox || bbox.isEmpty()) return;
      const c = bbox.getCenter(new T.Vector3());
      const r = Math.max(bbox.getSize(new T.Vector3()).length() / 2, 0.05);
      const dir = new T.Vector3(-1, -0.75, 0.55).normalize();
      const dist = r / Math.sin((camera.fov * Math.PI / 180) / 2);
      camera.position.copy(c).addScaledVector(dir, dist);
      camera.near = dist / 100;
      camera.far = dist * 10;
      camera.updateProjectionMatrix();
      controls.target.copy(c);
      controls.update();
    };
    // A grid in the world xy plane under the box, `margin` times its larger side, in round steps.
    v.grid = (bbox, margin) => {
      const size = bbox.getSize(new T.Vector3());
      const span = Math.max(size.x, size.y) * margin;
      const step = Math.pow(10, Math.floor(Math.log10(Math.max(span / 4, 1e-3))));
      const div = Math.max(2, Math.min(200, Math.round(span / step)));
      const grid = dark ? new T.GridHelper(div * step, div, 0x5a6472, 0x3a424d) :
        new T.GridHelper(div * step, div, 0xb8c2d0, 0xd8dee7);
      grid.rotation.x = Math.PI / 2;  // three's grid lies in xz; ours is the world xy plane
      const ctr = bbox.getCenter(new T.Vector3());
      grid.position.set(ctr.x, ctr.y, bbox.min.z);
      // Axes in metres: grid lines labelled just south (East, x) and west (North, y) of the
      // data, every line or every few so that at most 10 labels stand on each side.
      const half = div * step / 2;
      const labels = new T.Group();
      const label = (text, x, y, size) => {
        const cv = document.createElement('canvas');
        const ctx = cv.getContext('2d');
        const font = 'bold 40px sans-serif';
        ctx.font = font;
        cv.width = Math.ceil(ctx.measureText(text).width) + 16;
        cv.height = 56;
        ctx.font = font;
        ctx.fillStyle = dark ? '#d8dee7' : '#3a424d';
        ctx.textAlign = 'center';
        ctx.textBaseline = 'middle';
        ctx.fillText(text, cv.width / 2, cv.height / 2);
        const tex = new T.CanvasTexture(cv);
        const sp = new T.Sprite(new T.SpriteMaterial({ map: tex, depthTest: false,
          transparent: true }));
        sp.scale.set(size * cv.width / cv.height, size, 1);
        sp.position.set(x, y, bbox.min.z);
        sp.renderOrder = 3;
        labels.add(sp);
      };
      const lines = (lo, hi, c0) => {  // grid line coordinates over [lo, hi], one step beyond
        const out = [];
        for (let k = 0; k <= div; k++) {
          const u = c0 - half + k * step;
          if (u >= lo - step && u <= hi + step) out.push(u);
        }
        const every = Math.ceil(out.length / 10);
        return out.filter((_, i) => i % every === 0);
      };
      const xs = lines(bbox.min.x, bbox.max.x, ctr.x), ys = lines(bbox.min.y, bbox.max.y, ctr.y);
      const lsize = Math.max(xs.length > 1 ? xs[1] - xs[0] : step,
        ys.length > 1 ? ys[1] - ys[0] : step) * 0.16;
      const south = bbox.min.y - step * 0.6, west = bbox.min.x - step * 0.6;
      const fmtM = (m) => `${fmtNum(Math.round(m / step) * step)} m`;
      for (const x of xs) label(fmtM(x), x, south, lsize);
      for (const y of ys) label(fmtM(y), west - lsize, y, lsize);
      // The axis names beyond the last label of each side.
      const lastX = xs.length ? xs[xs.length - 1] : bbox.max.x;
      const lastY = ys.length ? ys[ys.length - 1] : bbox.max.y;
      label('East (x) →', lastX + 3.5 * lsize, south, lsize);
      label('North (y) ↑', west - lsize, lastY + 2 * lsize, lsize);
      v.overlay.axisLabels = labels.children.length;
      const g = new T.Group();
      g.add(grid, labels);
      return g;
    };
    return v;
  }

  window.sonar3dWeb = { fmtNum, el, select, decodeU8, decodeF32, decodeU32, COLORMAPS, hexToRgb, colormap,
    createViewer };
})();
