// The dashboard's frame: the views by URL fragment (#/segment, #/slave/3, #/process-data,
// #/process-data/3, #/gateway, #/bus, #/events), the event stream shared by all views, the
// token prompt, the theme.

import { api, listen, onUnauthorized, setToken, token } from "./api.js";
import { fill, errorLine } from "./dom.js";
import * as segment from "./segment.js";
import * as slave from "./slave.js";
import * as gateway from "./gateway.js";
import * as bus from "./bus.js";
import * as processData from "./process-data.js";
import * as events from "./events.js";
import { closeConfirmation, NEEDS_WRITE } from "./guard.js";

const VIEWS = { segment, slave, "process-data": { show: processData.showProcessData }, gateway, bus, events };
const MAX_EVENTS = 1000;

/** What every view may use. */
export const app = {
  /** `write`, `read`, or `none` (ecatd wants a token and has none that it accepts). */
  role: "none",
  /** The newest events, kept by ecatd before the page opened and received since; newest last. */
  log: [],
  listeners: new Set(),
  canWrite() {
    return this.role === "write";
  },
  /** Calls `fn(event)` for each new event until the view changes. */
  onEvent(fn) {
    this.listeners.add(fn);
  },
};

const view = document.getElementById("view");
let current = null;
/** Counts routings: a view whose show() ends after the next routing is stopped at once. */
let routing = 0;

/**
 * Who the caller is (GET /api/v1/session): the role decides whether write controls are
 * enabled. A refusal (tokens on, none or a wrong one given) is the role "none": read-only.
 */
async function loadSession() {
  const label = document.getElementById("role");
  try {
    const session = await api("/session");
    app.role = session.role;
    label.textContent = `${session.caller} (${session.role === "write" ? "read and write" : "read only"})`;
  } catch (err) {
    app.role = "none";
    label.textContent = err.status === 401 ? "no token" : "";
  }
  const readOnly = !app.canWrite();
  document.body.classList.toggle("read-only", readOnly);
  const badge = document.getElementById("read-only-badge");
  badge.hidden = !readOnly;
  badge.title = app.role === "none" ? "No token: every write control is disabled" : NEEDS_WRITE;
}

async function route() {
  const mine = ++routing;
  const [, name = "segment", ...args] = (location.hash || "#/segment").split("/");
  const module = VIEWS[name] || segment;
  if (current && current.stop) current.stop();
  current = null;
  // A confirmation of the view left is a Cancel: nothing is sent.
  closeConfirmation();
  app.listeners.clear();
  document.querySelectorAll("nav a").forEach((a) => {
    const active = a.dataset.view === name || (name === "slave" && a.dataset.view === "segment");
    if (active) a.setAttribute("aria-current", "page");
    else a.removeAttribute("aria-current");
  });
  fill(view);
  document.title = `ecatd: ${name}`;
  try {
    const shown = (await module.show(view, app, ...args.map(decodeURIComponent))) || null;
    // Left while it loaded: its streams and timers end now.
    if (mine !== routing) {
      if (shown && shown.stop) shown.stop();
      return;
    }
    current = shown;
  } catch (err) {
    if (mine === routing) fill(view, errorLine(err));
  }
}

function askToken(reason) {
  const dialog = document.getElementById("token-dialog");
  if (dialog.open) return;
  document.getElementById("token-reason").textContent = reason || "Enter the bearer token ecatd gave you (kept for this browser tab only).";
  const input = document.getElementById("token-input");
  input.value = token();
  // Escape closes without a button: then nothing changes.
  dialog.returnValue = "";
  dialog.showModal();
  input.focus();
}

/**
 * Puts the events ecatd kept into the log (not passed to the views: they are history, not
 * news); the number of the last one, or `null` when ecatd refused (no token yet).
 */
async function loadHistory() {
  let kept;
  try {
    kept = await api(`/events?limit=${MAX_EVENTS}`);
  } catch {
    return null;
  }
  const known = new Set(app.log.map((e) => e.id));
  for (const event of kept) {
    if (known.has(event.id)) continue;
    event.received = new Date(event.time);
    app.log.push(event);
  }
  app.log.sort((a, b) => a.id - b.id);
  app.log.splice(0, Math.max(0, app.log.length - MAX_EVENTS));
  return kept.length ? kept[kept.length - 1].id : 0;
}

function setupToken(stream) {
  const dialog = document.getElementById("token-dialog");
  document.getElementById("token-button").addEventListener("click", () => askToken());
  dialog.addEventListener("close", async () => {
    if (dialog.returnValue === "save") setToken(document.getElementById("token-input").value.trim());
    else if (dialog.returnValue === "forget") setToken("");
    else return;
    await loadSession();
    const last = await loadHistory();
    if (last !== null) stream.resumeAfter(last);
    stream.restart();
    route();
  });
  onUnauthorized((err) => askToken(`ecatd says: ${err.message}`));
}

const THEMES = ["auto", "light", "dark"];

function setupTheme() {
  const button = document.getElementById("theme-button");
  const apply = (theme) => {
    if (theme === "auto") document.documentElement.removeAttribute("data-theme");
    else document.documentElement.dataset.theme = theme;
    button.textContent = `Theme: ${theme}`;
  };
  let theme = localStorage.getItem("ecatd.theme") || "auto";
  apply(theme);
  button.addEventListener("click", () => {
    theme = THEMES[(THEMES.indexOf(theme) + 1) % THEMES.length];
    localStorage.setItem("ecatd.theme", theme);
    apply(theme);
  });
}

async function start() {
  setupTheme();
  const live = document.getElementById("live");
  const last = await loadHistory();
  const stream = listen((event) => {
    event.received = event.time ? new Date(event.time) : new Date();
    app.log.push(event);
    if (app.log.length > MAX_EVENTS) app.log.shift();
    app.listeners.forEach((fn) => fn(event));
  }, (status) => {
    live.textContent = `events: ${status}`;
    live.dataset.status = status;
  }, last);
  setupToken(stream);
  await loadSession();
  window.addEventListener("hashchange", route);
  await route();
}

start();
