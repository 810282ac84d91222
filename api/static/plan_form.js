// The start form's planner (GET /api/plan): the unit's noise, target uncertainties and the fit
// family in; the planned design, its predicted U per group and table time, and the start body
// of POST /api/runs out. An every-sample plan takes seconds (docs/benchmarks.md): while it is
// computed the box says so and its Plan button waits, the rest of the form stays usable.

import { getJson } from "./api.js";
import { h } from "./dom.js";

const FITS = [
  ["window", "window fit (planned-static)"],
  ["every-sample", "every-sample fit (planned-tumble)"],
  ["best", "the shorter of the two"],
];

function minutes(s) { return s >= 90 ? `${(s / 60).toFixed(1)} min` : `${Math.round(s)} s`; }

function describe(e) {
  const u = e.predicted_U_k2;
  return `${e.procedure}: ${e.parameters.repeats} passes of 12 poses, ${e.parameters.dwell_s} s each, ${e.fit} fit, `
    + `table time ${minutes(e.duration_s)}; predicted U (k=2) bias ${u.bias_ug.toFixed(0)} µg, `
    + `scale ${u.scale_ppm.toFixed(1)} ppm, misalignment ${u.misalignment_urad.toFixed(1)} µrad; `
    + `${e.k_fraction_of_bound.toFixed(2)}× the bound of any motion`;
}

/**
 * The planner's box. `onPlanned(start)` gets the plan's `start` body ({procedure, dwell_s,
 * parameters}), or null when a new plan is asked for or none meets the targets. Returns the
 * box, its Plan button and `detach(why)`, which says the plan is no longer used.
 */
export function planForm(onPlanned) {
  const num = (id, label, value, title) => h("label", { for: id, title }, label, h("input", { id, type: "number", min: "0", step: "any", value }));
  const fit = h("select", { id: "plan-fit", "aria-label": "fit family" }, FITS.map(([v, text]) => h("option", { value: v }, text)));
  const out = h("p", { class: "preview", id: "plan-result", "aria-live": "polite" }, "");
  const notes = h("ul", { class: "note", id: "plan-notes" });
  const button = h("button", { type: "button", id: "plan-run" }, "Plan");
  const box = h("details", { class: "plan", id: "start-plan" }, h("summary", {}, "Plan the procedure for target uncertainties…"),
    num("plan-white", "white noise (µg/√Hz)", "250"), num("plan-wander", "wander (µg)", "40"), num("plan-tau", "its correlation (s)", "200"),
    num("plan-bias", "bias U, k=2 (µg)", "", "empty: no bias target"),
    num("plan-scale", "scale U, k=2 (ppm)", "40"), num("plan-mis", "misalignment U, k=2 (µrad)", "40"),
    num("plan-minutes", "longest table time (min)", "60"),
    h("label", { for: "plan-fit" }, "Fit", fit), button, out, notes);
  const v = (id) => box.querySelector(`#${id}`).value;
  button.addEventListener("click", async () => {
    if (button.disabled) return;
    const q = new URLSearchParams({ white_ug_rt_hz: v("plan-white"), wander_ug: v("plan-wander") || "0", wander_tau_s: v("plan-tau") || "100", fit: fit.value });
    for (const [id, key] of [["plan-bias", "bias_ug"], ["plan-scale", "scale_ppm"], ["plan-mis", "misalignment_urad"], ["plan-minutes", "max_minutes"]]) {
      if (v(id)) q.set(key, v(id));
    }
    onPlanned(null);
    button.disabled = true;
    box.setAttribute("aria-busy", "true");
    notes.replaceChildren();
    const started = Date.now();
    const slow = fit.value !== "window" ? " (the every-sample fit's prediction takes seconds)" : "";
    const tick = () => { out.textContent = `Planning${slow}… ${Math.round((Date.now() - started) / 1000)} s`; };
    tick();
    const ticker = setInterval(tick, 1000);
    try {
      const r = await getJson(`/api/plan?${q}`);
      if (!r.start) {
        out.textContent = `No plan: ${r.problems.join("; ")}`
          + (r.closest ? `. Closest tried: ${describe(r.closest)}.` : "");
        return;
      }
      out.textContent = `${describe(r.plan)}. Start run uses it.`;
      notes.replaceChildren(...r.plan.notes.map((n) => h("li", {}, n)));
      onPlanned(r.start);
    } catch (err) {
      out.textContent = `No plan: ${err.message}`;
    } finally {
      clearInterval(ticker);
      button.disabled = false;
      box.removeAttribute("aria-busy");
    }
  });
  const detach = (why) => { notes.replaceChildren(h("li", { id: "plan-detached" }, why)); };
  return { box, button, detach };
}
