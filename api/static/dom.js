// DOM building without innerHTML (server text is never parsed as HTML), and shared widgets.

export function h(tag, attrs = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (v === undefined || v === null || v === false) continue;
    if (k.startsWith("on")) e.addEventListener(k.slice(2), v);
    else if (k === "class") e.className = v;
    else e.setAttribute(k, v === true ? "" : v);
  }
  for (const c of children.flat()) if (c !== null && c !== undefined && c !== false) e.append(c instanceof Node ? c : String(c));
  return e;
}

export function badge(state) {
  return h("span", { class: `badge ${String(state || "").toLowerCase()}` }, state || "?");
}

// A run's verdict: PASS, FAIL, ERROR or ABORTED, or why a completed fit has none
// ("no conformity statement: no limits are configured for model ADXL335").
export function outcomeCell(run) {
  if (run.outcome) return badge(run.outcome);
  if (run.conformity_note) return h("span", { class: "no-statement" }, run.conformity_note);
  return "–";
}

export function progressBar(fraction, big = false, label = "run progress") {
  const pct = Math.round(Math.max(0, Math.min(1, fraction || 0)) * 100);
  const bar = h("div", { class: `bar${big ? " big" : ""}`, role: "progressbar", "aria-label": label,
    "aria-valuemin": "0", "aria-valuemax": "100", "aria-valuenow": String(pct) });
  const fill = h("span");
  fill.style.width = `${pct}%`;
  bar.append(fill);
  return bar;
}

export function setProgress(bar, fraction) {
  const pct = Math.round(Math.max(0, Math.min(1, fraction || 0)) * 100);
  bar.setAttribute("aria-valuenow", String(pct));
  bar.firstChild.style.width = `${pct}%`;
}

export function when(iso) {
  if (!iso) return "–";
  const d = new Date(iso);
  return Number.isNaN(d.getTime()) ? iso : d.toLocaleString(undefined, { dateStyle: "medium", timeStyle: "short" });
}

export function table(caption, head, rows, numeric = []) {
  return h("div", { class: "table-wrap" },
    h("table", {},
      caption ? h("caption", {}, caption) : null,
      h("thead", {}, h("tr", {}, head.map((c, i) => h("th", { scope: "col", class: numeric.includes(i) ? "num" : null }, c)))),
      h("tbody", {}, rows.map((r) => h("tr", {}, r.map((c, i) => h("td", { class: numeric.includes(i) ? "num" : null }, c)))))));
}

export function card(title, ...body) {
  return h("section", { class: "card", "aria-label": title }, h("h2", {}, title), ...body);
}

export function message(text, kind = "muted") {
  return h("p", { class: kind }, text);
}
