// One unit: coefficient trends with ±U bands, its runs, certificates and drift checks.

import { downloadJson, getJson, linkAnchor } from "./api.js";
import { badge, card, h, message, table, when } from "./dom.js";
import { fmt, sparkline } from "./svgplot.js";

function trends(hist) {
  const cs = hist.coefficients.filter((c) => c.value.length);
  if (!cs.length) return message("No calibrated run yet: trends appear after the first fit.");
  const box = h("div", { class: "sparks", id: "trends" });
  for (const c of cs) {
    const last = c.value.length - 1;
    const u = c.U[last];
    box.append(h("figure", { class: "spark", style: "margin:0" },
      h("figcaption", {},
        h("div", { class: "name" }, `${c.label} (${c.unit})`),
        h("div", { class: "value num" }, `${fmt(c.value[last], 6)}${u == null ? "" : ` ± ${fmt(u, 2)}`}`)),
      sparkline(c.value, c.U, `${c.label} over ${c.value.length} runs, latest ${fmt(c.value[last], 6)} ${c.unit}`,
        220, 56, c.run_index.map((k) => hist.runs[k].kind === "drift_check"))));
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

function driftChecks(checks) {
  if (!checks.length) return message("No drift check yet.");
  return table(null, ["Checked", "Against", "Result", "Largest |Δ| / limit"], checks.slice().reverse().map((d) => [
    when(d.checked_at), d.reference_certificate || "–",
    d.result.status === "compared" ? (d.flagged ? badge("flagged") : badge("ok")) : h("span", { class: "muted" }, d.result.error || d.result.status || "–"),
    d.result.max_ratio == null ? "–" : fmt(d.result.max_ratio, 3),
  ]), [3]);
}

export async function unitView(view, serial, signal) {
  const enc = encodeURIComponent(serial);
  const [hist, series] = await Promise.all([
    getJson(`/api/units/${enc}/history`, { signal }),
    getJson(`/api/units/${enc}/plots/history`, { signal }),
  ]);
  const u = hist.unit;
  view.append(h("div", { class: "page-head" },
    h("h1", {}, `Unit ${u.serial}`),
    h("span", { class: "muted" }, [u.model, u.channel_unit && `channels in ${u.channel_unit}`, u.bench && `bench ${u.bench}`].filter(Boolean).join(" · ")),
    u.last_drift_flagged ? badge("flagged") : null));
  const runs = hist.runs.slice().reverse();
  view.append(h("div", { class: "grid wide" },
    h("section", { class: "card span", "aria-label": "Coefficient trends" }, h("h2", {}, "Coefficient trends"), trends(series)),
    card("Runs", runs.length ? table(null, ["Run", "Procedure", "State", "Finished", "Certificate"], runs.map((r) => [
      h("a", { href: `#/runs/${encodeURIComponent(r.id)}`, class: "mono" }, r.id),
      r.kind === "drift_check" ? `${r.procedure} (drift check)` : r.procedure, badge(r.state),
      when(r.finished_at), r.certificate_number || "–",
    ])) : message("No runs.")),
    card("Certificates", certificates(hist.certificates, serial)),
    card("Drift checks", driftChecks(hist.drift_checks))));
}
