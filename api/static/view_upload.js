// Analyse a recording from the page: the CSV and its sidecar go to POST /api/recordings, which
// fits and diagnoses them (nothing stored); the fit and the findings are shown here.

import { postForm } from "./api.js";
import { card, h, message } from "./dom.js";

function fitSummary(cal) {
  const num = (x) => Number(x).toPrecision(6);
  const k = cal.scale_matrix || [];
  return h("dl", { class: "facts", id: "upload-fit" },
    h("dt", {}, "unit"), h("dd", {}, `${cal.unit || "–"} (${cal.procedure || "?"}, channels in ${cal.channel_unit || "?"})`),
    h("dt", {}, "bias"), h("dd", { id: "upload-bias", class: "mono" }, (cal.bias || []).map(num).join("  ")),
    h("dt", {}, "scale K (diagonal)"), h("dd", { id: "upload-scale", class: "mono" }, k.map((row, i) => num(row[i])).join("  ")));
}

function diagnosisSummary(result) {
  if (!result.diagnosis) return message(`No diagnosis: ${result.diagnosis_error || "not available"}`);
  const findings = result.diagnosis.findings || [];
  return h("p", { id: "upload-findings" }, findings.length
    ? `Diagnosis: ${findings.length} finding${findings.length > 1 ? "s" : ""}: ${findings.map((f) => f.effect || f.name || "?").join(", ")}`
    : "Diagnosis: no finding");
}

export function uploadCard(session) {
  const csv = h("input", { id: "upload-csv", type: "file", accept: ".csv,text/csv", required: true });
  const sidecar = h("input", { id: "upload-sidecar", type: "file", accept: ".json,application/json", required: true });
  const button = h("button", { type: "submit", id: "upload-run" }, "Analyse");
  const out = h("div", { id: "upload-result", "aria-live": "polite" });
  const form = h("form", { class: "start", "aria-label": "analyse a recording" },
    h("label", { for: "upload-csv" }, "Recording (CSV)", csv),
    h("label", { for: "upload-sidecar" }, "Its sidecar (JSON)", sidecar),
    button);
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    const body = new FormData();
    body.append("recording", csv.files[0]);
    body.append("sidecar", sidecar.files[0]);
    button.disabled = true;
    out.replaceChildren(message("Fitting and diagnosing…"));
    try {
      const result = await postForm("/api/recordings", body);
      out.replaceChildren(fitSummary(result.calibration), diagnosisSummary(result));
    } catch (err) {
      out.replaceChildren(message(`Not analysed: ${err.message}`, "error"));
    } finally { button.disabled = false; }
  });
  if (!(session.role === "operator" || session.role === "admin")) {
    for (const c of [csv, sidecar, button]) c.disabled = true;
    out.replaceChildren(message("Analysing a recording needs an operator token."));
  }
  return card("Analyse a recording", form, out);
}
