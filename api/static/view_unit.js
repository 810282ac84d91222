// One unit: coefficient trends with ±U bands, its runs, certificates and drift checks.

import { downloadJson, getJson, linkAnchor, postJson, putJson } from "./api.js";
import { badge, card, h, message, outcomeCell, table, when } from "./dom.js";
import { fmt, sparkAxis, sparkline } from "./svgplot.js";
import { fmtU } from "./uncertainty.js";

function trends(hist) {
  const dates = (c) => c.run_index.map((k) => {
    const r = hist.runs[k];
    const t = r && (r.at || r.finished_at || r.started_at);
    return t ? `${new Date(t).toISOString().slice(0, 16).replace("T", " ")} UTC` : "";
  });
  const cs = hist.coefficients.filter((c) => c.value.length);
  if (!cs.length) return message("No calibrated run yet: trends appear after the first fit.");
  const box = h("div", { class: "sparks", id: "trends" });
  for (const c of cs) {
    const last = c.value.length - 1;
    const u = c.U[last];
    box.append(h("figure", { class: "spark", style: "margin:0" },
      h("figcaption", {},
        h("div", { class: "name" }, `${c.label} (${c.unit})`),
        h("div", { class: "value num" }, u == null ? fmt(c.value[last], 6) : fmtU(c.value[last], u))),
      sparkline(c.value, c.U, `${c.label} over ${c.value.length} runs, latest ${fmt(c.value[last], 6)} ${c.unit}`,
        220, 56, c.run_index.map((k) => hist.runs[k].kind === "drift_check"), dates(c)),
      sparkAxis(c.value, c.U, c.unit, dates(c))));
  }
  return h("div", {}, box, h("p", { class: "note" },
    `Each point is one fitted run, oldest left (filled: calibration, open: drift check); the band is U = ${hist.coverage_k}σ, σ the fit's Type A standard uncertainty (the certificate's U adds Type B).`));
}

function certificates(certs, serial) {
  if (!certs.length) return message("No certificate issued yet.");
  return table(null, ["Number", "Run", "Issued", "Download"], certs.map((c) => [
    c.number,
    h("a", { href: `#/runs/${encodeURIComponent(c.run_id)}`, class: "mono" }, c.run_id),
    when(c.issued_at),
    h("span", {},
      h("a", { href: "#", onclick: (ev) => { ev.preventDefault(); downloadJson(`/api/runs/${encodeURIComponent(c.run_id)}/certificate`, `${c.number}.json`); } }, "JSON"),
      " · ",
      linkAnchor(h, { target: "_blank", rel: "noopener" }, "PDF", `/api/runs/${encodeURIComponent(c.run_id)}/certificate.pdf`)),
  ]));
}

function driftControls(serial, drift, session, hasCertificate) {
  const canRun = session && (session.role === "operator" || session.role === "admin");
  const status = h("span", { class: "note", "aria-live": "polite", id: "drift-status" });
  const next = drift && drift.enabled && drift.next_run_at
    ? `Next nightly check: ${new Date(drift.next_run_at).toLocaleString(undefined, { dateStyle: "medium", timeStyle: "short" })} (${drift.procedure}, ${drift.dwell_s} s dwell, limits at k = ${drift.k}).`
    : "No nightly drift check is scheduled on this service (CALBENCH_DRIFT_TIME).";
  const button = h("button", { type: "button", id: "drift-run", disabled: !canRun || !hasCertificate,
    title: !hasCertificate ? "a drift check compares with the unit's last certificate: calibrate it first" : canRun ? "" : "needs an operator token",
    onclick: async () => {
      try { await postJson("/api/drift/run", { unit_serial: serial }); status.textContent = "Drift check queued: it runs as soon as the bench is free."; }
      catch (err) { status.textContent = `Not queued: ${err.message}`; }
    } }, "Check drift now");
  return h("div", {}, h("p", { class: "note", id: "drift-next" }, next), h("p", {}, button, " ", status));
}

function driftChecks(checks) {
  if (!checks.length) return message("No drift check yet.");
  return table(null, ["Checked", "Against", "Result", "Largest |Δ| / limit"], checks.slice().reverse().map((d) => [
    when(d.checked_at), d.reference_certificate || "–",
    d.result.status === "compared" ? (d.flagged ? badge("flagged") : badge("ok")) : h("span", { class: "muted" }, d.result.error || d.result.status || "–"),
    d.result.max_ratio == null ? "–" : fmt(d.result.max_ratio, 3),
  ]), [3]);
}

const G0 = 9.80665; // datasheets give sensitivity per standard gravity

// What the laboratory states about the unit on its certificates (ISO/IEC 17025 7.8.2.1 e, g, h).
function registrationCard(serial, u, session, onSaved) {
  const canEdit = session && (session.role === "operator" || session.role === "admin");
  const unit = u.channel_unit || "V";
  const field = (id, label, attrs, value) => {
    const input = h(attrs.rows ? "textarea" : "input", { id, name: id, ...attrs, disabled: !canEdit });
    if (value !== null && value !== undefined) input.value = String(value);
    return [h("label", { for: id }, label, input), input];
  };
  const [lModel, model] = field("reg-model", "Model", { maxlength: 200, placeholder: "ADXL325" }, u.model);
  const [lDesc, desc] = field("reg-description", "Description", { maxlength: 200, placeholder: "triaxial accelerometer" }, u.description);
  const [lCust, cust] = field("reg-customer", "Customer", { maxlength: 200 }, u.customer_name);
  const [lAddr, addr] = field("reg-address", "Customer address", { maxlength: 500 }, u.customer_address);
  const [lRecv, recv] = field("reg-received", "Date of receipt", { type: "date" }, u.received_on);
  const sensValue = u.nominal_scale == null ? null : +(u.nominal_scale * G0 * (unit === "V" ? 1000 : 1)).toPrecision(6);
  const sensUnit = unit === "V" ? "mV/g" : `${unit}/g`;
  const [lSens, sens] = field("reg-sensitivity", `Nominal sensitivity (${sensUnit})`, { type: "number", step: "any", inputmode: "decimal" }, sensValue);
  const [lZero, zero] = field("reg-zero", `Nominal zero-g output (${unit})`, { type: "number", step: "any", inputmode: "decimal" }, u.nominal_bias);
  const [lCond, cond] = field("reg-condition", "Condition as received", { maxlength: 500, placeholder: "no visible damage" }, u.condition);
  const status = h("span", { class: "note", "aria-live": "polite", id: "reg-status" });
  const save = h("button", { type: "submit", id: "reg-save", disabled: !canEdit }, "Save");
  const form = h("form", { class: "start", id: "registration", "aria-label": "unit registration" },
    lModel, lDesc, lCust, lAddr, lRecv, lSens, lZero, lCond, save, status);
  const text = (x) => (x.value.trim() === "" ? null : x.value.trim());
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    const body = { model: text(model), description: text(desc), customer_name: text(cust), customer_address: text(addr),
      received_on: text(recv), condition: text(cond),
      nominal_scale: sens.value === "" ? null : Number(sens.value) / (unit === "V" ? 1000 : 1) / G0,
      nominal_bias: zero.value === "" ? null : Number(zero.value) };
    try { await putJson(`/api/units/${encodeURIComponent(serial)}`, body); status.textContent = "Saved: the next certificates state these."; if (onSaved) onSaved(); }
    catch (err) { status.textContent = `Not saved: ${err.message}`; }
  });
  return h("section", { class: "card span", "aria-label": "Registration", id: "unit-registration" }, h("h2", {}, "Registration (on the certificate)"),
    form, canEdit ? null : message("Editing the registration needs an operator token."));
}

export async function unitView(view, serial, signal, session) {
  const enc = encodeURIComponent(serial);
  const known = await getJson("/api/units", { signal });
  if (!known.some((x) => x.serial === serial)) {
    const state = h("span", { class: "muted", id: "unit-state" }, "not registered yet");
    view.append(h("div", { class: "page-head" }, h("h1", {}, `Unit ${serial}`), state),
      h("div", { class: "grid wide" }, registrationCard(serial, {}, session, () => { state.textContent = "registered: no run yet"; })));
    return;
  }
  const [hist, series, drift] = await Promise.all([
    getJson(`/api/units/${enc}/history`, { signal }),
    getJson(`/api/units/${enc}/plots/history`, { signal }),
    getJson("/api/drift", { signal }).catch(() => null),
  ]);
  const u = hist.unit;
  view.append(h("div", { class: "page-head" },
    h("h1", {}, `Unit ${u.serial}`),
    h("span", { class: "muted" }, [u.model, u.channel_unit && `channels in ${u.channel_unit}`, u.bench && `bench ${u.bench}`].filter(Boolean).join(" · ")),
    u.last_drift_flagged ? badge("flagged") : null));
  const runs = hist.runs.slice().reverse();
  view.append(h("div", { class: "grid wide" },
    h("section", { class: "card span", "aria-label": "Coefficient trends" }, h("h2", {}, "Coefficient trends"), trends(series)),
    card("Runs", runs.length ? table(null, ["Run", "Procedure", "State", "Outcome", "Finished", "Certificate"], runs.map((r) => [
      h("a", { href: `#/runs/${encodeURIComponent(r.id)}`, class: "mono" }, r.id),
      r.kind === "drift_check" ? `${r.procedure} (drift check)` : r.procedure, badge(r.state), outcomeCell(r),
      when(r.finished_at), r.certificate_number || "–",
    ])) : message("No runs.")),
    registrationCard(serial, u, session),
    card("Certificates", certificates(hist.certificates, serial)),
    card("Drift checks", driftControls(serial, drift, session, hist.certificates.length > 0), driftChecks(hist.drift_checks))));
}
