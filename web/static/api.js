// ecatd's REST API and event stream, with the bearer token when one is set. Every write
// is JSON or octet-stream with the X-Ecat-Client header, as ecatd's browser checks require.

const TOKEN_KEY = "ecatd.token";
const BASE = "/api/v1";

/** An API error: HTTP status and ecatd's message. */
export class ApiError extends Error {
  constructor(status, message, kind) {
    super(message);
    this.status = status;
    this.kind = kind;
  }
}

const unauthorizedListeners = new Set();

/** Calls `fn(error)` when ecatd refuses a call for want of a (valid) token. */
export function onUnauthorized(fn) {
  unauthorizedListeners.add(fn);
}

export function token() {
  return sessionStorage.getItem(TOKEN_KEY) || "";
}

export function setToken(value) {
  if (value) sessionStorage.setItem(TOKEN_KEY, value);
  else sessionStorage.removeItem(TOKEN_KEY);
}

function headers(extra) {
  const out = { "X-Ecat-Client": "dashboard", ...extra };
  const t = token();
  if (t) out.Authorization = "Bearer " + t;
  return out;
}

async function failure(response) {
  let message = response.statusText;
  let kind;
  try {
    const body = await response.json();
    // RFC 9457 problem details (docs/call-it.md): `detail` says what, `reason` is the
    // stable code.
    message = body.detail || body.title || message;
    kind = body.reason;
  } catch {
    // Not JSON: keep the status text.
  }
  const err = new ApiError(response.status, message, kind);
  if (response.status === 401) unauthorizedListeners.forEach((fn) => fn(err));
  return err;
}

/** GET (or `method`) `path` under /api/v1; `body` is sent as JSON; returns the JSON. */
export async function api(path, { method = "GET", body } = {}) {
  const init = { method, headers: headers(body === undefined ? {} : { "Content-Type": "application/json" }) };
  if (body !== undefined) init.body = JSON.stringify(body);
  const response = await fetch(BASE + path, init);
  if (!response.ok) throw await failure(response);
  return response.json();
}

/** GET `path` as bytes, reporting `progress(received, total)` as they arrive. */
export async function download(path, progress) {
  const response = await fetch(BASE + path, { headers: headers() });
  if (!response.ok) throw await failure(response);
  const total = Number(response.headers.get("Content-Length")) || 0;
  const reader = response.body.getReader();
  const parts = [];
  let received = 0;
  for (;;) {
    const { done, value } = await reader.read();
    if (done) break;
    parts.push(value);
    received += value.length;
    progress(received, total);
  }
  const out = new Uint8Array(received);
  let at = 0;
  for (const p of parts) {
    out.set(p, at);
    at += p.length;
  }
  return out;
}

/**
 * PUT `bytes` to `path` as application/octet-stream; `progress(phase, fraction)` reports the
 * body going to ecatd ("sending") and then the wait for the slave ("writing").
 */
export function upload(path, bytes, progress) {
  return new Promise((resolve, reject) => {
    const xhr = new XMLHttpRequest();
    xhr.open("PUT", BASE + path);
    for (const [k, v] of Object.entries(headers({ "Content-Type": "application/octet-stream" }))) {
      xhr.setRequestHeader(k, v);
    }
    xhr.upload.onprogress = (e) => {
      if (e.lengthComputable) progress("sending", e.loaded / e.total);
    };
    xhr.upload.onload = () => progress("writing", 1);
    xhr.onerror = () => reject(new ApiError(0, "connection to ecatd lost"));
    xhr.onload = async () => {
      if (xhr.status >= 200 && xhr.status < 300) {
        resolve(JSON.parse(xhr.responseText));
        return;
      }
      reject(await failure(new Response(xhr.responseText, { status: xhr.status, statusText: xhr.statusText })));
    };
    xhr.send(bytes);
  });
}

/**
 * Reads the server-sent events of `path` under /api/v1 with `fetch` (so that the token goes
 * in a header: `EventSource` cannot send one) and calls `onEvent(data, name)` with each
 * event's JSON data and its `event:` name; `onStatus(text, error)` says whether it is live.
 * It remembers the last event `id:` and sends it as `Last-Event-ID` when it connects again,
 * so that nothing is missed; `lastId` is the one to start after (0: every kept event).
 * Reconnects after a second when the stream ends or the connection fails. A refusal (4xx)
 * ends it, unless `retryRefused`: then it tries again after a second, or, refused for want
 * of a token (401), when `restart()` says a new token is there. `stop()` ends it for good
 * (leaving the view), `restart()` connects again at once.
 */
export function stream(path, onEvent, onStatus, { retryRefused = false, lastId = null } = {}) {
  let stopped = false;
  let controller;
  let wake = null;
  async function run() {
    while (!stopped) {
      controller = new AbortController();
      try {
        const extra = { Accept: "text/event-stream" };
        if (lastId !== null) extra["Last-Event-ID"] = String(lastId);
        const response = await fetch(BASE + path, { headers: headers(extra), signal: controller.signal });
        if (!response.ok) throw await failure(response);
        onStatus("live");
        const reader = response.body.pipeThrough(new TextDecoderStream()).getReader();
        let buffer = "";
        for (;;) {
          const { done, value } = await reader.read();
          if (done) break;
          buffer += value.replace(/\r\n/g, "\n");
          let end;
          while ((end = buffer.indexOf("\n\n")) >= 0) {
            const block = buffer.slice(0, end).split("\n");
            buffer = buffer.slice(end + 2);
            const name = (block.find((l) => l.startsWith("event:")) || "event: message").slice(6).trim();
            const id = block.find((l) => l.startsWith("id:"));
            if (id) lastId = id.slice(3).trim();
            const data = block.filter((l) => l.startsWith("data:")).map((l) => l.slice(5).trimStart()).join("\n");
            if (!data) continue;
            let parsed;
            try {
              parsed = JSON.parse(data);
            } catch {
              // Not JSON (a comment or keep-alive): nothing to show.
              continue;
            }
            onEvent(parsed, name);
          }
        }
        onStatus("reconnecting…");
      } catch (err) {
        if (stopped) return;
        if (err.name === "AbortError") {
          // restart(): a new token; connect again at once.
          onStatus("reconnecting…");
          continue;
        }
        onStatus(err.status === 401 ? "token needed" : err.status ? "refused" : "offline", err);
        if (err.status >= 400 && err.status < 500 && !retryRefused) return;
        if (err.status === 401) {
          // Asking again with the same token is refused again: wait for a new one.
          await new Promise((resolve) => {
            wake = resolve;
          });
          wake = null;
          continue;
        }
      }
      await new Promise((r) => setTimeout(r, 1000));
    }
  }
  run();
  return {
    restart() {
      if (wake) wake();
      else if (controller) controller.abort();
    },
    /** Connects from now on after event `id` (the history the caller loaded ends there). */
    resumeAfter(id) {
      lastId = id;
    },
    stop() {
      stopped = true;
      if (wake) wake();
      if (controller) controller.abort();
    },
  };
}

/**
 * Listens to /api/v1/events after event `lastId` (the last one of the history the caller
 * loaded; `null`: from now on) and calls `onEvent(event)` for each; `onStatus(text)` says
 * whether it is live. Reconnects after a second when the stream ends, from the last event it
 * had; refused for want of a token, when the token prompt's answer restarts it.
 */
export function listen(onEvent, onStatus, lastId) {
  return stream("/events", (event) => onEvent(event), onStatus, { retryRefused: true, lastId });
}

/** SHA-256 of `bytes`, hex. */
export async function sha256(bytes) {
  const digest = new Uint8Array(await crypto.subtle.digest("SHA-256", bytes));
  return Array.from(digest, (b) => b.toString(16).padStart(2, "0")).join("");
}
