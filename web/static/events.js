// The events log: the events ecatd kept and every one since, newest first, with the time
// ecatd published each (UTC) and its text. Filters by kind, slave and time ask ecatd
// (GET /api/v1/events?kind=&slave=&since=: the server reads slave addresses and spans as
// every other client's query does; a slave's name is looked up in the segment first), again
// at each new event; the text filter narrows what is shown.

import { api } from "./api.js";
import { h, fill } from "./dom.js";

/** The kinds ecatd publishes (docs/operations.md, "APIs"); kinds seen in the log are added. */
const KNOWN_KINDS = ["state_changed", "al_error", "emergency", "slave_found", "slave_lost", "slave_replaced", "topology_mismatch", "startup_failed", "bus_fault", "bus_recovered", "ring_broken", "ring_closed", "gateway_started", "gateway_stopped", "gateway_failed", "write", "app_claimed", "app_released", "app_watchdog", "process_data_forced", "process_data_released", "foe_progress"];
/** As many as the page keeps unfiltered. */
const LIMIT = 1000;

function describe(e) {
  if (e.text) return e.text;
  switch (e.kind) {
    case "state_changed":
      return `slave ${e.position}: ${e.from} → ${e.to}`;
    case "emergency":
      return `emergency 0x${e.emergency.error_code.toString(16).padStart(4, "0")}, data ${e.emergency.data}`;
    default:
      return `${e.kind.replace(/_/g, " ")} ${e.name || ""}`.trim();
  }
}

/** `2026-11-29 07:10:00.123 UTC` from ecatd's RFC 3339 stamp (or the time it arrived). */
function utc(e) {
  const at = e.time ? new Date(e.time) : e.received;
  if (!at || Number.isNaN(at.getTime())) return "–";
  return at.toISOString().replace("T", " ").replace("Z", " UTC");
}

function kindOptions(select, log) {
  const kinds = [...new Set([...KNOWN_KINDS, ...log.map((e) => e.kind).filter((k) => k && k !== "lagged")])];
  if (select.options.length === kinds.length + 1) return;
  const chosen = select.value;
  fill(select, h("option", { value: "" }, "all kinds"), kinds.map((k) => h("option", { value: k }, k.replace(/_/g, " "))));
  select.value = chosen;
}

/** How ecatd names a slave in a query: a position, `#station`, `@alias`, `alias:offset`. */
const ADDRESS = /^\s*(pos:|station:|alias:|#|@)?(0x[0-9a-f]+|[0-9]+)([:+](0x[0-9a-f]+|[0-9]+))?\s*$/i;

/**
 * The kept events `params` select, of the slave `who` names: an address goes to ecatd as it
 * is; other text is a slave's name (`DI8`), matched against the segment's names, one query
 * per slave it matches.
 */
async function history(params, who) {
  if (!who || ADDRESS.test(who)) {
    if (who) params.set("slave", who);
    return api(`/events?${params}`);
  }
  const slaves = await api("/slaves");
  const named = slaves.filter((sl) => (sl.name || "").toLowerCase().includes(who.toLowerCase()));
  if (!named.length) throw new Error(`no slave is named ${JSON.stringify(who)} (or give its position)`);
  const found = [];
  for (const sl of named) {
    params.set("slave", String(sl.position));
    found.push(...(await api(`/events?${params}`)));
  }
  found.sort((a, b) => a.id - b.id);
  return found.slice(-LIMIT);
}

export function show(view, app) {
  const kind = h("select", { id: "event-kind" });
  const slave = h("input", { id: "event-slave", type: "text", size: 10, placeholder: "3, #0x3ec, @7, DI8", spellcheck: false });
  const since = h("input", { id: "event-since", type: "text", size: 22, placeholder: "10m, 1h, 2026-11-29T07:00:00Z", spellcheck: false });
  const text = h("input", { id: "event-filter", type: "search", placeholder: "slave, state, code…", "aria-label": "Filter events by text" });
  const clear = h("button", { type: "button", id: "event-clear" }, "Clear filters");
  const count = h("span", { id: "event-count", role: "status" });
  const problem = h("p", { id: "event-error", class: "error", role: "alert", hidden: true });
  const body = h("tbody", {});
  kindOptions(kind, app.log);

  /** Whether ecatd must be asked (a filter the page does not apply itself). */
  const asking = () => Boolean(kind.value || slave.value.trim() || since.value.trim());
  /** The events ecatd answered for the filters (null: none asked, the log is shown). */
  let answered = null;
  /** Counts queries: an answer that is not the newest is dropped. */
  let asked = 0;
  let again = null;

  const render = () => {
    const q = text.value.trim().toLowerCase();
    const source = answered ?? app.log;
    const rows = source.filter((e) => !q || describe(e).toLowerCase().includes(q) || e.kind.includes(q) || (e.name || "").toLowerCase().includes(q))
      .slice().reverse();
    count.textContent = `${rows.length} of ${source.length} events${answered ? " matching the filters" : ""}`;
    body.dataset.filtered = answered ? "server" : "none";
    fill(body, rows.map((e) => h("tr", { class: `event event-${e.kind}`, "data-id": e.id, "data-position": e.position, "data-kind": e.kind },
      h("td", { class: "events-time" }, h("time", { datetime: e.time || "" }, utc(e))),
      h("td", {}, e.kind.replace(/_/g, " ")),
      h("td", {}, e.kind === "lagged" ? "–" : `${e.position}${e.name ? ` ${e.name}` : ""}`),
      h("td", {}, describe(e)))));
  };

  const query = async () => {
    const mine = ++asked;
    if (!asking()) {
      answered = null;
      problem.hidden = true;
      render();
      return;
    }
    // Until ecatd answers, what shows is not yet what the filters ask for.
    body.dataset.filtered = "pending";
    const params = new URLSearchParams({ limit: String(LIMIT) });
    if (kind.value) params.set("kind", kind.value);
    if (since.value.trim()) params.set("since", since.value.trim());
    try {
      const found = await history(params, slave.value.trim());
      if (mine !== asked) return;
      answered = found;
      problem.hidden = true;
    } catch (err) {
      if (mine !== asked) return;
      // A filter ecatd cannot read (`since=yesterday`): said, and nothing shown as if it matched.
      answered = [];
      problem.textContent = `filter not applied: ${err.message}`;
      problem.hidden = false;
    }
    render();
  };

  for (const el of [kind, slave, since]) el.addEventListener("change", query);
  text.addEventListener("input", render);
  clear.addEventListener("click", () => {
    kind.value = "";
    slave.value = "";
    since.value = "";
    text.value = "";
    query();
  });
  app.onEvent(() => {
    kindOptions(kind, app.log);
    if (!asking()) {
      render();
      return;
    }
    // Events come in bursts (a state request for all slaves): one query per burst.
    if (again) return;
    again = setTimeout(() => {
      again = null;
      query();
    }, 200);
  });
  const field = (label, input) => h("label", {}, label, input);
  const form = h("form", {
    class: "event-filters",
    role: "search",
    "aria-label": "Filter events",
    onsubmit: (ev) => {
      ev.preventDefault();
      query();
    },
  }, field("Kind", kind), field("Slave", slave), field("Since", since), field("Text", text),
  h("button", { type: "submit", id: "event-apply" }, "Filter"), clear);
  fill(view, h("div", { class: "view-head" }, h("h2", {}, "Events"), count), form, problem,
    h("table", { class: "table", id: "events" }, h("thead", {}, h("tr", {},
      h("th", { scope: "col" }, "Time (UTC)"), h("th", { scope: "col" }, "Kind"), h("th", { scope: "col" }, "Slave"), h("th", { scope: "col" }, "What"))), body));
  render();
  return {
    stop() {
      clearTimeout(again);
      asked += 1;
    },
  };
}
