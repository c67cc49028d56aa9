// The CoE object dictionary as a tree, from SDO Information (spec-notes §coe.info): the
// object list, each object's description, and its entries' descriptions when opened.
// Values are read on demand and decoded by their data type; a writable entry gets an editor
// for its type, behind a confirmation (disabled without the write role).

import { api } from "./api.js";
import { h, fill, hex, errorLine } from "./dom.js";
import { confirmWrite, slaveText, writeControl } from "./guard.js";

const OBJECT_CODES = { 7: "VAR", 8: "ARRAY", 9: "RECORD" };
/** Object access bits 3-5: writable in PREOP, SAFEOP, OP (spec-notes §coe.info). */
const WRITE_BITS = 0x38;

function sub(n) {
  return n.toString(16).toUpperCase().padStart(2, "0");
}

/** An input suited to the data type: a true/false choice, a number, or text. */
function editor(entry, label) {
  const type = entry.data_type_name.toUpperCase();
  if (type === "BOOLEAN") {
    return h("select", { class: "editor", "aria-label": label }, h("option", { value: "true" }, "true"), h("option", { value: "false" }, "false"));
  }
  const numeric = /INTEGER|UNSIGNED|REAL|BYTE|WORD/.test(type);
  return h("input", {
    class: "editor",
    type: "text",
    inputmode: numeric ? "decimal" : "text",
    "aria-label": label,
    placeholder: numeric ? "number (or 0x hex)" : type.includes("STRING") && !type.includes("VISIBLE") ? "hex bytes" : "text",
    spellcheck: false,
  });
}

function entryRow(slave, entry, app) {
  const position = slave.position;
  const id = `entry-${entry.index.toString(16).padStart(4, "0")}-${sub(entry.subindex).toLowerCase()}`;
  const label = `${hex(entry.index)}:${sub(entry.subindex)}`;
  const output = h("output", { class: "value", "aria-live": "polite" }, "not read");
  const read = async () => {
    output.textContent = "reading…";
    output.classList.remove("error");
    try {
      const r = await api(`/slaves/${position}/coe/sdo/${hex(entry.index)}/${entry.subindex}?type=auto`);
      output.textContent = r.value ?? r.data;
      output.dataset.hex = r.data;
    } catch (err) {
      output.textContent = err.message;
      output.classList.add("error");
    }
  };
  const writable = (entry.access & WRITE_BITS) !== 0;
  const row = h("div", { class: "entry", id },
    h("span", { class: "entry-name" }, h("code", {}, label), " ", entry.description || "(no name)"),
    h("span", { class: "entry-type" }, `${entry.data_type_name}, ${entry.bit_length} bit, ${writable ? "read/write" : "read only"}`),
    h("button", { type: "button", class: "read", onclick: read, "aria-label": `Read ${label}` }, "Read"),
    output);
  if (writable) {
    const input = editor(entry, `New value for ${label}`);
    const status = h("span", { class: "write-status", role: "status" });
    const write = async () => {
      const value = input.value;
      if (value.trim() === "" && !entry.data_type_name.toUpperCase().includes("STRING")) {
        status.textContent = "enter a value first";
        return;
      }
      const rows = [["Slave", slaveText(slave.position, slave.name, slave.station)],
        ["Object", `${label} ${entry.description || "(no name)"}`], ["Type", `${entry.data_type_name}, ${entry.bit_length} bit`]];
      if (output.dataset.hex !== undefined) rows.push(["Now", output.textContent]);
      rows.push(["New value", value]);
      const asked = await confirmWrite({
        title: "Write a CoE entry",
        intro: `ecatd writes the value to slave ${slave.position} with an SDO download.`,
        rows,
        confirm: "Write value",
      });
      if (!asked) {
        status.textContent = "not written";
        return;
      }
      status.textContent = "writing…";
      try {
        await api(`/slaves/${position}/coe/sdo/${hex(entry.index)}/${entry.subindex}`, { method: "PUT", body: { value, type: "auto" } });
        status.textContent = "written";
        await read();
      } catch (err) {
        status.textContent = `refused: ${err.message}`;
      }
    };
    input.addEventListener("keydown", (e) => {
      if (e.key === "Enter") write();
    });
    row.append(writeControl(h("span", { class: "entry-write" }, input, h("button", { type: "button", class: "write-value", onclick: write }, "Write…"), status), app));
  }
  return row;
}

async function openObject(slave, object, body, app) {
  const position = slave.position;
  const subs = object.object_code === 7 ? [0] : Array.from({ length: object.max_subindex + 1 }, (_, i) => i);
  fill(body, h("p", { class: "muted" }, "reading entries…"));
  const rows = [];
  for (const n of subs) {
    try {
      const entry = await api(`/slaves/${position}/coe/od/${hex(object.index)}/${n}`);
      rows.push(entryRow(slave, entry, app));
    } catch (err) {
      rows.push(h("div", { class: "entry" }, h("code", {}, `${hex(object.index)}:${sub(n)}`), " ", errorLine(err)));
    }
  }
  fill(body, rows);
}

/** The dictionary of `slave` (as GET /slaves/{position} answers it), into `container`. */
export async function dictionary(container, slave, app) {
  const position = slave.position;
  fill(container, h("p", { class: "muted" }, "reading the object list…"));
  let list;
  try {
    list = await api(`/slaves/${position}/coe/od`);
  } catch (err) {
    fill(container, errorLine(err));
    return;
  }
  const filter = h("input", { type: "search", placeholder: "filter by index or name", "aria-label": "Filter objects" });
  const tree = h("div", { class: "tree", role: "group", "aria-label": "CoE objects" });
  fill(container, h("label", { class: "filter" }, "Filter ", filter), tree);
  const nodes = list.indices.map((index) => {
    const title = h("span", {}, hex(index), " …");
    const body = h("div", { class: "entries" });
    const node = h("details", { class: "object", id: `object-${index.toString(16).padStart(4, "0")}`, "data-index": index }, h("summary", {}, title), body);
    node.addEventListener("toggle", () => {
      if (node.open && !node.dataset.loaded && node.object) {
        node.dataset.loaded = "1";
        openObject(slave, node.object, body, app);
      }
    });
    tree.append(node);
    return { index, node, title };
  });
  filter.addEventListener("input", () => {
    const q = filter.value.trim().toLowerCase();
    for (const n of nodes) n.node.hidden = q !== "" && !n.title.textContent.toLowerCase().includes(q);
  });
  // Descriptions four at a time: the mailbox serves one request per slave at a time anyway.
  let next = 0;
  const worker = async () => {
    while (next < nodes.length) {
      const n = nodes[next++];
      try {
        const o = await api(`/slaves/${position}/coe/od/${hex(n.index)}`);
        n.node.object = o;
        fill(n.title, h("code", {}, hex(o.index)), ` ${o.name || "(no name)"} `, h("span", { class: "muted" }, `${OBJECT_CODES[o.object_code] || o.object_code}, ${o.data_type_name}${o.object_code === 7 ? "" : `, ${o.max_subindex} entries`}`));
        if (n.node.open && !n.node.dataset.loaded) n.node.dispatchEvent(new Event("toggle"));
      } catch (err) {
        fill(n.title, h("code", {}, hex(n.index)), " ", h("span", { class: "error" }, err.message));
      }
    }
  };
  await Promise.all([worker(), worker(), worker(), worker()]);
}
