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

  window.sonar3dWeb = { fmtNum, el, select, decodeU8, decodeF32, decodeU32, COLORMAPS, hexToRgb, colormap };
})();
