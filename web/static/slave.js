// One slave: identity and SII summary, mailbox protocols, the CoE dictionary, SoE IDNs,
// FoE file transfer, EoE IP settings, ESC error counters and recent emergencies; a link to
// its process data.

import { api, download, upload, sha256 } from "./api.js";
import { h, fill, hex, section, facts, errorLine } from "./dom.js";
import { siiSummary } from "./sii.js";
import { dictionary } from "./dictionary.js";
import { stateBadge, stateControl, stateConfirmation } from "./segment.js";
import { confirmWrite, slaveText, writeControl } from "./guard.js";

function bytesOf(hexText) {
  return new Uint8Array((hexText.match(/../g) || []).map((b) => parseInt(b, 16)));
}

function idnName(idn) {
  const kind = idn & 0x8000 ? "P" : "S";
  return `${kind}-${(idn >> 12) & 7}-${String(idn & 0xfff).padStart(4, "0")}`;
}

/** ESC error counters 0x0300-0x0313 (spec-notes §esc.errors). */
function counterRows(b) {
  const ports = [0, 1, 2, 3];
  return [
    ["Invalid frames", ports.map((n) => b[2 * n]).join(" / ")],
    ["RX errors", ports.map((n) => b[2 * n + 1]).join(" / ")],
    ["Forwarded RX errors", ports.map((n) => b[8 + n]).join(" / ")],
    ["Processing unit errors", String(b[0x0c])],
    ["PDI errors", String(b[0x0d])],
    ["Lost links", ports.map((n) => b[0x10 + n]).join(" / ")],
  ];
}

async function escCounters(body, position) {
  const out = h("div", {});
  const refresh = async () => {
    try {
      const r = await api(`/slaves/${position}/registers/0x0300?length=20`);
      fill(out, h("p", { class: "muted" }, "per port 0 / 1 / 2 / 3"), facts(counterRows(bytesOf(r.data))));
    } catch (err) {
      fill(out, errorLine(err));
    }
  };
  fill(body, out, h("button", { type: "button", onclick: refresh }, "Read counters again"));
  await refresh();
}

async function soeView(body, position) {
  fill(body, h("p", { class: "muted" }, "reading S-0-0017 (IDN list)…"));
  try {
    const list = bytesOf((await api(`/slaves/${position}/soe/0/17`)).data);
    // A list: current length, maximum length (bytes), then the IDNs (spec-notes §soe).
    const idns = [];
    const len = list[0] | (list[1] << 8);
    for (let i = 4; i + 1 < Math.min(list.length, 4 + len); i += 2) idns.push(list[i] | (list[i + 1] << 8));
    const rows = idns.map((idn) => {
      const value = h("output", { class: "value" }, "not read");
      const name = h("span", { class: "muted" }, "");
      api(`/slaves/${position}/soe/0/${idn}?elements=2`).then((r) => {
        const b = bytesOf(r.data);
        name.textContent = String.fromCharCode(...b.subarray(4, 4 + (b[0] | (b[1] << 8))));
      }).catch(() => {});
      const read = async () => {
        try {
          value.textContent = "0x" + (await api(`/slaves/${position}/soe/0/${idn}`)).data;
        } catch (err) {
          value.textContent = err.message;
        }
      };
      return h("tr", {}, h("td", {}, h("code", {}, idnName(idn))), h("td", {}, name),
        h("td", {}, h("button", { type: "button", onclick: read, "aria-label": `Read ${idnName(idn)}` }, "Read")), h("td", {}, value));
    });
    fill(body, h("table", { class: "table" }, h("thead", {}, h("tr", {}, h("th", {}, "IDN"), h("th", {}, "Name"), h("th", {}, ""), h("th", {}, "Value (hex)"))), h("tbody", {}, rows)));
  } catch (err) {
    fill(body, errorLine(err));
  }
}

function foeView(body, slave, app) {
  const position = slave.position;
  const name = h("input", { id: "foe-name", type: "text", value: "firmware.bin", spellcheck: false });
  const bar = h("progress", { id: "foe-progress", max: 100, value: 0, "aria-label": "FoE transfer progress" });
  const percent = h("span", { id: "foe-percent" }, "0 %");
  const status = h("p", { id: "foe-status", role: "status" }, "idle");
  const set = (fraction, text) => {
    const p = Math.round(fraction * 100);
    bar.value = p;
    percent.textContent = `${p} %`;
    status.textContent = text;
  };
  const save = h("span", {});
  const readFile = async () => {
    set(0, "reading from the slave…");
    delete status.dataset.sha256;
    fill(save);
    try {
      const bytes = await download(`/slaves/${position}/foe/${encodeURIComponent(name.value)}`, (got, total) => {
        if (total) set(got / total, `receiving ${got} of ${total} bytes`);
      });
      const digest = await sha256(bytes);
      set(1, `read back ${bytes.length} bytes, SHA-256 ${digest}`);
      status.dataset.sha256 = digest;
      status.dataset.size = bytes.length;
      const url = URL.createObjectURL(new Blob([bytes]));
      fill(save, h("a", { href: url, download: name.value }, `Save ${name.value}`));
    } catch (err) {
      set(0, `failed: ${err.message}`);
    }
  };
  const controls = [h("label", { for: "foe-name" }, "File name "), name,
    h("button", { type: "button", id: "foe-read", onclick: readFile }, "Read from slave")];
  const file = h("input", { id: "foe-file", type: "file", "aria-label": "File to write" });
  const write = async () => {
    const chosen = file.files[0];
    if (!chosen) {
      status.textContent = "choose a file first";
      return;
    }
    const fileName = name.value;
    const bytes = new Uint8Array(await chosen.arrayBuffer());
    const digest = await sha256(bytes);
    const asked = await confirmWrite({
      title: "Write a file to the slave",
      intro: `ecatd writes the file to slave ${position} over FoE; a file of that name on the slave is replaced.`,
      rows: [["Slave", slaveText(position, slave.name, slave.station)], ["File name", fileName],
        ["Content", `${chosen.name}, ${bytes.length} bytes, SHA-256 ${digest}`]],
      confirm: "Write file",
    });
    if (!asked) {
      status.textContent = "not written";
      return;
    }
    set(0, "sending…");
    delete status.dataset.sha256;
    try {
      await upload(`/slaves/${position}/foe/${encodeURIComponent(fileName)}`, bytes, (phase, f) => {
        // The body reaches ecatd first (half the bar), then ecatd writes it to the slave.
        if (phase === "sending") set(f * 0.5, `sending to ecatd: ${Math.round(f * 100)} %`);
        else set(0.5, "ecatd is writing the file to the slave…");
      });
      set(1, `done: wrote ${bytes.length} bytes, SHA-256 ${digest}`);
      status.dataset.sha256 = digest;
      status.dataset.size = bytes.length;
    } catch (err) {
      set(0, `failed: ${err.message}`);
    }
  };
  controls.push(writeControl(h("span", {}, file, h("button", { type: "button", id: "foe-write", onclick: write }, "Write to slave…")), app));
  fill(body, h("div", { class: "row" }, controls), h("div", { class: "row" }, bar, percent), status, save);
}

const IP_FIELDS = [["mac", "MAC address"], ["ip", "IP address"], ["subnet_mask", "Subnet mask"], ["default_gateway", "Default gateway"], ["dns_server", "DNS server"], ["dns_name", "DNS name"]];

async function eoeView(body, slave, app) {
  const position = slave.position;
  let current;
  try {
    current = await api(`/slaves/${position}/eoe/ip`);
  } catch (err) {
    fill(body, errorLine(err));
    return;
  }
  const inputs = IP_FIELDS.map(([k, label]) => [k, h("input", { id: `eoe-${k}`, type: "text", value: current[k] || "", spellcheck: false }), label]);
  const status = h("span", { role: "status" });
  const form = h("form", {
    class: "form",
    onsubmit: async (e) => {
      e.preventDefault();
      const settings = {};
      for (const [k, input] of inputs) if (input.value.trim()) settings[k] = input.value.trim();
      const asked = await confirmWrite({
        title: "Set the EoE IP parameters",
        intro: `ecatd sends these IP parameters to slave ${position} over EoE.`,
        rows: [["Slave", slaveText(position, slave.name, slave.station)],
          ...IP_FIELDS.filter(([k]) => settings[k]).map(([k, label]) => [label, settings[k]])],
        confirm: "Set IP parameters",
      });
      if (!asked) {
        status.textContent = "not set";
        return;
      }
      status.textContent = "setting…";
      try {
        await api(`/slaves/${position}/eoe/ip`, { method: "PUT", body: settings });
        status.textContent = "set";
      } catch (err) {
        status.textContent = `refused: ${err.message}`;
      }
    },
  }, inputs.map(([k, input, label]) => h("label", { for: `eoe-${k}` }, label, input)), h("div", { class: "row" }, h("button", { type: "submit" }, "Set IP parameters…"), status));
  fill(body, writeControl(form, app));
}

function emergencies(body, position, app) {
  const list = h("ul", { class: "log", id: "emergencies" });
  const render = () => {
    const mine = app.log.filter((e) => e.kind === "emergency" && e.position === position).slice(-20).reverse();
    fill(list, mine.length ? mine.map((e) => h("li", {}, `${e.received.toLocaleTimeString()} error code ${hex(e.emergency.error_code)}, register ${hex(e.emergency.error_register, 2)}, data ${e.emergency.data}`))
      : h("li", { class: "muted" }, "none since this page opened"));
  };
  app.onEvent((e) => {
    if (e.kind === "emergency" && e.position === position) render();
  });
  render();
  fill(body, list);
}

function wide(card) {
  card.classList.add("wide");
  return card;
}

export async function show(view, app, positionText) {
  const position = Number(positionText);
  const slave = await api(`/slaves/${position}`);
  const has = (p) => slave.mailbox_protocols.includes(p);
  const head = h("div", { class: "view-head" },
    h("h2", {}, `Slave ${position}: ${slave.name}`), stateBadge(slave),
    h("a", { href: `#/process-data/${position}`, id: "process-data-link" }, "process data"),
    h("a", { href: "#/segment" }, "back to the segment"));
  const identity = h("div", {}, h("p", { class: "muted" }, "reading the SII…"));
  const parts = [section("Identity and SII", identity)];
  const coe = h("div", { id: "dictionary" });
  const soe = h("div", {});
  const foe = h("div", {});
  const eoe = h("div", {});
  const counters = h("div", {});
  const emcy = h("div", {});
  if (has("CoE")) parts.push(wide(section("CoE dictionary", coe)));
  if (has("SoE")) parts.push(section("SoE IDNs", soe));
  if (has("FoE")) parts.push(section("FoE files", foe));
  if (has("EoE")) parts.push(section("EoE interface", eoe));
  parts.push(section("ESC error counters", counters), section("Recent emergencies", emcy));
  head.append(stateControl(app, {
    label: `slave ${position}`,
    id: "slave",
    // The state it is in now, not when the page opened.
    confirmation: async (state) => stateConfirmation(await api(`/slaves/${position}`), state),
    request: (state) => api(`/slaves/${position}/state`, { method: "PUT", body: { state } }),
  }));
  fill(view, head, h("div", { class: "grid" }, parts));
  emergencies(emcy, position, app);
  if (has("FoE")) foeView(foe, slave, app);
  api(`/slaves/${position}/sii`).then((r) => {
    fill(identity, facts([["Station address", hex(slave.station)], ["Requested state", slave.requested_state],
      ["Mailbox protocols (master)", slave.mailbox_protocols.join(", ") || "none (no mailbox)"],
      ["AL status", `${hex(slave.al_status_code)} ${slave.al_status_text}`], ...siiSummary(bytesOf(r.data))]));
  }).catch((err) => fill(identity, errorLine(err)));
  // One after the other: they share the slave's mailbox.
  (async () => {
    await escCounters(counters, position);
    if (has("CoE")) await dictionary(coe, slave, app);
    if (has("SoE")) await soeView(soe, position);
    if (has("EoE")) await eoeView(eoe, slave, app);
  })();
}
