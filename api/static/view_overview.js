// Overview (start a run, recent runs, units) and the units list.

import { getJson, postJson } from "./api.js";
import { badge, card, h, message, outcomeCell, progressBar, table, when } from "./dom.js";
import { planForm } from "./plan_form.js";
import { uploadCard } from "./view_upload.js";

const PROCEDURES = ["static-12", "rate-1axis", "oscillation-2axis", "planned-static", "planned-tumble"];
const LIVE = new Set(["queued", "running", "paused", "suspended"]);
const RUN_STATES = ["queued", "running", "paused", "suspended", "interrupted", "completed", "failed", "error", "aborted"];
const REFRESH_MS = 3000;

function unitLink(serial) { return h("a", { href: `#/units/${encodeURIComponent(serial)}` }, serial); }
function runLink(id) { return h("a", { href: `#/runs/${encodeURIComponent(id)}`, class: "mono" }, id); }

export function unitsTable(units) {
  if (!units.length) return message("No units yet: start a run to register one.");
  return table("Units calibrated on this service", ["Serial", "Model", "Runs", "Last certificate", "Drift"],
    units.map((u) => [
      unitLink(u.serial), u.model || "–", String(u.n_runs), u.last_certificate || "–",
      u.last_drift_flagged === null || u.last_drift_flagged === undefined ? "not checked"
        : u.last_drift_flagged ? badge("flagged") : badge("ok"),
    ]), [2]);
}

function runsTable(runs) {
  if (!runs.length) return message("No runs yet.");
  return table("Most recent first", ["Run", "Unit", "Procedure", "State", "Outcome", "Progress", "Started"],
    runs.map((r) => [
      runLink(r.id), unitLink(r.unit_serial), r.kind === "drift_check" ? `${r.procedure} (drift check)` : r.procedure, badge(r.state),
      outcomeCell(r),
      h("div", { class: "progress-line" }, progressBar(r.progress, false, `progress of run ${r.id}`), `${Math.round(r.progress * 100)} %`),
      when(r.started_at || r.created_at),
    ]));
}

function startForm(session) {
  const serial = h("input", { id: "start-serial", name: "unit_serial", required: true, placeholder: "SN-0001",
    pattern: "[A-Za-z0-9][A-Za-z0-9._\\-]{0,63}", title: "letters, digits, '.', '_', '-'" });
  const proc = h("select", { id: "start-procedure", name: "procedure" }, PROCEDURES.map((p) => h("option", { value: p }, p)));
  const dwell = h("input", { id: "start-dwell", name: "dwell_s", type: "number", min: "0.1", max: "86400", step: "any",
    placeholder: "from a noise window", title: "static dwell per pose (s); empty: the service setting, else a noise window decides" });
  const bench = h("select", { id: "start-bench", name: "bench" }, h("option", { value: "" }, "any free bench"));
  const status = h("p", { class: "note", "aria-live": "polite" });
  const pv = h("p", { class: "preview", id: "start-preview", "aria-live": "polite" }, "");
  const poses = h("p", { class: "note", id: "start-poses" }, "");
  const observable = h("p", { class: "note", id: "start-observability" }, "");
  const warn = h("p", { class: "note warning", id: "start-warning", role: "alert" }, "");
  const button = h("button", { type: "submit", id: "start-run" }, "Start run");
  let planned = null; // the plan's start body (plan_form.js) while the form uses it
  const showPreview = async () => {
    try {
      const q = new URLSearchParams();
      if (serial.value.trim() && serial.checkValidity()) q.set("unit_serial", serial.value.trim());
      if (dwell.value && dwell.checkValidity()) q.set("dwell_s", dwell.value);
      // a plan's design is previewed with its parameters (all its passes), as Start run will send them
      const plan = planned && proc.value === planned.procedure && Number(dwell.value) === planned.dwell_s ? planned : null;
      if (plan) q.set("parameters", JSON.stringify(plan.parameters));
      const p = await getJson(`/api/procedures/${encodeURIComponent(proc.value)}/preview?${q}`);
      warn.textContent = (p.warnings || []).map((w) => `Unit ${serial.value.trim()}: ${w}.`).join(" ");
      const dwellText = p.dwell_s == null ? "dwell decided by a noise window at the start (estimate assumes a provisional one)" : `dwell ${p.dwell_s} s per pose (${p.dwell_source})`;
      const mins = (s) => (s >= 90 ? `${Math.round(s / 60)} min` : `${Math.round(s)} s`);
      const passes = plan && plan.parameters.repeats ? ` (the plan's ${plan.parameters.repeats} passes)` : "";
      pv.textContent = `${p.n_poses} poses${passes}, ${p.n_windows} windows, ${dwellText}; about ${mins(p.wall_duration_s)}`
        + (Math.abs(p.wall_duration_s - p.duration_s) > 1 ? ` (${mins(p.duration_s)} on the bench clock)` : "")
        + (p.problems.length ? ` · cannot run: ${p.problems.join("; ")}` : "");
      const deg = (a) => `(${a.map((x) => `${+x.toFixed(1)}°`).join(", ")})`;
      poses.textContent = `Poses (table angles, outer axis first): ${p.poses_deg.map(deg).join(" · ")}`;
      const not = Object.entries(p.not_observable || {});
      observable.textContent = `Determined by this motion: ${p.observable.join(", ") || "nothing"}`
        + (not.length ? `; not: ${not.map(([t, why]) => `${t} (${why})`).join("; ")}` : "");
    } catch (err) { pv.textContent = `No preview: ${err.message}`; poses.textContent = ""; observable.textContent = ""; }
  };
  const loadBenches = async () => {
    try {
      const benches = await getJson("/api/benches");
      bench.replaceChildren(h("option", { value: "" }, "any free bench"),
        ...benches.map((b) => h("option", { value: b.name }, `${b.name} (${b.state})`)));
    } catch (err) { /* the bench stays "any free bench" */ }
  };
  if (session.role !== "none") {
    proc.addEventListener("change", showPreview);
    serial.addEventListener("change", showPreview);
    dwell.addEventListener("change", showPreview);
    showPreview();
    loadBenches();
  }
  // the planner (plan_form.js): its start body is what Start run sends while the procedure and dwell are the plan's
  const { box: planBox, button: planButton, detach } = planForm((start) => {
    planned = start;
    if (start) {
      proc.value = start.procedure;
      dwell.value = String(start.dwell_s);
    }
    showPreview(); // with the plan's parameters, or without them once the plan is gone
  });
  const keepPlan = () => {
    if (!planned) return;
    const why = proc.value !== planned.procedure ? `the procedure is now ${proc.value}`
      : Number(dwell.value) !== planned.dwell_s ? `the dwell is now ${dwell.value || "empty"} s` : "";
    if (why) { planned = null; detach(`Start run no longer uses the plan: ${why}.`); }
  };
  proc.addEventListener("change", keepPlan);
  dwell.addEventListener("change", keepPlan);
  const details = h("a", { href: "#/units", id: "unit-details", title: "customer, model, date of receipt, nominal values: what the certificate states" }, "unit registration…");
  serial.addEventListener("input", () => { details.href = serial.value.trim() ? `#/units/${encodeURIComponent(serial.value.trim())}` : "#/units"; });
  const form = h("form", { class: "start", "aria-label": "start a run" },
    h("label", { for: "start-serial" }, "Unit serial", serial, details),
    h("label", { for: "start-procedure" }, "Procedure", proc),
    h("label", { for: "start-dwell" }, "Dwell (s)", dwell),
    h("label", { for: "start-bench" }, "Bench", bench),
    planBox,
    button);
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    button.disabled = true; status.textContent = "Starting…";
    try {
      const body = { unit_serial: serial.value.trim(), procedure: proc.value };
      if (dwell.value) body.dwell_s = Number(dwell.value);
      if (bench.value) body.bench = bench.value;
      if (planned && proc.value === planned.procedure) Object.assign(body, { dwell_s: planned.dwell_s, parameters: planned.parameters });
      const created = await postJson("/api/runs", body);
      location.hash = `#/runs/${encodeURIComponent(created.id)}`;
    } catch (err) {
      status.textContent = `Not started: ${err.message}`;
      button.disabled = false;
    }
  });
  const canStart = session.role === "operator" || session.role === "admin";
  if (!canStart) {
    for (const c of [serial, proc, dwell, bench, button, planButton]) c.disabled = true;
    status.textContent = "Starting runs needs an operator token; this view is read-only.";
  }
  return card("Start a run", form, pv, poses, observable, warn, status);
}

export async function overviewView(view, session, signal) {
  view.append(h("div", { class: "page-head" }, h("h1", {}, "Bench overview")));
  const runsBox = h("div", {}, message("Loading runs…"));
  const unitsBox = h("div", {}, message("Loading units…"));
  // search (text in the run id or serial), state filter and pages of PAGE runs
  const PAGE = 20;
  let offset = 0;
  const search = h("input", { id: "runs-search", type: "search", placeholder: "run id or serial", "aria-label": "search runs", maxlength: "64" });
  const stateSel = h("select", { id: "runs-state", "aria-label": "filter runs by state" },
    h("option", { value: "" }, "any state"), ...RUN_STATES.map((st) => h("option", { value: st }, st)));
  const prev = h("button", { type: "button", class: "ghost", id: "runs-prev", disabled: true }, "Newer");
  const next = h("button", { type: "button", class: "ghost", id: "runs-next", disabled: true }, "Older");
  const pageNote = h("span", { class: "note", id: "runs-page" });
  const runsQuery = () => {
    const q = new URLSearchParams({ limit: String(PAGE + 1), offset: String(offset) });
    if (search.value.trim()) q.set("q", search.value.trim());
    if (stateSel.value) q.set("state", stateSel.value);
    return `/api/runs?${q}`;
  };
  const showRuns = (runs) => {
    prev.disabled = offset === 0;
    next.disabled = runs.length <= PAGE;
    const shown = runs.slice(0, PAGE);
    pageNote.textContent = shown.length ? `runs ${offset + 1}–${offset + shown.length}` : "";
    const filtered = offset || search.value.trim() || stateSel.value;
    runsBox.replaceChildren(shown.length || !filtered ? runsTable(shown) : message("No run matches."));
  };
  const reloadRuns = async () => { try { showRuns(await getJson(runsQuery(), { signal })); } catch (err) { if (err.name !== "AbortError") runsBox.replaceChildren(message(`Not available: ${err.message}`)); } };
  let typing = 0;
  search.addEventListener("input", () => { clearTimeout(typing); typing = setTimeout(() => { offset = 0; reloadRuns(); }, 250); });
  stateSel.addEventListener("change", () => { offset = 0; reloadRuns(); });
  prev.addEventListener("click", () => { offset = Math.max(0, offset - PAGE); reloadRuns(); });
  next.addEventListener("click", () => { offset += PAGE; reloadRuns(); });
  view.append(h("div", { class: "grid wide" }, startForm(session), card("Units", unitsBox), uploadCard(session), h("section", { class: "card span", "aria-label": "Runs" }, h("h2", {}, "Runs"),
    h("p", { class: "actions runs-filter" }, search, " ", stateSel, " ", prev, " ", next, " ", pageNote), runsBox)));
  const load = async () => {
    const [runs, units, drift] = await Promise.all([getJson(runsQuery(), { signal }), getJson("/api/units", { signal }),
      getJson("/api/drift", { signal }).catch(() => null)]);
    showRuns(runs);
    const next = drift && drift.enabled && drift.next_run_at
      ? `Nightly drift check of every certified unit, on its bench: next ${when(drift.next_run_at)}${drift.pending_units.length ? ` · waiting: ${drift.pending_units.join(", ")}` : ""}. Run one now from a unit's page.`
      : "No nightly drift check is scheduled (CALBENCH_DRIFT_TIME); run one from a unit's page.";
    const skipped = drift && drift.not_checked && drift.not_checked.length
      ? [h("p", { class: "note", id: "drift-not-checked" }, "Not checked: " + drift.not_checked.map((n) => `${n.unit_serial} (${n.reason})`).join("; "))]
      : [];
    unitsBox.replaceChildren(unitsTable(units), h("p", { class: "note", id: "drift-schedule" }, next), ...skipped);
    return runs.some((r) => LIVE.has(r.state));
  };
  if (session.role === "none") {
    runsBox.replaceChildren(message("Reading needs a token.")); unitsBox.replaceChildren(message("Reading needs a token."));
    return;
  }
  let live = false;
  try { live = await load(); } catch (err) {
    if (err.name === "AbortError") return;
    const why = err.status === 401 || err.status === 403 ? "Reading needs a token." : `Not available: ${err.message}`;
    runsBox.replaceChildren(message(why)); unitsBox.replaceChildren(message(why));
    return;
  }
  const tick = async () => {
    if (signal.aborted) return;
    try { await load(); } catch (err) { if (err.name === "AbortError") return; }
    setTimeout(tick, REFRESH_MS);
  };
  setTimeout(tick, live ? REFRESH_MS : REFRESH_MS * 3);
}

// The units list: search (serial, model or customer) and pages of UNITS_PAGE units.
const UNITS_PAGE = 20;

export async function unitsView(view, signal) {
  view.append(h("div", { class: "page-head" }, h("h1", {}, "Units")));
  let offset = 0;
  const search = h("input", { id: "units-search", type: "search", placeholder: "serial, model or customer", "aria-label": "search units", maxlength: "64" });
  const prev = h("button", { type: "button", class: "ghost", id: "units-prev", disabled: true }, "Previous");
  const next = h("button", { type: "button", class: "ghost", id: "units-next", disabled: true }, "Next");
  const pageNote = h("span", { class: "note", id: "units-page" });
  const box = h("div", { id: "units-list" }, message("Loading units…"));
  const load = async () => {
    const q = new URLSearchParams({ limit: String(UNITS_PAGE + 1), offset: String(offset) });
    if (search.value.trim()) q.set("q", search.value.trim());
    try {
      const units = await getJson(`/api/units?${q}`, { signal });
      prev.disabled = offset === 0;
      next.disabled = units.length <= UNITS_PAGE;
      const shown = units.slice(0, UNITS_PAGE);
      pageNote.textContent = shown.length ? `units ${offset + 1}–${offset + shown.length}` : "";
      box.replaceChildren(shown.length || !(offset || search.value.trim()) ? unitsTable(shown) : message("No unit matches."));
    } catch (err) { if (err.name !== "AbortError") box.replaceChildren(message(`Not available: ${err.message}`)); }
  };
  let typing = 0;
  search.addEventListener("input", () => { clearTimeout(typing); typing = setTimeout(() => { offset = 0; load(); }, 250); });
  prev.addEventListener("click", () => { offset = Math.max(0, offset - UNITS_PAGE); load(); });
  next.addEventListener("click", () => { offset += UNITS_PAGE; load(); });
  view.append(h("section", { class: "card", "aria-label": "Units" },
    h("p", { class: "actions units-filter" }, search, " ", prev, " ", next, " ", pageNote), box));
  await load();
}
