// Small SVG plots: line/point charts (linear or log axes, bands, reference lines), grouped bars,
// and sparklines with an uncertainty band. Every plot is an <svg role="img"> with a text label
// for screen readers.

import { fmtU } from "./uncertainty.js";

const NS = "http://www.w3.org/2000/svg";
export const CHANNEL_COLOURS = ["var(--cx)", "var(--cy)", "var(--cz)"];

function el(name, attrs = {}, text) {
  const e = document.createElementNS(NS, name);
  for (const [k, v] of Object.entries(attrs)) if (v !== undefined && v !== null) e.setAttribute(k, v);
  if (text !== undefined) e.textContent = text;
  return e;
}

export function fmt(v, digits = 3) {
  if (v === null || v === undefined || !Number.isFinite(v)) return "–";
  const a = Math.abs(v);
  if (a !== 0 && (a < 1e-3 || a >= 1e5)) return v.toExponential(digits - 1);
  return Number(v.toPrecision(digits)).toString();
}

function niceStep(span, n) {
  const raw = span / Math.max(n, 1);
  const p = 10 ** Math.floor(Math.log10(raw));
  const m = raw / p;
  return (m < 1.5 ? 1 : m < 3 ? 2 : m < 7 ? 5 : 10) * p;
}

/** Tick labels with as many decimals as the tick step needs (9.8150, 9.8155, … not 9.82, 9.82). */
function tickLabel(v, step) {
  const a = Math.abs(v);
  if (a !== 0 && (a < 1e-3 || a >= 1e5)) {
    const digits = Math.max(1, Math.min(6, Math.ceil(Math.log10(a / step)) + 1));
    return v.toExponential(digits - 1);
  }
  return v.toFixed(Math.max(0, Math.min(8, -Math.floor(Math.log10(step) + 1e-9))));
}

/** Plot width (SVG user units) close to the rendered width, so text keeps its size on a phone. */
export function plotWidth() {
  const w = window.innerWidth || 1024;
  return w < 700 ? Math.max(300, w - 56) : 640;
}

function linTicks(lo, hi, n = 5) {
  if (!(hi > lo)) return [lo];
  const s = niceStep(hi - lo, n);
  const out = [];
  for (let v = Math.ceil(lo / s) * s; v <= hi + s * 1e-9; v += s) out.push(Math.abs(v) < s * 1e-9 ? 0 : v);
  return out;
}

function logTicks(lo, hi) {
  for (const mult of [[1], [1, 3], [1, 2, 5]]) {
    const out = [];
    for (let e = Math.floor(Math.log10(lo)); e <= Math.ceil(Math.log10(hi)); e++) {
      for (const m of mult) {
        const v = m * 10 ** e;
        if (v >= lo * 0.999 && v <= hi * 1.001) out.push(v);
      }
    }
    if (out.length >= 3) return out;
  }
  return [lo, hi];
}

function extent(values, log) {
  const v = values.filter((x) => Number.isFinite(x) && (!log || x > 0));
  if (!v.length) return [log ? 1 : 0, log ? 10 : 1];
  let lo = Math.min(...v), hi = Math.max(...v);
  if (lo === hi) { const d = log ? lo * 0.5 : Math.abs(lo) * 0.05 || 1; lo -= d; hi += d; }
  if (!log) { const pad = (hi - lo) * 0.06; lo -= pad; hi += pad; }
  else { lo /= 1.3; hi *= 1.3; }
  return [lo, hi];
}

function scale(lo, hi, a, b, log) {
  if (log) { const l0 = Math.log10(lo), l1 = Math.log10(hi); return (v) => a + ((Math.log10(v) - l0) / (l1 - l0)) * (b - a); }
  return (v) => a + ((v - lo) / (hi - lo)) * (b - a);
}

function frame(width, height, label) {
  const svg = el("svg", { viewBox: `0 0 ${width} ${height}`, class: "plot", role: "img", "aria-label": label });
  svg.append(el("title", {}, label));
  return svg;
}

/**
 * Line/point chart.
 * opts: {x: [..] | categories: [..], series: [{name, y, colour, lo, hi, dash, points, line}],
 *        xlog, ylog, xlabel, ylabel, hlines: [{y, label, colour}], hband: {lo, hi}, label, width, height}
 */
export function chart(opts) {
  const W = opts.width || plotWidth(), H = opts.height || 300;
  const M = { l: 70, r: 14, t: 12, b: opts.categories ? 58 : 42 };
  const svg = frame(W, H, opts.label || opts.ylabel || "plot");
  const cats = opts.categories;
  const xs = cats ? cats.map((_, i) => i) : opts.x;
  const yAll = [];
  for (const s of opts.series) { yAll.push(...s.y); if (s.lo) yAll.push(...s.lo); if (s.hi) yAll.push(...s.hi); }
  for (const h of opts.hlines || []) yAll.push(h.y);
  if (opts.hband) yAll.push(opts.hband.lo, opts.hband.hi);
  const [x0, x1] = cats ? [-0.6, cats.length - 0.4] : extent(xs, opts.xlog);
  const [y0, y1] = extent(yAll, opts.ylog);
  const X = scale(x0, x1, M.l, W - M.r, opts.xlog), Y = scale(y0, y1, H - M.b, M.t, opts.ylog);
  const axis = el("g", { class: "axis" });
  const yt = opts.ylog ? logTicks(y0, y1) : linTicks(y0, y1, 5);
  const ystep = opts.ylog ? 0 : niceStep(y1 - y0, 5);
  for (const v of yt) {
    axis.append(el("line", { x1: M.l, x2: W - M.r, y1: Y(v), y2: Y(v), class: "gridline" }));
    axis.append(el("text", { x: M.l - 6, y: Y(v) + 4, "text-anchor": "end" }, opts.ylog ? fmt(v, 2) : tickLabel(v, ystep)));
  }
  if (cats) {
    const every = Math.max(1, Math.ceil(cats.length / Math.max(1, (W - M.l) / 46)));
    cats.forEach((c, i) => {
      if (i % every) return;
      axis.append(el("text", { x: X(i), y: H - M.b + 14, "text-anchor": "end",
        transform: `rotate(-35 ${X(i)} ${H - M.b + 14})` }, c));
    });
  } else {
    const xstep = opts.xlog ? 0 : niceStep(x1 - x0, 6);
    for (const v of opts.xlog ? logTicks(x0, x1) : linTicks(x0, x1, 6)) {
      axis.append(el("line", { x1: X(v), x2: X(v), y1: M.t, y2: H - M.b, class: "gridline" }));
      axis.append(el("text", { x: X(v), y: H - M.b + 15, "text-anchor": "middle" }, opts.xlog ? fmt(v, 2) : tickLabel(v, xstep)));
    }
  }
  axis.append(el("path", { d: `M${M.l},${M.t}V${H - M.b}H${W - M.r}`, fill: "none" }));
  if (opts.xlabel) axis.append(el("text", { x: (M.l + W - M.r) / 2, y: H - 4, "text-anchor": "middle" }, opts.xlabel));
  if (opts.ylabel) axis.append(el("text", { x: 12, y: (M.t + H - M.b) / 2, "text-anchor": "middle",
    transform: `rotate(-90 12 ${(M.t + H - M.b) / 2})` }, opts.ylabel));
  svg.append(axis);
  if (opts.hband) {
    svg.append(el("rect", { x: M.l, width: W - M.r - M.l, y: Y(opts.hband.hi), height: Math.max(0, Y(opts.hband.lo) - Y(opts.hband.hi)),
      fill: "#2ca02c", "fill-opacity": 0.07 }));
  }
  for (const h of opts.hlines || []) {
    svg.append(el("line", { x1: M.l, x2: W - M.r, y1: Y(h.y), y2: Y(h.y), stroke: h.colour || "#444", "stroke-dasharray": "5 4" }));
    if (h.label) svg.append(el("text", { x: W - M.r - 4, y: Y(h.y) - 5, "text-anchor": "end" }, h.label));
  }
  const ok = (i, s) => Number.isFinite(s.y[i]) && (!opts.ylog || s.y[i] > 0) && Number.isFinite(xs[i]);
  opts.series.forEach((s, k) => {
    const colour = s.colour || CHANNEL_COLOURS[k % 3];
    const off = cats && opts.series.length > 1 ? (k - (opts.series.length - 1) / 2) * 0.12 : 0;
    if (s.lo && s.hi) {
      const idx = xs.map((_, i) => i).filter((i) => Number.isFinite(s.lo[i]) && Number.isFinite(s.hi[i]) && (!opts.ylog || s.lo[i] > 0));
      if (idx.length > 1) {
        const d = idx.map((i, j) => `${j ? "L" : "M"}${X(xs[i])},${Y(s.hi[i])}`).join("")
          + idx.slice().reverse().map((i) => `L${X(xs[i])},${Y(s.lo[i])}`).join("") + "Z";
        svg.append(el("path", { d, fill: colour, "fill-opacity": 0.16, stroke: "none" }));
      }
    }
    const idx = xs.map((_, i) => i).filter((i) => ok(i, s));
    if (s.line !== false && idx.length > 1) {
      svg.append(el("path", { d: idx.map((i, j) => `${j ? "L" : "M"}${X(xs[i] + off)},${Y(s.y[i])}`).join(""),
        fill: "none", stroke: colour, "stroke-width": 1.6, "stroke-dasharray": s.dash || null }));
    }
    if (s.points !== false) {
      const g = el("g", { fill: colour });
      for (const i of idx) {
        const c = el("circle", { cx: X(xs[i] + off), cy: Y(s.y[i]), r: 3.2 });
        c.append(el("title", {}, `${s.name}: ${cats ? cats[i] : fmt(xs[i])} → ${fmt(s.y[i], 6)}`));
        g.append(c);
      }
      svg.append(g);
    }
  });
  return svg;
}

/** Grouped bar chart: categories × series, a zero line and an optional band (e.g. ±2). */
export function bars(opts) {
  const W = opts.width || plotWidth(), H = opts.height || 260;
  const M = { l: 52, r: 10, t: 10, b: 58 };
  const svg = frame(W, H, opts.label || "bar chart");
  const n = opts.categories.length, k = opts.series.length;
  const all = opts.series.flatMap((s) => s.y).filter(Number.isFinite);
  if (opts.band) all.push(opts.band, -opts.band);
  const m = Math.max(1e-12, ...all.map(Math.abs)) * 1.1;
  const Y = scale(-m, m, H - M.b, M.t, false);
  const slot = (W - M.l - M.r) / Math.max(n, 1), bw = Math.max(2, (slot * 0.8) / k);
  const axis = el("g", { class: "axis" });
  for (const v of linTicks(-m, m, 6)) {
    axis.append(el("line", { x1: M.l, x2: W - M.r, y1: Y(v), y2: Y(v), class: "gridline" }));
    axis.append(el("text", { x: M.l - 6, y: Y(v) + 4, "text-anchor": "end" }, tickLabel(v, niceStep(2 * m, 6))));
  }
  if (opts.band) svg.append(el("rect", { x: M.l, width: W - M.l - M.r, y: Y(opts.band), height: Y(-opts.band) - Y(opts.band),
    fill: "#2ca02c", "fill-opacity": 0.08 }));
  svg.append(axis);
  svg.append(el("line", { x1: M.l, x2: W - M.r, y1: Y(0), y2: Y(0), stroke: "#888" }));
  const every = Math.max(1, Math.ceil(n / Math.max(1, (W - M.l) / 40)));
  opts.categories.forEach((c, i) => {
    const cx = M.l + slot * (i + 0.5);
    if (i % every === 0) svg.append(el("text", { x: cx, y: H - M.b + 14, "text-anchor": "end", transform: `rotate(-35 ${cx} ${H - M.b + 14})` }, c));
    opts.series.forEach((s, j) => {
      const v = s.y[i];
      if (!Number.isFinite(v)) return;
      const x = cx - (bw * k) / 2 + j * bw;
      const r = el("rect", { x, width: bw - 1, y: Math.min(Y(v), Y(0)), height: Math.max(1, Math.abs(Y(v) - Y(0))),
        fill: s.colour || CHANNEL_COLOURS[j % 3] });
      r.append(el("title", {}, `${c} ${s.name}: ${fmt(v, 3)}${s.detail ? ` (${s.detail[i]})` : ""}`));
      svg.append(r);
    });
  });
  if (opts.ylabel) svg.append(el("text", { x: 12, y: (M.t + H - M.b) / 2, "text-anchor": "middle",
    transform: `rotate(-90 12 ${(M.t + H - M.b) / 2})` }, opts.ylabel));
  return svg;
}

/** Sparkline: values with a ±U band, the last point marked; points where hollow[i] drawn open. */
export function sparkline(values, U, label, width = 220, height = 56, hollow = [], dates = []) {
  const svg = frame(width, height, label);
  const n = values.length;
  const lo = values.map((v, i) => (U[i] == null ? v : v - U[i]));
  const hi = values.map((v, i) => (U[i] == null ? v : v + U[i]));
  const [y0, y1] = extent([...lo, ...hi], false);
  const X = (i) => (n <= 1 ? width / 2 : 6 + (i * (width - 12)) / (n - 1));
  const Y = scale(y0, y1, height - 5, 5, false);
  if (n > 1) {
    const d = values.map((_, i) => `${i ? "L" : "M"}${X(i)},${Y(hi[i])}`).join("")
      + values.map((_, i) => `L${X(n - 1 - i)},${Y(lo[n - 1 - i])}`).join("") + "Z";
    svg.append(el("path", { d, fill: "var(--accent)", "fill-opacity": 0.15 }));
    svg.append(el("path", { d: values.map((v, i) => `${i ? "L" : "M"}${X(i)},${Y(v)}`).join(""), fill: "none", stroke: "var(--accent)", "stroke-width": 1.5 }));
  }
  values.forEach((v, i) => {
    if (U[i] != null) svg.append(el("line", { x1: X(i), x2: X(i), y1: Y(lo[i]), y2: Y(hi[i]), stroke: "var(--accent)", "stroke-opacity": 0.5 }));
    const c = el("circle", { cx: X(i), cy: Y(v), r: i === n - 1 ? 3.5 : 2.4,
      fill: hollow[i] ? "#fff" : "var(--accent)", stroke: "var(--accent)", "stroke-width": 1.2 });
    c.append(el("title", {}, `${U[i] == null ? fmt(v, 6) : fmtU(v, U[i])}${dates[i] ? ` · ${dates[i]}` : ""}`));
    svg.append(c);
  });
  return svg;
}

/** The y range and the first and last date of a trend (dates: one label per point). */
export function sparkAxis(values, U, unit, dates) {
  const lo = Math.min(...values.map((v, i) => (U[i] == null ? v : v - U[i])));
  const hi = Math.max(...values.map((v, i) => (U[i] == null ? v : v + U[i])));
  const div = document.createElement("div");
  div.className = "spark-axis";
  const y = document.createElement("span");
  y.className = "num";
  // as many digits as the span needs: the two ends never print alike
  const step = hi > lo ? (hi - lo) / 10 : Math.abs(hi) * 1e-6 || 1e-9;
  y.textContent = `y ${tickLabel(lo, step)} … ${tickLabel(hi, step)} ${unit}`;
  const x = document.createElement("span");
  x.textContent = dates.length ? `${dates[0]} → ${dates[dates.length - 1]}` : "";
  div.append(y, x);
  return div;
}

/** A legend row: [{name, colour}]. */
export function legend(items) {
  const div = document.createElement("div");
  div.className = "legend";
  for (const it of items) {
    const span = document.createElement("span");
    const sw = document.createElement("i");
    sw.style.background = it.colour;
    if (it.dashed) sw.style.opacity = "0.5";
    span.append(sw, it.name);
    div.append(span);
  }
  return div;
}
