// One run: live progress (event stream, polling as fallback), then its fit, the |g| check
// before/after, residuals, Allan curve, diagnosis and certificate.

import { downloadJson, followEvents, getJson, linkAnchor, postJson } from "./api.js";
import { badge, card, h, message, progressBar, setProgress, table, when } from "./dom.js";
import { CHANNEL_COLOURS, bars, chart, fmt, legend } from "./svgplot.js";
import { fmtU, splitU } from "./uncertainty.js";
import { signalCard } from "./view_signal.js";

const LIVE = new Set(["queued", "running", "paused", "suspended"]);
const G0 = 9.80665; // standard gravity: datasheets give sensitivity per g0
const POLL_MS = 1500;
const enc = encodeURIComponent;

function seconds(s) {
  if (!Number.isFinite(s)) return "–";
  const m = Math.floor(s / 60);
  return m ? `${m} min ${Math.round(s % 60)} s` : `${s.toFixed(1)} s`;
}

// Samples the DAQ produced that the recording lacks: each gap where it is and what was done.
function gapLine(run) {
  const gaps = [...(run.gaps || [])];
  const dt = h("dt", {}, "Samples lost");
  const dd = h("dd", { id: "run-gaps" });
  const draw = () => {
    const known = run.n_samples_lost === 0 || gaps.length > 0;
    dt.hidden = dd.hidden = !known;
    if (!gaps.length) { dd.textContent = "none"; return; }
    const lost = gaps.reduce((n, g) => n + (g.n_lost ?? 0), 0);
    const where = gaps.map((g) => `${g.n_lost ?? "?"} at ${g.t_last_s == null ? "the start" : `${g.t_last_s.toFixed(3)} s`}`
      + ` (${g.cause}; ${g.window_label ? `window ${g.window_label} re-measured` : g.action})`);
    dd.title = where.join("\n");
    dd.textContent = `${lost} in ${gaps.length} gap${gaps.length > 1 ? "s" : ""}: ${where.slice(0, 3).join("; ")}${gaps.length > 3 ? "; …" : ""}`;
  };
  draw();
  return { nodes: [dt, dd], add: (g) => { gaps.push(g); draw(); } };
}

// The phases of a live run: recording its windows on the bench, analysing the recording (fit,
// verdict, diagnosis, budget), storing its certificate. Pause and Abort apply while recording.
const PHASES = [["recording", "Recording"], ["analysing", "Analysing"], ["certificate", "Certificate"]];

function phaseList() {
  const items = PHASES.map(([key, label]) => h("li", { "data-phase": key }, label));
  const el = h("ol", { class: "phases", id: "run-phases", "aria-label": "run phases" }, ...items);
  const show = (phase, final) => {
    const at = final ? PHASES.length : PHASES.findIndex(([k]) => k === phase);
    items.forEach((li, i) => {
      li.className = i < at ? "done" : i === at ? "current" : "todo";
      if (i === at) li.setAttribute("aria-current", "step"); else li.removeAttribute("aria-current");
    });
  };
  return { el, show };
}

function liveCard(run, session, act) {
  const bar = progressBar(run.progress, true, "run progress");
  const pct = h("strong", { id: "progress-text", class: "num" }, `${Math.round(run.progress * 100)} %`);
  const state = h("span", { id: "run-state" }, badge(run.state));
  const phases = phaseList();
  const step = h("dd", { id: "run-step" }, "–");
  const windows = h("dd", { id: "run-window" }, "–");
  const time = h("dd", { id: "run-time" }, "–");
  const left = h("dd", { id: "run-eta" }, "–");
  const pose = h("dd", { id: "run-pose", class: "num" }, "–");
  const poseLabel = h("dt", {}, "Table");
  const canAct = session.role === "operator" || session.role === "admin";
  const needs = "needs an operator token";
  const abort = h("button", { type: "button", class: "danger", id: "abort-run", disabled: !canAct || !LIVE.has(run.state),
    title: canAct ? "stop the run; the table goes to its safe state and the recording is kept" : needs,
    onclick: act.abort }, "Abort");
  const pause = h("button", { type: "button", class: "ghost", id: "pause-run", disabled: !canAct,
    title: canAct ? "hold the run: the table stops, the window in progress is recorded again on continue" : needs,
    onclick: act.pause }, "Pause");
  const cont = h("button", { type: "button", id: "continue-run", disabled: !canAct,
    title: canAct ? "continue the held run (after a suspension: the table is prepared again)" : needs,
    onclick: act.resume }, "Continue");
  const resume = h("button", { type: "button", id: "resume-run", disabled: !canAct,
    title: canAct ? "continue this run on the bench from the window after its last complete one" : needs,
    onclick: act.resume }, "Resume");
  const busy = h("p", { class: "note", id: "analysing-note", hidden: true });
  let st = run.state, phase = run.phase || "recording";
  const controls = () => {
    const recording = phase === "recording";
    pause.hidden = !(recording && (st === "running" || st === "queued"));
    cont.hidden = !(recording && (st === "paused" || st === "suspended"));
    resume.hidden = st !== "interrupted";
    abort.hidden = !(recording && LIVE.has(st));
    abort.disabled = !canAct || !LIVE.has(st);
    busy.hidden = recording || !LIVE.has(st);
    busy.textContent = phase === "certificate" ? "The recording is analysed; the certificate is being stored."
      : "Every window is recorded: the fit, the verdict and the diagnosis run now (the run can no longer be paused or aborted).";
    state.replaceChildren(badge(LIVE.has(st) && !recording ? phase : st));
    phases.show(phase, !LIVE.has(st));
  };
  controls();
  const gaps = gapLine(run);
  const el = h("section", { class: "card span", "aria-label": "Progress" },
    h("header", {}, h("h2", {}, "Progress"), state),
    phases.el,
    h("div", { class: "progress-line" }, bar, pct),
    h("dl", { class: "kv" }, h("dt", {}, "Step"), step, h("dt", {}, "Window"), windows,
      h("dt", {}, "Time"), time, h("dt", {}, "Time left"), left, poseLabel, pose, ...gaps.nodes),
    busy,
    h("p", { class: "actions" }, pause, " ", cont, " ", resume, " ", abort),
    run.state === "interrupted" ? h("p", { class: "note", id: "interrupted-note" },
      "The run stopped before finishing. Every complete window is kept: Resume continues it on this bench "
      + "from the next window, and the certificate is issued at the end.") : null);
  let analysis = NaN, analysisStart = NaN;
  const update = (p) => {
    if (p.state) st = p.state;
    if (p.phase) phase = p.phase;
    if (p.progress !== undefined) { setProgress(bar, p.progress); pct.textContent = `${Math.round(p.progress * 100)} %`; }
    if (p.step_label !== undefined) step.textContent = `${Math.min(p.step_index + 1, p.n_steps)} of ${p.n_steps}: ${p.step_label}`;
    if (p.n_windows) windows.textContent = p.window_index == null ? `between windows (${p.n_windows} planned)` : `${p.window_index + 1} of ${p.n_windows}`;
    if (p.elapsed_s !== undefined) time.textContent = `${seconds(p.elapsed_s)} recorded (bench clock)`;
    if (p.analysis_s !== undefined) analysis = p.analysis_s;
    if (p.analysis_started_at) analysisStart = Date.parse(p.analysis_started_at);
    const then = Number.isFinite(analysis) ? `, then about ${seconds(analysis)} of analysis (this bench's past runs of the procedure)`
      : ", then the analysis (no past run of this procedure on this bench to time it by)";
    if (phase !== "recording") {
      const spent = Number.isFinite(analysisStart) ? (Date.now() - analysisStart) / 1000 : NaN;
      left.textContent = Number.isFinite(analysis) && Number.isFinite(spent)
        ? `recording done; analysing: about ${seconds(Math.max(0, analysis - spent))} left`
        : "recording done; analysing";
    }
    else if (st === "paused" || st === "suspended") left.textContent = "on hold";
    else if (Number.isFinite(p.remaining_s)) left.textContent = `about ${seconds(p.remaining_s)} of recording (from the pace so far)${then}`;
    if (p.table_deg) pose.textContent = p.table_deg.map((a) => `${a.toFixed(1)}°`).join("  ");
    controls();
  };
  const final = (r) => {
    st = r.state;
    controls();
    setProgress(bar, r.progress); pct.textContent = `${Math.round(r.progress * 100)} %`;
    step.textContent = `ended ${r.state}${r.outcome ? ` (${r.outcome})` : r.conformity_note ? ` (${r.conformity_note})` : ""}`;
    windows.textContent = r.last_complete_window == null ? "none complete" : `${r.last_complete_window + 1} complete`;
    const wall = (Date.parse(r.finished_at) - Date.parse(r.started_at)) / 1000;
    time.textContent = Number.isFinite(wall) ? `${seconds(wall)} (wall clock)` : "–";
    left.textContent = "–";
    if (r.n_samples) { poseLabel.textContent = "Recording"; pose.textContent = `${r.n_samples} samples`; }
  };
  if (!LIVE.has(run.state)) final(run);
  return { el, update, final, addGap: gaps.add };
}

// Every action on the run (its audit trail): when (UTC), who, what.
function auditCard() {
  const body = h("tbody", { id: "run-audit-rows" });
  const el = h("section", { class: "card span", "aria-label": "Actions on the run", id: "run-audit", hidden: true },
    h("h2", {}, "Actions on the run"),
    h("div", { class: "table-wrap" }, h("table", {},
      h("thead", {}, h("tr", {}, ["Time (UTC)", "Who", "Action", "Detail"].map((c) => h("th", { scope: "col" }, c)))),
      body)));
  const utc = (iso) => iso.replace("T", " ").replace(/\.\d+/, "").replace(/(\+00:00|Z)$/, "");
  const show = (run) => {
    const rows = run.audit || [];
    el.hidden = !rows.length;
    body.replaceChildren(...rows.map((a) => h("tr", {},
      h("td", { class: "mono" }, utc(a.at)), h("td", {}, a.actor),
      h("td", {}, a.action === "state" ? `state: ${a.state}`
        : a.action === "withdraw" ? "statement of conformity withdrawn" : `${a.action} requested`),
      h("td", {}, [a.detail, a.window_index == null ? "" : `window index ${a.window_index}`].filter(Boolean).join(" · ")))));
  };
  return { el, show };
}

function verdictBanner() {
  const el = h("div", { id: "verdict", class: "verdict", role: "status", hidden: true });
  const show = (run) => {
    if (LIVE.has(run.state) || run.kind === "drift_check" || !(run.outcome || run.conformity_note)) { el.hidden = true; return; }
    if (!run.outcome) {  // a completed fit no limits judged: no PASS or FAIL, and why
      el.className = "verdict none";
      el.replaceChildren(h("strong", { id: "verdict-outcome" }, run.conformity_note));
      el.hidden = false;
      return;
    }
    const checks = run.limit_checks || [];
    const bad = checks.filter((c) => !c.passed).length;
    const what = checks.length
      ? (bad ? `${bad} of ${checks.length} limit checks outside their acceptance intervals` : `all ${checks.length} limit checks inside their acceptance intervals`)
      : run.error || "";
    el.className = `verdict ${run.outcome.toLowerCase()}`;
    el.replaceChildren(h("strong", { id: "verdict-outcome" }, run.outcome), h("span", {}, what));
    el.hidden = false;
  };
  return { el, show };
}

function bound(v) { return v == null ? "∞" : fmt(v, 6); }

function conformityCard(run) {
  const checks = run.limit_checks || [];
  const c = h("section", { class: "card span", "aria-label": "Limit checks", id: "limit-checks" }, h("h2", {}, "Limit checks"));
  if (!checks.length) { c.append(message(run.conformity_note ? `${run.conformity_note}: the certificate makes no statement of conformity.` : "No limit checks.")); return c; }
  c.append(table(`decision rule: ${run.decision_rule}`, ["Quantity", "Value", "U", "Unit", "Tolerance", "Acceptance", "Verdict"],
    checks.map((k) => [k.name, ...(k.expanded_uncertainty == null ? [fmt(k.value, 6), "not stated"] : splitU(k.value, k.expanded_uncertainty)),
      k.unit.replace("m/s2", "m/s²"),
      `[${k.low == null ? "−∞" : fmt(k.low, 6)}, ${bound(k.high)}]`,
      `[${k.acceptance_low == null ? "−∞" : fmt(k.acceptance_low, 6)}, ${bound(k.acceptance_high)}]`,
      badge(k.passed ? "pass" : "fail")]), [1, 2]));
  return c;
}

function fitCard(cal) {
  const unit = cal.channel_unit;
  const ax = ["x", "y", "z"];
  const U = (s) => (Number.isFinite(s) ? 2 * s : NaN);
  const bias = table(`bias (${unit}), value ± U (k = 2)`, ["", "value ± U"], ax.map((a, i) => [a, fmtU(cal.bias[i], U(cal.bias_sigma[i]))]), [1]);
  const K = h("div", { class: "table-wrap" }, h("table", { class: "matrix" },
    h("caption", {}, `scale matrix K (${unit} per m/s²), value ± U (k = 2)`),
    h("tbody", {}, cal.scale_matrix.map((row, i) => h("tr", {}, h("th", { scope: "row" }, ax[i]),
      row.map((v, j) => h("td", {}, fmtU(v, U(cal.scale_matrix_sigma[i][j])))))))));
  const mv = unit === "V" ? 1000 : 1, sUnit = unit === "V" ? "mV/g" : `${unit}/g`;
  // cross-axis K_ij/K_ii in mrad everywhere (here and on the certificate), with its U
  const cross = (i, j) => fmtU(1000 * cal.scale_matrix[i][j] / cal.scale_matrix[i][i], 1000 * U(Math.hypot(
    cal.scale_matrix_sigma[i][j] / cal.scale_matrix[i][i],
    cal.scale_matrix[i][j] * cal.scale_matrix_sigma[i][i] / cal.scale_matrix[i][i] ** 2)));
  const sheet = table(`data-sheet units: sensitivity S = K_ii·g_n and cross-axis K_ij/K_ii, value ± U (k = 2)`,
    ["", `S (${sUnit})`, "from x (mrad)", "from y (mrad)", "from z (mrad)"],
    ax.map((a, i) => [a, fmtU(cal.scale_matrix[i][i] * G0 * mv, U(cal.scale_matrix_sigma[i][i]) * G0 * mv),
      ...ax.map((_, j) => (i === j ? "–" : cross(i, j)))]), [1, 2, 3, 4]);
  const g = cal.g_check || {};
  const gRows = ["before", "after"].filter((k) => g[k]).map((k) => [k, fmt(g[k].mean_error_m_s2, 3), fmt(g[k].std_m_s2, 3)]);
  return card("Fitted model", sheet, bias, K,
    h("p", { class: "note" }, `terms: ${(cal.terms || []).join(", ")} · residual RMS ${fmt(cal.residual_rms, 3)} ${unit}`),
    gRows.length ? table(String(cal.method || "").startsWith("dynamic")
      ? "|g| check over 1 s blocks of the moving recording (m/s²)"
      : "|g| check over static windows (m/s²)", ["", "mean error", "std"], gRows, [1, 2]) : null);
}


function datasheetForm(runId, unit, onResult) {
  const sens = h("input", { id: "nominal-sens", type: "number", step: "any", min: "0", required: true, inputmode: "decimal", placeholder: "0.174" });
  const zero = h("input", { id: "nominal-zero", type: "number", step: "any", inputmode: "decimal", placeholder: "1.5" });
  const note = h("span", { class: "note", "aria-live": "polite" });
  const form = h("form", { class: "start", "aria-label": "compare with datasheet values" },
    h("label", { for: "nominal-sens" }, `Datasheet sensitivity (${unit}/g)`, sens),
    h("label", { for: "nominal-zero" }, `Zero-g output (${unit})`, zero),
    h("button", { type: "submit", class: "ghost", style: "color: var(--accent); border-color: var(--accent)" }, "Compare"), note);
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    const q = new URLSearchParams({ nominal_scale: String(Number(sens.value) / G0) });
    if (zero.value !== "") for (let i = 0; i < 3; i++) q.append("nominal_bias", zero.value);
    try { onResult(await getJson(`/api/runs/${enc(runId)}/plots/g-check?${q}`)); }
    catch (err) { note.textContent = err.message; }
  });
  return form;
}

function gCard(gc, runId, unit) {
  const gl = { y: gc.g_local_m_s2, label: `g local ${fmt(gc.g_local_m_s2, 7)} m/s²`, colour: "#333" };
  const panel = (title, ys, colour, mean, std) => h("figure", { style: "margin:0" },
    h("figcaption", { class: "note" }, `${title}: mean error ${fmt(mean, 3)} m/s², std ${fmt(std, 3)} m/s²`),
    chart({ categories: gc.labels, series: [{ name: title, y: ys, colour, line: false }], hlines: [gl],
      ylabel: "|f̂| (m/s²)", height: 230, label: `${title}: corrected specific force magnitude per window against local g` }));
  const plots = h("div");
  const render = (data) => {
    const body = [];
    if (data.before_m_s2) body.push(panel(`before (${data.before_label})`, data.before_m_s2, "var(--before)", data.before_mean_error_m_s2, data.before_std_m_s2));
    else body.push(message("Before: no nominal scale is known for these channels and the unit has no earlier calibration; enter the datasheet values to compare."));
    body.push(panel("after (this calibration)", data.after_m_s2, "var(--accent)", data.after_mean_error_m_s2, data.after_std_m_s2));
    plots.replaceChildren(...body);
  };
  render(gc);
  return h("section", { class: "card", "aria-label": "|g| check", id: "g-check" }, h("h2", {}, "|g| check, before and after"), plots,
    unit === "V" || unit === "count" ? datasheetForm(runId, unit, render) : null);
}

function residualCard(rs) {
  const series = rs.channels.map((c, k) => ({ name: c, y: rs.normalized.map((r) => r[k]), colour: CHANNEL_COLOURS[k],
    detail: rs.residual.map((r) => `${fmt(r[k], 3)} ${rs.channel_unit}`) }));
  return h("section", { class: "card", "aria-label": "Residuals", id: "residuals" }, h("h2", {}, "Residuals per window"),
    bars({ categories: rs.labels, series, band: 2, ylabel: "residual / σ", label: "normalised fit residuals per window and channel" }),
    legend(series.map((s) => ({ name: s.name, colour: s.colour }))),
    h("p", { class: "note" }, `Window mean minus model, in units of the mean's standard deviation; the green band is ±2. `
      + `χ² = ${fmt(rs.chi2, 4)} for ${rs.dof} degrees of freedom (${rs.method} fit).`));
}

// Noise in the units of a data sheet from the Allan curve and the fitted sensitivity K_ii:
// white-noise density N = σ(τ₀)·√τ₀ at the shortest τ (σ ∝ τ^-1/2 there), bias instability
// B = min σ(τ) / 0.664 (IEEE Std 952 Annex C), both divided by K_ii and g_n, in µg/√Hz and µg.
// B is quoted only where the curve has its minimum inside the τ measured: a curve still falling
// at its longest τ comes from a record too short to show the floor, and that is said instead.
export function biasInstability(taus, adev) {
  const finite = adev.map((v, i) => [v, taus[i]]).filter(([v]) => Number.isFinite(v));
  if (finite.length < 3) return { reached: false, tauMax: taus[taus.length - 1] };
  let k = 0;
  finite.forEach(([v], i) => { if (v < finite[k][0]) k = i; });
  const tauMax = finite[finite.length - 1][1];
  return k >= finite.length - 1 ? { reached: false, tauMax } : { reached: true, sigma: finite[k][0], tau: finite[k][1], tauMax };
}

function noiseTable(al, cal) {
  if (!cal || !al.taus_s.length) return null;
  const scale = (k) => cal.scale_matrix[k][k] * G0 / 1e6; // channel unit per µg
  const rows = al.channels.map((c, k) => {
    const s0 = al.adev[k][0], t0 = al.taus_s[0];
    const b = biasInstability(al.taus_s, al.adev[k]);
    const short = `not reached: σ(τ) still falling at τ = ${fmt(b.tauMax, 3)} s (record too short)`;
    return [c, fmt(s0 * Math.sqrt(t0) / scale(k), 3), b.reached ? `${fmt(b.sigma / 0.664 / scale(k), 3)} (τ = ${fmt(b.tau, 3)} s)` : short,
      `${fmt(s0 * Math.sqrt(t0), 3)} ${al.unit}·√s`, b.reached ? `${fmt(b.sigma / 0.664, 3)} ${al.unit}` : "–"];
  });
  return table("noise, from the curve and the fitted sensitivity", ["", "density (µg/√Hz)", "bias instability (µg)", "density (raw)", "instability (raw)"], rows, [1, 3, 4]);
}

function allanCard(al, cal) {
  const series = al.channels.map((c, k) => ({ name: c, y: al.adev[k], lo: al.adev_lo[k], hi: al.adev_hi[k], colour: CHANNEL_COLOURS[k] }));
  return h("section", { class: "card", "aria-label": "Allan deviation", id: "allan" }, h("h2", {}, "Allan deviation"),
    chart({ x: al.taus_s, series, xlog: true, ylog: true, xlabel: "averaging time τ (s)", ylabel: `σ(τ) (${al.unit})`,
      height: 280, label: `overlapping Allan deviation of the ${al.source}` }),
    legend(series.map((s) => ({ name: s.name, colour: s.colour }))),
    noiseTable(al, cal),
    h("p", { class: "note" }, `${al.source}, ${fmt(al.start_s, 4)}–${fmt(al.end_s, 4)} s, ${al.n_samples} samples; `
      + `bands: ${Math.round(al.ci_level * 100)} % χ² interval. Density N = σ(τ₀)·√τ₀ at the shortest τ; `
      + "bias instability B = min σ(τ)/0.664 (IEEE Std 952), converted with the fitted K_ii and g_n = 9.80665 m/s²."));
}

function diagnosisCard(d) {
  const c = h("section", { class: "card", "aria-label": "Diagnosis", id: "diagnosis" }, h("h2", {}, "Diagnosis"));
  if (!d.diagnosis) { c.append(message(d.note || "No diagnosis.")); return c; }
  const f = d.diagnosis.findings || [];
  const base = d.diagnosis.baseline || {}, fin = d.diagnosis.final || {};
  c.append(h("ul", { class: "findings" }, f.length
    ? f.map((x) => h("li", {}, h("strong", {}, x.effect.replaceAll("_", " ")), ": ", x.summary,
      x.delta_bic == null ? "" : h("span", { class: "muted" }, ` (ΔBIC ${fmt(x.delta_bic, 4)})`)))
    : h("li", { class: "clean" }, "The first-order model explains this recording to its noise: no unmodelled physics found.")));
  if (d.diagnosis.mismatch && d.diagnosis.mismatch.where) c.append(h("p", { class: "note" }, `Mismatch: ${d.diagnosis.mismatch.where}.`));
  c.append(h("p", { class: "note" }, `χ²/dof ${fmt(base.chi2_dof, 3)} with ${(base.terms || []).join(", ")}`
    + (f.length ? ` → ${fmt(fin.chi2_dof, 3)} with ${(fin.terms || []).join(", ")}` : "") + "."));
  return c;
}

function certificateCard(run) {
  const c = h("section", { class: "card", "aria-label": "Certificate", id: "certificate" }, h("h2", {}, "Certificate"));
  if (!run.certificate_number) {
    c.append(message(run.certificate_note ? `No certificate: ${run.certificate_note}`
      : run.state === "completed" ? "No certificate issued for this run." : `No certificate: the run is ${run.state}.`));
    return c;
  }
  const status = h("span", { class: "note", "aria-live": "polite" });
  const withdrawn = (run.audit || []).find((a) => a.action === "withdraw");
  c.append(h("p", {}, h("strong", {}, run.certificate_number)),
    ...(withdrawn ? [message(`The statement of conformity on this certificate was withdrawn (${withdrawn.detail}); `
      + "the certificate is kept as issued.")] : []),
    h("p", {},
      h("button", { type: "button", id: "download-json", onclick: async () => {
        try { const data = await downloadJson(`/api/runs/${enc(run.id)}/certificate`, `${run.certificate_number}.json`); status.textContent = `downloaded, sha256 ${data.sha256.slice(0, 12)}…`; }
        catch (err) { status.textContent = `download failed: ${err.message}`; }
      } }, "Download JSON"), " ",
      linkAnchor(h, { id: "pdf-link", target: "_blank", rel: "noopener" }, "Open PDF", `/api/runs/${enc(run.id)}/certificate.pdf`), " ", status),
    h("p", { class: "note", id: "exports" }, "The correction for other tools: ",
      ...[["imucal", "imucal JSON"], ["kalibr", "Kalibr YAML"], ["c-header", "C header"], ["json", "JSON"]].flatMap(([f, label], i) => [
        i ? " · " : "", linkAnchor(h, { download: "", "data-format": f }, label, `/api/runs/${enc(run.id)}/export/${f}`)])));
  return c;
}

async function optional(path, signal) {
  try { return await getJson(path, { signal }); } catch (err) { if (err.name === "AbortError") throw err; return { error: err.message }; }
}

// A drift check's comparison with the unit's last certificate: Δ of each coefficient against
// its limit k·sqrt(u_ref² + u_check² + u_rep²).
async function driftCard(run, signal) {
  const c = h("section", { class: "card span", "aria-label": "Drift check", id: "drift-result" }, h("h2", {}, "Drift against the last certificate"));
  let checks;
  try { checks = await getJson(`/api/drift/checks?unit_serial=${enc(run.unit_serial)}&limit=1000`, { signal }); }
  catch (err) { if (err.name === "AbortError") throw err; c.append(message(`Not available: ${err.message}`)); return c; }
  const d = checks.find((x) => x.run_id === run.id);
  if (!d) { c.append(message("No comparison stored for this run.")); return c; }
  const r = d.result;
  if (r.status !== "compared") { c.append(message(r.error || r.status)); return c; }
  c.querySelector("h2").append(" ", badge(d.flagged ? "flagged" : "ok"));
  c.append(h("p", { class: "note" }, `Against ${d.reference_certificate || r.reference_number}; limit = ${r.k}·√(u_ref² + u_check² + u_rep²) per coefficient; `
    + `an unchanged unit is flagged with probability ${fmt(100 * r.false_alarm_probability, 2)} %. Largest |Δ|/limit ${fmt(r.max_ratio, 3)}.`),
  table(null, ["Coefficient", "Unit", "Certificate", "Check", "Δ", "Limit", "|Δ|/limit", ""],
    r.coefficients.map((x) => [x.name, x.unit.replace("m/s2", "m/s²"), fmt(x.reference, 7), fmt(x.check, 7), fmt(x.delta, 3), fmt(x.limit, 3),
      fmt(Math.abs(x.delta) / x.limit, 3), badge(x.exceeded ? "flagged" : "ok")]), [2, 3, 4, 5, 6]));
  return c;
}

async function renderResults(box, run, signal) {
  box.replaceChildren();
  const grid = h("div", { class: "grid wide" });
  if (run.n_samples) box.append(h("p", { class: "note", id: "raw-recording" }, "Raw recording as stored: ",
    linkAnchor(h, { download: "", "data-part": "csv" }, "samples (CSV)", `/api/runs/${enc(run.id)}/recording/csv`), " · ",
    linkAnchor(h, { download: "", "data-part": "sidecar" }, "sidecar (JSON)", `/api/runs/${enc(run.id)}/recording/sidecar`)));
  box.append(grid);
  if (run.kind === "drift_check") grid.append(await driftCard(run, signal));
  if (run.calibration) grid.append(fitCard(run.calibration));
  const diag = await optional(`/api/runs/${enc(run.id)}/diagnosis`, signal);
  if (!run.calibration) {
    grid.append(card("Result", message(run.error ? `The run ended ${run.state}: ${run.error}` : `The run ended ${run.state} without a fit.`)));
    if (!diag.error) grid.append(diagnosisCard(diag));
    return;
  }
  if (run.kind !== "drift_check") {
    grid.append(certificateCard(run));
    grid.append(conformityCard(run));
  }
  const [gc, rs, al] = await Promise.all(["g-check", "residuals", "allan"].map((p) => optional(`/api/runs/${enc(run.id)}/plots/${p}`, signal)));
  grid.append(gc.error ? card("|g| check", message(gc.error)) : gCard(gc, run.id, run.calibration.channel_unit));
  grid.append(rs.error ? card("Residuals", message(rs.error)) : residualCard(rs));
  grid.append(al.error ? card("Allan deviation", message(al.error)) : allanCard(al, run.calibration));
  grid.append(diag.error ? card("Diagnosis", message(diag.error)) : diagnosisCard(diag));
}

export async function runView(view, runId, session, signal) {
  let run = await getJson(`/api/runs/${enc(runId)}`, { signal });
  view.append(h("div", { class: "page-head" }, h("h1", {}, run.kind === "drift_check" ? "Drift check " : "Run ", h("span", { class: "mono" }, run.id)),
    h("span", { class: "muted" }, "unit ", h("a", { href: `#/units/${enc(run.unit_serial)}` }, run.unit_serial), ` · ${run.procedure} · ${when(run.started_at || run.created_at)}`,
      run.started_by ? h("span", { id: "run-started-by" }, ` · started by ${run.started_by}`) : null)));
  const banner = verdictBanner();
  view.append(banner.el);
  banner.show(run);
  const status = h("p", { class: "note", "aria-live": "polite" });
  const post = (action, done, then) => async () => {
    try { await postJson(`/api/runs/${enc(runId)}/${action}`); status.textContent = done; if (then) then(); }
    catch (err) { status.textContent = `${action[0].toUpperCase()}${action.slice(1)} failed: ${err.message}`; }
  };
  // A resumed run is live again: draw the page anew to follow its events.
  const reload = () => window.dispatchEvent(new HashChangeEvent("hashchange"));
  const live = liveCard(run, session, {
    abort: post("abort", "Abort requested."),
    pause: post("pause", "Pause requested: the table holds; the window in progress is recorded again on continue."),
    resume: post("resume", "Resume requested.", () => { if (run.state === "interrupted") reload(); }),
  });
  const results = h("div", { id: "results" });
  const winBody = h("tbody");
  const winCard = h("section", { class: "card span", "aria-label": "Completed windows", id: "windows", hidden: true },
    h("h2", {}, "Completed windows"), h("p", { class: "note" }, "Each window's values as it completes: its channel means in the recording's units."),
    h("div", { class: "table-wrap" }, h("table", {},
      h("thead", {}, h("tr", {}, ["#", "Label", "Kind", "Table pose", "Samples", "Channel means"].map((c, i) => h("th", { scope: "col", class: [0, 3, 4, 5].includes(i) ? "num" : null }, c)))),
      winBody)));
  const audit = auditCard();
  audit.show(run);
  const signalView = signalCard();
  view.append(h("div", { class: "grid" }, live.el, signalView.el, winCard, audit.el), status, results);
  const seen = new Set();
  const addWindow = (w) => {
    if (seen.has(w.index)) return;
    seen.add(w.index);
    winCard.hidden = false;
    winBody.prepend(h("tr", {}, h("td", { class: "num" }, String(w.index + 1)), h("td", {}, w.label), h("td", {}, w.kind),
      h("td", { class: "num" }, (w.pose_deg || []).map((a) => `${Number(a).toFixed(1)}°`).join("  ")),
      h("td", { class: "num" }, String(w.n_samples)),
      h("td", { class: "num window-means" }, Object.entries(w.means || {}).filter(([, v]) => Number.isFinite(v)).map(([c, v]) => `${c} ${fmt(v, 6)}`).join("  "))));
  };
  for (const w of run.windows || []) addWindow(w);
  const finish = async () => {
    run = await getJson(`/api/runs/${enc(runId)}`, { signal });
    for (const w of run.windows || []) addWindow(w);
    if (LIVE.has(run.state)) live.update({ state: run.state, progress: run.progress, phase: run.phase || undefined });
    else live.final(run);
    banner.show(run);
    audit.show(run);
    await renderResults(results, run, signal);
  };
  if (!LIVE.has(run.state)) { await finish(); return; }
  results.append(message("Results appear here when the run ends."));
  try {
    await followEvents(runId, (name, data) => {
      if (name === "progress" || name === "state") live.update(data);
      if (name === "window") addWindow(data);
      if (name === "signal") signalView.update(data);
      if (name === "gap") live.addGap(data);
      if (name === "finished") live.update({ state: data.state, progress: data.state === "completed" ? 1 : undefined });
      if (name === "shutdown") status.textContent = "The service is restarting: the run will be stored interrupted and can be resumed.";
    }, signal);
  } catch (err) {
    if (err.name === "AbortError") return;
    status.textContent = `Live stream unavailable (${err.message}); polling instead.`;
  }
  // The stream ended (or failed): poll until the stored run is final and its results are in.
  // A run's final state is stored with its certificate (or drift check) in one transaction.
  while (!signal.aborted) {
    try { run = await getJson(`/api/runs/${enc(runId)}`, { signal }); }
    catch (err) {
      if (err.name === "AbortError") return;
      status.textContent = `Service unreachable (${err.message}); retrying.`;
      await new Promise((r) => setTimeout(r, POLL_MS * 2));
      continue;
    }
    live.update({ state: run.state, progress: run.progress, phase: run.phase || undefined });
    if (!LIVE.has(run.state)) break;
    await new Promise((r) => setTimeout(r, POLL_MS));
  }
  if (!signal.aborted) await finish();
}
