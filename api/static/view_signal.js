// The signal as it comes: the last seconds of a live run's samples (three channels and the
// table angles), decimated by the bench agent to a few hundred points (block means). Drawn
// anew from each `signal` event of the run's stream; the recording itself is not decimated.

import { h } from "./dom.js";
import { CHANNEL_COLOURS, chart, legend } from "./svgplot.js";

const CHANNELS = ["ax", "ay", "az"];
const AXIS_COLOURS = ["#8c564b", "#9467bd", "#7f7f7f", "#bcbd22"];

export function signalCard() {
  const note = h("p", { class: "note", id: "signal-note" }, "Waiting for the first samples…");
  const accel = h("div", { id: "signal-accel" });
  const angles = h("div", { id: "signal-table" });
  const el = h("section", { class: "card span", "aria-label": "Live signal", id: "live-signal", hidden: true },
    h("h2", {}, "Live signal"), note, accel, angles);
  const update = (s) => {
    const t = s.t_s || [];
    if (t.length < 2) return;
    el.hidden = false;
    const t0 = t[t.length - 1];
    const x = t.map((v) => v - t0); // seconds before the newest point
    const series = CHANNELS.map((c) => ({ name: c, y: (s[c] || []).map((v) => v ?? NaN), points: false }));
    accel.replaceChildren(chart({ x, series, xlabel: "time before now (s)", ylabel: "channel (recording units)",
      height: 220, label: "live signal: channel values of the last seconds" }), legend(series.map((se, i) => ({ name: se.name, colour: CHANNEL_COLOURS[i] }))));
    const axes = (s.table_deg || []).map((y, i) => ({ name: `axis ${i + 1}`, y: y.map((v) => v ?? NaN), colour: AXIS_COLOURS[i % 4], points: false }));
    angles.replaceChildren(axes.length ? chart({ x, series: axes, xlabel: "time before now (s)", ylabel: "table angle (°)",
      height: 180, label: "live signal: table angles of the last seconds" }) : "", axes.length ? legend(axes) : "");
    note.textContent = `Last ${Math.round(t0 - t[0])} s at t = ${t0.toFixed(1)} s on the recording clock; `
      + `each point the mean of ${s.samples_per_point} samples (${t.length} points).`;
    el.dataset.newest = String(t0);
  };
  return { el, update };
}
