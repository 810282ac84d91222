// The dashboard shell: token box, role, bench status, and the hash router
// (#/ overview, #/units, #/units/SERIAL, #/runs/ID).

import { getJson, getToken, setToken } from "./api.js";
import { overviewView, unitsView } from "./view_overview.js";
import { unitView } from "./view_unit.js";
import { runView } from "./view_run.js";

export const session = { role: "none", controller: null, publicRead: null };

function notice(text, kind = "error") {
  const n = document.getElementById("notice");
  if (!text) { n.hidden = true; n.textContent = ""; return; }
  n.hidden = false; n.textContent = text; n.className = `notice${kind === "info" ? " info" : ""}`;
}

const NEED_TOKEN = "This lab needs a token to read: paste a viewer or operator token above.";

async function refreshRole() {
  const roleEl = document.getElementById("role");
  if (!getToken() && session.publicRead === false) {
    // no token and reads are not public: say so without a request that can only fail
    session.role = "none"; roleEl.textContent = "no access"; notice(NEED_TOKEN);
    return;
  }
  try {
    const who = await getJson("/api/whoami");
    session.role = who.role;
    roleEl.textContent = who.role === "anonymous" ? "read-only (no token)" : who.role;
    notice("");
  } catch (err) {
    session.role = "none";
    roleEl.textContent = "no access";
    notice(err.status === 401
      ? (getToken() ? "That token is unknown or revoked: paste a valid one." : NEED_TOKEN)
      : `Cannot reach the service: ${err.message}`);
  }
}

async function refreshBench() {
  try {
    const hl = await getJson("/api/health");
    session.publicRead = hl.public_read;
    const busy = hl.busy_run ? ` · busy: run ${hl.busy_run}` : " · idle";
    document.getElementById("bench").textContent =
      `bench ${hl.bench}${hl.simulated ? " (simulated)" : ""}${busy}${hl.database_ok ? "" : " · DATABASE UNREACHABLE"}`;
    const cfg = document.getElementById("config-notice");
    const problems = hl.certificate_problems || [];
    if (cfg) {
      cfg.hidden = !problems.length;
      cfg.className = hl.certificates_blocked ? "notice" : "notice info";
      cfg.textContent = problems.length ? `${hl.certificates_blocked ? "No certificates can be issued: " : "Certificates are incomplete: "}${problems.join("; ")}.` : "";
    }
  } catch { document.getElementById("bench").textContent = "service unreachable"; }
}

async function route() {
  if (session.controller) session.controller.abort();
  session.controller = new AbortController();
  const signal = session.controller.signal;
  const view = document.getElementById("view");
  const hash = decodeURIComponent(location.hash.replace(/^#/, "")) || "/";
  const parts = hash.split("/").filter(Boolean);
  view.replaceChildren();
  try {
    if (session.role === "none" && parts.length) view.append(Object.assign(document.createElement("p"), { className: "muted", textContent: "Paste a token above to see this page." }));
    else if (parts[0] === "units" && parts[1]) await unitView(view, parts.slice(1).join("/"), signal, session);
    else if (parts[0] === "units") await unitsView(view, signal);
    else if (parts[0] === "runs" && parts[1]) await runView(view, parts[1], session, signal);
    else await overviewView(view, session, signal);
  } catch (err) {
    if (err.name === "AbortError") return;
    view.replaceChildren(Object.assign(document.createElement("p"), { className: "muted", textContent: `Could not load this page: ${err.message}` }));
  }
  view.focus({ preventScroll: true });
}

function setup() {
  const form = document.getElementById("token-form");
  const input = document.getElementById("token-input");
  input.value = getToken();
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    setToken(input.value.trim());
    await refreshRole();
    route();
  });
  document.getElementById("token-clear").addEventListener("click", async () => {
    setToken(""); input.value = "";
    await refreshRole();
    route();
  });
  window.addEventListener("hashchange", route);
  setInterval(refreshBench, 10000);
  refreshBench().then(refreshRole).then(route);
}

setup();
