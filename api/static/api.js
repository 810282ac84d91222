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

export async function getJson(path, { signal } = {}) {
  const resp = await fetch(path, { headers: headers(), signal });
  if (!resp.ok) throw await failure(resp);
  return resp.json();
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

export async function putJson(path, body) {
  const resp = await fetch(path, {
    method: "PUT",
    headers: headers({ "Content-Type": "application/json" }),
    body: JSON.stringify(body),
  });
  if (!resp.ok) throw await failure(resp);
  return resp.json();
}

/** A link the browser opens itself (PDF): the token travels as ?access_token=. */
export function linkWithToken(path) {
  const t = getToken();
  return t ? `${path}${path.includes("?") ? "&" : "?"}access_token=${encodeURIComponent(t)}` : path;
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
