// The events log: the events ecatd kept and every one since, newest first, with the time
// ecatd published each, filtered by kind and by text.

import { h, fill } from "./dom.js";

const KINDS = ["all", "state_changed", "al_error", "emergency", "slave_found", "slave_lost", "slave_replaced", "topology_mismatch", "startup_failed", "lagged"];

function describe(e) {
  switch (e.kind) {
    case "state_changed":
      return `slave ${e.position}: ${e.from} → ${e.to}`;
    case "al_error":
      return `slave ${e.position} ${e.name}: AL error 0x${(e.al_status_code ?? 0).toString(16).padStart(4, "0")} in ${e.to}`;
    case "emergency":
      return `slave ${e.position}: emergency 0x${e.emergency.error_code.toString(16).padStart(4, "0")}, data ${e.emergency.data}`;
    default:
      return `slave ${e.position} ${e.name || ""} ${e.text || ""}`.trim();
  }
}

export function show(view, app) {
  const kind = h("select", { id: "event-kind", "aria-label": "Event kind" }, KINDS.map((k) => h("option", { value: k }, k.replace(/_/g, " "))));
  const text = h("input", { id: "event-filter", type: "search", placeholder: "slave, state, code…", "aria-label": "Filter events by text" });
  const count = h("span", { role: "status" });
  const body = h("tbody", {});
  const render = () => {
    const q = text.value.trim().toLowerCase();
    const rows = app.log.filter((e) => (kind.value === "all" || e.kind === kind.value) && (!q || describe(e).toLowerCase().includes(q) || e.kind.includes(q)))
      .slice().reverse();
    count.textContent = `${rows.length} of ${app.log.length} events`;
    fill(body, rows.map((e) => h("tr", { class: `event event-${e.kind}` },
      h("td", {}, e.received.toLocaleTimeString()), h("td", {}, e.kind.replace(/_/g, " ")), h("td", {}, describe(e)))));
  };
  kind.addEventListener("change", render);
  text.addEventListener("input", render);
  app.onEvent(render);
  fill(view, h("div", { class: "view-head" }, h("h2", {}, "Events"), h("div", { class: "row" }, kind, text, count)),
    h("table", { class: "table", id: "events" }, h("thead", {}, h("tr", {}, h("th", {}, "Time"), h("th", {}, "Kind"), h("th", {}, "What"))), body));
  render();
}
