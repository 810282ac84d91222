// Talking to the calbench JSON API: the pasted token, JSON calls, the live event stream.

const TOKEN_KEY = "calbench.token";

export function getToken() {
  try { return localStorage.getItem(TOKEN_KEY) || ""; } catch { return ""; }
}

export function setToken(value) {
  try {
    if (value) localStorage.setItem(TOKEN_KEY, value); else localStorage.removeItem(TOKEN_KEY);
  } catch { /* storage disabled: the token lives for this page only */ }
}

function headers(extra = {}) {
  const h = { Accept: "application/json", ...extra };
  const t = getToken();
  if (t) h.Authorization = `Bearer ${t}`;
  return h;
}

/** An API error with the HTTP status and the server's own message. */
export class ApiError extends Error {
  constructor(status, message) { super(message); this.status = status; }
}

async function failure(resp) {
  let detail = resp.statusText;
  try {
    const body = await resp.json();
    if (typeof body.detail === "string") detail = body.detail;
    else if (Array.isArray(body.detail)) detail = body.detail.map((d) => `${(d.loc || []).join(".")}: ${d.msg}`).join("; ");
  } catch { /* not JSON */ }
  return new ApiError(resp.status, `${resp.status} ${detail}`);
}

// The last answer to each path with its ETag: the next read of the path sends it back as
// If-None-Match and takes a 304 (no body) as that answer, so a document the page polls is
// sent again only when it changed.
const answers = new Map();
const MAX_ANSWERS = 64;

export async function getJson(path, { signal } = {}) {
  const known = answers.get(path);
  const resp = await fetch(path, { headers: headers(known ? { "If-None-Match": known.etag } : {}), signal, cache: "no-store" });
  if (resp.status === 304 && known) return JSON.parse(known.text);
  if (!resp.ok) throw await failure(resp);
  const text = await resp.text();
  const etag = resp.headers.get("ETag");
  answers.delete(path);
  if (etag) {
    answers.set(path, { etag, text });
    if (answers.size > MAX_ANSWERS) answers.delete(answers.keys().next().value);
  }
  return JSON.parse(text);
}

export async function postJson(path, body) {
  const resp = await fetch(path, {
    method: "POST",
    headers: headers({ "Content-Type": "application/json" }),
    body: body === undefined ? undefined : JSON.stringify(body),
  });
  if (!resp.ok) throw await failure(resp);
  return resp.json();
}

/** POST a multipart form (files): the browser sets its boundary; JSON comes back. */
export async function postForm(path, form) {
  const resp = await fetch(path, { method: "POST", headers: headers(), body: form });
  if (!resp.ok) throw await failure(resp);
  return resp.json();
}

/**
 * A short-lived link the browser opens itself (a certificate PDF), signed by the service
 * (POST /api/links): the pasted token never goes into a URL, a log or the history.
 * Without a token (public reads) the plain path.
 */
export async function signedLink(path) {
  if (!getToken()) return path;
  const { url } = await postJson("/api/links", { path });
  return url;
}

const LINK_REFRESH_MS = 120_000; // links live 300 s: re-sign well before

/** An anchor to `path` whose href is a signed link, signed again on a click once it is old. */
export function linkAnchor(h, attrs, text, path) {
  const a = h("a", { ...attrs, href: path }, text);
  let signedAt = 0;
  const sign = async () => { a.href = await signedLink(path); signedAt = Date.now(); };
  sign().catch(() => { /* shown on click */ });
  a.addEventListener("click", async (ev) => {
    if (Date.now() - signedAt < LINK_REFRESH_MS) return;
    ev.preventDefault();
    const win = window.open("", "_blank");
    try {
      await sign();
      if (win) { win.opener = null; win.location.href = a.href; } else window.location.href = a.href;
    } catch (err) { if (win) win.close(); a.title = `link failed: ${err.message}`; }
  });
  return a;
}

export async function putJson(path, body) {
  const resp = await fetch(path, {
    method: "PUT",
    headers: headers({ "Content-Type": "application/json" }),
    body: JSON.stringify(body),
  });
  if (!resp.ok) throw await failure(resp);
  return resp.json();
}

/** Download a JSON resource as a file (the token goes in the header, not the URL). */
export async function downloadJson(path, filename) {
  const data = await getJson(path);
  const blob = new Blob([JSON.stringify(data, null, 2)], { type: "application/json" });
  const url = URL.createObjectURL(blob);
  const a = document.createElement("a");
  a.href = url; a.download = filename;
  document.body.append(a); a.click(); a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 5000);
  return data;
}

/**
 * Follow a run's server-sent events with fetch (so the token goes in a header).
 * onEvent(name, data) for each event; resolves when the stream ends, rejects on failure.
 */
export async function followEvents(runId, onEvent, signal) {
  const resp = await fetch(`/api/runs/${encodeURIComponent(runId)}/events`, {
    headers: headers({ Accept: "text/event-stream" }), signal,
  });
  if (!resp.ok || !resp.body) throw await failure(resp);
  const reader = resp.body.getReader();
  const decoder = new TextDecoder();
  let buf = "";
  for (;;) {
    const { value, done } = await reader.read();
    if (done) break;
    buf += decoder.decode(value, { stream: true });
    let cut;
    while ((cut = buf.indexOf("\n\n")) >= 0) {
      const block = buf.slice(0, cut); buf = buf.slice(cut + 2);
      let name = "message"; const data = [];
      for (const line of block.split("\n")) {
        if (line.startsWith("event:")) name = line.slice(6).trim();
        else if (line.startsWith("data:")) data.push(line.slice(5).trim());
      }
      if (!data.length) continue;
      let parsed; try { parsed = JSON.parse(data.join("\n")); } catch { parsed = data.join("\n"); }
      onEvent(name, parsed);
    }
  }
}
