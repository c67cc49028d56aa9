// The segment: every slave in ring order as a line of ports, with link state (ESC DL status
// 0x0110, spec-notes §esc.dl), AL state and status code, identity, alias, DC support (ESC
// features 0x0008 bit 2, spec-notes §esc.info); live from the event stream; state requests for one slave or all.
// Each slave's key process-data values (a CiA 402 drive's state, a digital terminal's bits),
// live from the process-data stream. With cable redundancy on, the ring above the slaves
// (ring.js), from GET /master, redrawn at every event (ring_broken, ring_closed among them).

import { api, stream } from "./api.js";
import { h, fill, hex, errorLine } from "./dom.js";
import { keyValues } from "./process-data.js";
import { confirmWrite, slaveText, writeControl } from "./guard.js";
import { ringFigure, ringText } from "./ring.js";

export const STATES = ["INIT", "PREOP", "BOOT", "SAFEOP", "OP"];

/** The state badge: colour and the state's name as text (never colour alone). */
export function stateBadge(slave) {
  // A slave that does not answer is "ABSENT" (the API never reports its last state as live).
  const state = slave.state.startsWith("UNKNOWN") ? "UNKNOWN" : slave.state;
  return h("span", { class: `state state-${state.toLowerCase()}${slave.al_error ? " state-error" : ""}` },
    slave.state, slave.al_error ? " + ERROR" : "");
}

function bytes(hexText) {
  return (hexText.match(/../g) || []).map((b) => parseInt(b, 16));
}

/** Ports (descriptor 0x0007, DL status 0x0110) and DC support (0x0008) of one slave. */
async function escLinks(position) {
  const [head, dl] = await Promise.all([
    api(`/slaves/${position}/registers/0x0007?length=3`),
    api(`/slaves/${position}/registers/0x0110?length=2`),
  ]);
  const [descriptor, features] = bytes(head.data);
  const status = bytes(dl.data);
  const dlStatus = status[0] | (status[1] << 8);
  const ports = [0, 1, 2, 3].map((n) => ({
    n,
    implemented: ((descriptor >> (2 * n)) & 3) !== 0,
    link: Boolean(dlStatus & (1 << (4 + n))),
    loopClosed: Boolean(dlStatus & (1 << (8 + 2 * n))),
    communication: Boolean(dlStatus & (1 << (9 + 2 * n))),
  }));
  return { ports, dc: Boolean(features & 4) };
}

function portList(links) {
  if (!links) return h("span", { class: "muted" }, "ports: not read");
  return h("ul", { class: "ports", "aria-label": "ports" }, links.ports.filter((p) => p.implemented).map((p) =>
    h("li", { class: `port ${p.communication ? "port-up" : p.link ? "port-link" : "port-down"}` },
      `P${p.n} `, p.communication ? "up" : p.link ? "link" : "no link", p.loopClosed ? " (closed)" : "")));
}

/**
 * A state request: a select with no state chosen (a placeholder), and a button that stays
 * disabled until one is; pressing it asks `confirmation(state)` (the dialog's text, async:
 * it may read the segment first) and, confirmed, `request(state)`. Read-only: drawn
 * disabled. The choice goes back to the placeholder after each request.
 */
export function stateControl(app, { label, id, confirmation, request, onDone = () => {} }) {
  const select = h("select", { "aria-label": `Requested state for ${label}`, class: "state-choice" },
    h("option", { value: "", selected: true }, "choose a state"),
    STATES.map((st) => h("option", { value: st }, st)));
  const status = h("span", { class: "muted", role: "status" });
  const button = h("button", {
    type: "button",
    class: "request-state",
    disabled: true,
    onclick: async () => {
      const state = select.value;
      if (!state) return;
      button.disabled = true;
      let asked;
      try {
        asked = await confirmWrite(await confirmation(state));
      } catch (err) {
        status.textContent = `not requested: ${err.message}`;
        button.disabled = false;
        return;
      }
      if (!asked) {
        status.textContent = "not requested";
        button.disabled = false;
        return;
      }
      status.textContent = `requesting ${state}…`;
      try {
        await request(state);
        status.textContent = `requested ${state}`;
      } catch (err) {
        status.textContent = `refused: ${err.message}`;
      } finally {
        select.value = "";
        button.disabled = true;
        onDone();
      }
    },
  }, id === "all" ? "Request for all" : "Request state");
  if (id) button.id = `request-state-${id}`;
  select.addEventListener("change", () => {
    button.disabled = !select.value || !app.canWrite();
  });
  return writeControl(h("span", { class: "state-control" }, select, button, status), app);
}

/** The confirmation of a state request for `slave` (as GET /slaves answers it). */
export function stateConfirmation(slave, state) {
  return {
    title: "Request a state",
    intro: `ecatd asks slave ${slave.position} to go to ${state}.`,
    rows: [["Slave", slaveText(slave.position, slave.name, slave.station)], ["Now", slave.state], ["Requested state", state]],
    confirm: `Request ${state}`,
  };
}

export async function show(view, app) {
  const list = h("ol", { class: "segment", "aria-label": "slaves in ring order" });
  const summary = h("p", { class: "summary", role: "status" });
  const links = new Map();
  /** Process-data entries by slave position, then by index:subindex. */
  const pd = new Map();
  const keyBox = (position) => h("div", { class: "key-box", "data-position": position },
    keyValues(position, [...(pd.get(position) || new Map()).values()]));
  const head = h("div", { class: "view-head" }, h("h2", {}, "Segment"), summary);
  /** The ring (cable redundancy); empty and hidden on a single port. */
  const ring = h("section", { class: "card ring-card", "aria-label": "cable redundancy", hidden: true });
  fill(view, head, ring, list);
  let allConfirmed = [];
  /** Each slave's state control, kept across redraws (a chosen state survives an event). */
  const controls = new Map();
  /** The newest GET /slaves answer per position, for the confirmations. */
  const latest = new Map();
  const controlOf = (position) => {
    if (!controls.has(position)) {
      controls.set(position, stateControl(app, {
        label: `slave ${position}`,
        id: String(position),
        confirmation: (state) => stateConfirmation(latest.get(position), state),
        request: (state) => api(`/slaves/${position}/state`, { method: "PUT", body: { state } }),
        onDone: () => refresh(),
      }));
    }
    return controls.get(position);
  };
  head.append(h("div", { class: "all-states" }, "All slaves: ",
    stateControl(app, {
      label: "all slaves",
      id: "all",
      confirmation: async (state) => {
        // Named from what ecatd has now, not from what the page drew earlier; the request
        // goes to exactly the slaves the dialog named.
        const slaves = await api("/slaves");
        allConfirmed = slaves;
        return {
          title: "Request a state for all slaves",
          intro: `ecatd asks each of the ${slaves.length} slaves of the segment, one after the other, to go to ${state}.`,
          rows: [
            ["Slaves", `all ${slaves.length}: ${slaves.map((sl) => `${sl.position} ${sl.name || "(no name)"}`).join(", ")}`],
            ["Now", [...new Set(slaves.map((sl) => sl.state))].join(", ")],
            ["Requested state", state],
          ],
          confirm: `Request ${state} for all ${slaves.length} slaves`,
        };
      },
      request: async (state) => {
        for (const sl of allConfirmed) await api(`/slaves/${sl.position}/state`, { method: "PUT", body: { state } });
      },
      onDone: () => refresh(),
    })));

  async function readLinks(slaves) {
    for (const sl of slaves) {
      try {
        links.set(sl.position, await escLinks(sl.position));
      } catch {
        links.set(sl.position, null);
      }
    }
  }

  async function drawRing(slaves) {
    let master;
    try {
      master = await api("/master");
    } catch {
      return;
    }
    const r = master.redundancy;
    const figure = ringFigure(r, slaves.map((sl) => sl.name));
    ring.hidden = !figure;
    if (!figure) return;
    fill(ring, h("h3", {}, "Cable redundancy"),
      h("p", { class: r.state === "broken" ? "ring-broken" : "muted", role: "status", id: "ring-state" }, ringText(r)),
      figure);
  }

  async function refresh() {
    let slaves;
    try {
      slaves = await api("/slaves");
    } catch (err) {
      fill(list, errorLine(err));
      return;
    }
    if (slaves.some((sl) => !links.has(sl.position))) await readLinks(slaves);
    drawRing(slaves);
    for (const sl of slaves) latest.set(sl.position, sl);
    const errors = slaves.filter((sl) => sl.al_error || !sl.present).length;
    summary.textContent = `${slaves.length} slaves, ${errors} in error or missing`;
    fill(list, slaves.map((sl) => {
      const link = links.get(sl.position);
      return h("li", { class: `slave${sl.al_error ? " slave-error" : ""}${sl.present ? "" : " slave-missing"}`, "data-position": sl.position, "data-state": sl.state },
        h("div", { class: "slave-title" },
          h("a", { href: `#/slave/${sl.position}` }, `${sl.position}: ${sl.name || "(no name)"}`),
          stateBadge(sl)),
        h("dl", { class: "facts compact" },
          h("dt", {}, "Station"), h("dd", {}, hex(sl.station)),
          h("dt", {}, "Alias"), h("dd", {}, sl.alias ? String(sl.alias) : "none"),
          h("dt", {}, "Identity"), h("dd", {}, `${hex(sl.identity.vendor_id, 8)} / ${hex(sl.identity.product_code, 8)} rev ${hex(sl.identity.revision, 8)}`),
          h("dt", {}, "AL status"), h("dd", {}, `${hex(sl.al_status_code)} ${sl.al_status_text}`),
          h("dt", {}, "DC"), h("dd", {}, link ? (link.dc ? "supported" : "no") : "–"),
          h("dt", {}, "Mailbox"), h("dd", {}, sl.mailbox_protocols.join(" ") || "none")),
        keyBox(sl.position),
        portList(link),
        controlOf(sl.position));
    }));
  }

  // The server's default interval: 100 ms, or the cycle when it is longer.
  const values = stream("/process-data/stream", (data, name) => {
    if (name !== "values") return;
    const touched = new Set();
    for (const e of data.entries) {
      if (!pd.has(e.slave)) pd.set(e.slave, new Map());
      pd.get(e.slave).set(`${e.index}:${e.subindex}`, e);
      touched.add(e.slave);
    }
    for (const position of touched) {
      const box = list.querySelector(`.key-box[data-position="${position}"]`);
      if (box) box.replaceWith(keyBox(position));
    }
  }, () => {});

  let pending = null;
  app.onEvent((event) => {
    if (["slave_found", "slave_lost", "slave_replaced"].includes(event.kind)) {
      links.clear();
      // The image may have changed: all values again from a new stream.
      pd.clear();
      values.restart();
    }
    if (event.kind === "emergency" || pending) return;
    // Events come in bursts (a state request for all slaves): one refresh per burst.
    pending = setTimeout(() => {
      pending = null;
      refresh();
    }, 100);
  });
  await refresh();
  return {
    stop: () => {
      clearTimeout(pending);
      values.stop();
    },
  };
}
