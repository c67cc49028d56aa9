// The segment: every slave in ring order as a line of ports, with link state (ESC DL status
// 0x0110, spec-notes §esc.dl), AL state and status code, identity, alias, DC support (ESC
// features 0x0008 bit 2, spec-notes §esc.info); live from the event stream; state requests for one slave or all.
// Each slave's key process-data values (a CiA 402 drive's state, a digital terminal's bits),
// live from the process-data stream.

import { api, stream } from "./api.js";
import { h, fill, hex, errorLine } from "./dom.js";
import { keyValues } from "./process-data.js";

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

function stateControl(label, target, onDone) {
  const select = h("select", { "aria-label": `Requested state for ${label}` },
    STATES.map((st) => h("option", { value: st, selected: st === "OP" }, st)));
  const status = h("span", { class: "muted", role: "status" });
  const button = h("button", {
    type: "button",
    class: "write",
    onclick: async () => {
      button.disabled = true;
      status.textContent = "requesting…";
      try {
        await target(select.value);
        status.textContent = `requested ${select.value}`;
      } catch (err) {
        status.textContent = `refused: ${err.message}`;
      } finally {
        button.disabled = false;
        onDone();
      }
    },
  }, "Request");
  return h("span", { class: "state-control" }, select, button, status);
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
  fill(view, head, list);
  if (app.canWrite()) {
    head.append(h("div", { class: "all-states" }, "All slaves: ",
      stateControl("all slaves", async (state) => {
        const slaves = await api("/slaves");
        for (const sl of slaves) await api(`/slaves/${sl.position}/state`, { method: "PUT", body: { state } });
      }, () => refresh())));
  }

  async function readLinks(slaves) {
    for (const sl of slaves) {
      try {
        links.set(sl.position, await escLinks(sl.position));
      } catch {
        links.set(sl.position, null);
      }
    }
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
        app.canWrite() ? stateControl(`slave ${sl.position}`, (state) => api(`/slaves/${sl.position}/state`, { method: "PUT", body: { state } }), () => refresh()) : "");
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
