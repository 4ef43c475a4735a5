// Small SVG charts drawn by the page itself: line charts and stacked bar charts with axes,
// grid lines, a legend and a tooltip per point. No library, no build step.
"use strict";

const Charts = (() => {
  const NS = "http://www.w3.org/2000/svg";
  const M = { top: 18, right: 26, bottom: 30, left: 58 };
  const PALETTE = [
    "#1f6feb", "#d1242f", "#1a7f37", "#9a6700", "#8250df",
    "#bf3989", "#0a7ea4", "#fb8500", "#57606a", "#6f42c1",
    "#2da44e", "#e16f24",
  ];

  function el(name, attrs, parent, text) {
    const node = document.createElementNS(NS, name);
    for (const [key, value] of Object.entries(attrs || {})) node.setAttribute(key, String(value));
    if (text !== undefined) node.textContent = text;
    if (parent) parent.appendChild(node);
    return node;
  }

  function size(svg) {
    const box = svg.viewBox.baseVal;
    return { w: box.width, h: box.height };
  }

  function clear(svg) {
    while (svg.firstChild) svg.removeChild(svg.firstChild);
  }

  function empty(svg, message) {
    clear(svg);
    const { w, h } = size(svg);
    el("text", { x: w / 2, y: h / 2, "text-anchor": "middle", class: "empty" }, svg, message);
    svg.dataset.points = "0";
  }

  // "Nice" tick values covering [lo, hi].
  function ticks(lo, hi, count) {
    if (!(hi > lo)) return [lo];
    const raw = (hi - lo) / Math.max(1, count);
    const mag = Math.pow(10, Math.floor(Math.log10(raw)));
    const step = [1, 2, 2.5, 5, 10].map((f) => f * mag).find((s) => s >= raw) || raw;
    const out = [];
    for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) out.push(+v.toPrecision(12));
    return out;
  }

  function logTicks(lo, hi) {
    const out = [];
    for (let e = Math.floor(Math.log10(lo)); e <= Math.ceil(Math.log10(hi)); e += 1) {
      const v = Math.pow(10, e);
      if (v >= lo * 0.999 && v <= hi * 1.001) out.push(v);
    }
    return out.length >= 2 ? out : [lo, hi];
  }

  function frame(svg, opts, xs, yLo, yHi) {
    const { w, h } = size(svg);
    const pw = w - M.left - M.right;
    const ph = h - M.top - M.bottom;
    const xLo = opts.xMin !== undefined ? opts.xMin : Math.min(...xs);
    const xHi = opts.xMax !== undefined ? opts.xMax : Math.max(...xs);
    const xSpan = xHi > xLo ? xHi - xLo : 1;
    const log = !!opts.log;
    const ly = (v) => (log ? Math.log10(Math.max(v, yLo)) : v);
    const yA = ly(yLo);
    const yB = ly(yHi) > yA ? ly(yHi) : yA + 1;
    const sx = (x) => M.left + ((x - xLo) / xSpan) * pw;
    const sy = (y) => M.top + ph - ((ly(y) - yA) / (yB - yA)) * ph;
    const yTicks = log ? logTicks(yLo, yHi) : ticks(yLo, yHi, 4);
    for (const t of yTicks) {
      el("line", { x1: M.left, x2: M.left + pw, y1: sy(t), y2: sy(t), class: "grid" }, svg);
      el("text", { x: M.left - 6, y: sy(t) + 4, "text-anchor": "end" }, svg, opts.yFormat(t));
    }
    const xTicks = opts.xTicks ? opts.xTicks(xLo, xHi) : ticks(xLo, xHi, 6);
    for (const t of xTicks) {
      el("line", { x1: sx(t), x2: sx(t), y1: M.top + ph, y2: M.top + ph + 4, class: "axis" }, svg);
      el("text", { x: sx(t), y: M.top + ph + 17, "text-anchor": "middle" }, svg, opts.xFormat(t));
    }
    el("line", { x1: M.left, x2: M.left + pw, y1: M.top + ph, y2: M.top + ph, class: "axis" }, svg);
    el("line", { x1: M.left, x2: M.left, y1: M.top, y2: M.top + ph, class: "axis" }, svg);
    return { sx, sy, pw, ph, xSpan };
  }

  function legend(svg, series) {
    const { w } = size(svg);
    const g = el("g", { class: "legend" }, svg);
    let x = w - M.right;
    for (let i = series.length - 1; i >= 0; i -= 1) {
      const label = series[i].name;
      x -= label.length * 6.2 + 22;
      el("rect", { x, y: 2, width: 10, height: 10, fill: series[i].color }, g);
      el("text", { x: x + 14, y: 11 }, g, label);
    }
  }

  // series: [{name, color, points: [[x, y|null], ...]}]; gaps where y is null.
  function line(svg, series, opts) {
    const values = series.flatMap((s) => s.points.filter((p) => p[1] !== null && isFinite(p[1])));
    if (!values.length) return empty(svg, opts.emptyText || "No data in this window");
    clear(svg);
    const ys = values.map((p) => p[1]);
    let yLo = opts.yMin !== undefined ? opts.yMin : Math.min(0, ...ys);
    let yHi = opts.yMax !== undefined ? opts.yMax : Math.max(...ys);
    if (opts.log) {
      const positive = ys.filter((y) => y > 0);
      yLo = positive.length ? Math.pow(10, Math.floor(Math.log10(Math.min(...positive)))) : 0.1;
      yHi = positive.length ? Math.pow(10, Math.ceil(Math.log10(Math.max(...positive)))) : 1;
    } else if (yHi <= yLo) {
      yHi = yLo + 1;
    }
    const xs = series.flatMap((s) => s.points.map((p) => p[0]));
    const f = frame(svg, opts, xs, yLo, yHi);
    let drawn = 0;
    for (const s of series) {
      let d = "";
      let pen = false;
      for (const [x, y] of s.points) {
        if (y === null || !isFinite(y) || (opts.log && y <= 0)) { pen = false; continue; }
        d += `${pen ? "L" : "M"}${f.sx(x).toFixed(1)},${f.sy(y).toFixed(1)}`;
        pen = true;
        drawn += 1;
      }
      if (d) el("path", { d, fill: "none", stroke: s.color, "stroke-width": 2, "stroke-linejoin": "round" }, svg);
      if (opts.dots !== false) {
        for (const [x, y] of s.points) {
          if (y === null || !isFinite(y) || (opts.log && y <= 0)) continue;
          const dot = el("circle", { cx: f.sx(x), cy: f.sy(y), r: 2.5, fill: s.color }, svg);
          el("title", {}, dot, `${s.name}: ${opts.yFormat(y)} at ${opts.xFormat(x)}`);
        }
      }
    }
    if (series.length > 1 || opts.legend) legend(svg, series);
    svg.dataset.points = String(drawn);
  }

  // x: bucket positions; stacks: [{name, color, values: [...]}] stacked bottom-up.
  function bars(svg, xs, stacks, opts) {
    const totals = xs.map((_, i) => stacks.reduce((sum, s) => sum + (s.values[i] || 0), 0));
    if (!totals.some((t) => t > 0)) return empty(svg, opts.emptyText || "No data in this window");
    clear(svg);
    const step = xs.length > 1 ? xs[1] - xs[0] : 1;
    const xMin = opts.xMin !== undefined ? opts.xMin : xs[0];
    const xMax = opts.xMax !== undefined ? opts.xMax : xs[xs.length - 1] + step;
    const f = frame(svg, { ...opts, xMin, xMax }, xs, 0, Math.max(...totals) * 1.05);
    const slot = (f.pw * step) / (xMax - xMin);
    const width = Math.max(1, slot * 0.8);
    let drawn = 0;
    xs.forEach((x, i) => {
      let base = 0;
      for (const s of stacks) {
        const v = s.values[i] || 0;
        if (v <= 0) continue;
        const y0 = f.sy(base);
        const y1 = f.sy(base + v);
        const r = el("rect", { x: f.sx(x) + slot * 0.1, y: y1, width, height: Math.max(0.5, y0 - y1), fill: s.color }, svg);
        el("title", {}, r, `${s.name}: ${opts.yFormat(v)} at ${opts.xFormat(x)}`);
        base += v;
        drawn += 1;
      }
    });
    legend(svg, stacks.map((s) => ({ name: s.name, color: s.color })));
    svg.dataset.points = String(drawn);
  }

  return { line, bars, empty, PALETTE };
})();
