// The process data the cycle carries (#/process-data, #/process-data/3): every mapped entry
// with its value, live from /api/v1/process-data/stream, bits as lamps, a trend of one
// entry, outputs forced and released behind a confirmation (write role); and the key values
// the segment view shows per slave (a CiA 402 drive's state, a digital terminal's bits).

import { api, stream } from "./api.js";
import { h, fill, hex, section, facts, errorLine, lamp, setLamp, Modal } from "./dom.js";
import { LineChart } from "./chart.js";
import { confirmWrite, slaveText, writeControl } from "./guard.js";

/** How often the page asks for changed values (ms): at least ten updates a second. */
const STREAM_MS = 100;
/** Trend samples: ten seconds at one a stream interval. */
const TREND_POINTS = 100;

/**
 * CiA 402 power states by statusword (CiA 402-2 / IEC 61800-7-201 "state coding"): bits
 * 0-3 and 6 (mask 0x4F) for four states, bits 0-3, 5 and 6 (mask 0x6F) for the others.
 */
const CIA402_STATES = [
  [0x4f, 0x00, "Not ready to switch on"],
  [0x4f, 0x40, "Switch on disabled"],
  [0x6f, 0x21, "Ready to switch on"],
  [0x6f, 0x23, "Switched on"],
  [0x6f, 0x27, "Operation enabled"],
  [0x6f, 0x07, "Quick stop active"],
  [0x4f, 0x0f, "Fault reaction active"],
  [0x4f, 0x08, "Fault"],
];

/** The CiA 402 power state a statusword (0x6041) reports. */
export function cia402State(statusword) {
  const found = CIA402_STATES.find(([mask, value]) => (statusword & mask) === value);
  return found ? found[2] : "Unknown state";
}

/** Whether `e` is a CiA 402 statusword the slave sends. */
function isStatusword(e) {
  return e.index === 0x6041 && e.subindex === 0 && e.direction === "in";
}

/** One entry's key in the image: slave, index, subindex. */
function entryKey(e) {
  return `${e.slave}:${e.index}:${e.subindex}`;
}

/** A digital input or output: one bit (or a BOOLEAN). */
function isBit(e) {
  return e.bit_length === 1 || e.type === "BOOLEAN" || typeof e.value === "boolean";
}

function sub(n) {
  return n.toString(16).toUpperCase().padStart(2, "0");
}

/** `0x7000:01`. */
function objectName(e) {
  return `${hex(e.index)}:${sub(e.subindex)}`;
}

/** Whether values of `e` can be drawn (numbers and bits, not strings or long octets). */
function chartable(e) {
  return e.bit_length <= 64 && !/STRING|OCTET|DOMAIN/.test(e.type);
}

/** A value as text: bits on/off, unsigned integers with their hex, others as hex bytes. */
function valueText(e, value = e.value) {
  if (value === undefined || value === null) return "–";
  if (typeof value === "boolean") return value ? "on" : "off";
  if (typeof value === "string") return "0x" + value;
  if (/^(UNSIGNED|BYTE|WORD|DWORD)/.test(e.type) && Number.isInteger(value) && value >= 0 && e.bit_length >= 8) {
    return `${value} (${hex(value, Math.ceil(e.bit_length / 4))})`;
  }
  return String(value);
}

/** A value as a number for the trend (bits as 0 and 1). */
function numeric(value) {
  if (typeof value === "boolean") return value ? 1 : 0;
  return typeof value === "number" ? value : null;
}

/**
 * The key values of one slave for the segment view: a CiA 402 drive's power state, a
 * digital terminal's bits as lamps, else its first few entries; null without process data.
 */
export function keyValues(position, entries) {
  if (!entries.length) return null;
  const link = h("a", { href: `#/process-data/${position}`, class: "pd-link" }, "process data");
  const status = entries.find(isStatusword);
  if (status && typeof status.value === "number") {
    return h("p", { class: "key-values" }, "CiA 402: ",
      h("strong", { class: "cia402-state", "data-statusword": status.value }, cia402State(status.value)),
      ` (statusword ${hex(status.value)}) `, link);
  }
  if (entries.every(isBit)) {
    const groups = ["in", "out"].map((dir) => entries.filter((e) => e.direction === dir)).filter((g) => g.length);
    return h("div", { class: "key-values" }, groups.map((g) => h("div", { class: "lamps-row" },
      h("span", { class: "muted" }, g[0].direction === "in" ? "Inputs" : "Outputs"),
      h("ul", { class: "lamps", "aria-label": g[0].direction === "in" ? "inputs" : "outputs" },
        g.map((e) => h("li", {}, lamp(Boolean(e.value), e.name, String(e.subindex))))))), link);
  }
  return h("p", { class: "key-values" }, entries.slice(0, 3).map((e) => `${e.name}: ${valueText(e)}; `), link);
}

/** The number (or boolean) typed for output `e`, or a message saying what is wrong. */
function parseValue(e, text) {
  if (text === "true" || text === "false") return { value: text === "true" };
  const t = text.trim();
  if (!t) return { error: "enter a value first" };
  const n = /^[-+]?0x[0-9a-f]+$/i.test(t) ? parseInt(t, 16) : Number(t);
  if (!Number.isFinite(n)) return { error: `${t} is not a number` };
  if (!/REAL/.test(e.type) && !Number.isInteger(n)) return { error: `${e.type || "this entry"} takes an integer` };
  return { value: n };
}

/** The API path of output `e`. */
function outputPath(e) {
  return `/slaves/${e.slave}/process-data/${hex(e.index)}/${e.subindex}`;
}

/**
 * Asks to confirm forcing output `e` of slave `slaveName` to `value`, then forces it; a
 * refusal because an application owns the outputs (409) is said, with "Force anyway
 * (override)" as a second explicit confirmation. Resolves with ecatd's answer, or null when
 * nothing was forced. `opened(modal)` gets the dialog (closed when the view is left).
 */
async function confirmForce(e, slaveName, value, opened) {
  const modal = new Modal("force-dialog", "Force an output");
  opened(modal);
  const what = () => [
    h("p", {}, "From the next cycle on, ecatd writes this value into the output in every cycle, until it is released:"),
    facts([
      ["Slave", `${e.slave}: ${slaveName} (station ${hex(e.station)})`],
      ["Object", `${objectName(e)} ${e.name}`],
      ["Type", `${e.type || "unknown type"}, ${e.bit_length} bit`],
      ["Value", typeof value === "boolean" ? `${value ? "on" : "off"} (${value ? 1 : 0})` : valueText(e, value)],
    ]),
  ];
  let override = false;
  let choice = await modal.ask(what(), [
    { label: "Force", value: "force", id: "force-confirm", class: "write" },
    { label: "Cancel", value: "", id: "force-cancel", focus: true },
  ]);
  while (choice) {
    modal.busy(override ? "forcing over the application…" : "forcing…");
    try {
      const forced = await api(outputPath(e), { method: "PUT", body: { value, override } });
      modal.close();
      return forced;
    } catch (err) {
      const owned = err.status === 409 && (!err.kind || String(err.kind).toUpperCase() === "OUTPUTS_OWNED");
      if (owned && !override) {
        override = true;
        choice = await modal.ask([
          ...what(),
          h("p", { class: "error", role: "alert", id: "force-refusal" }, `ecatd refused: ${err.message}`),
          h("p", {}, "An application owns the outputs. Forcing anyway writes over the value it sets for this output, in every cycle until released."),
        ], [
          { label: "Force anyway (override)", value: "override", id: "force-override", class: "write danger" },
          { label: "Cancel", value: "", id: "force-cancel", focus: true },
        ]);
      } else {
        await modal.ask([...what(), h("p", { class: "error", role: "alert", id: "force-refusal" }, `ecatd refused: ${err.message}`)],
          [{ label: "Close", value: "", id: "force-cancel" }]);
        choice = "";
      }
    }
  }
  modal.close();
  return null;
}

/** The row of one entry: its cells, and `update(e)` for each new value. */
function entryRow(e, ctx) {
  const id = `pd-${e.slave}-${e.index.toString(16).padStart(4, "0")}-${sub(e.subindex).toLowerCase()}`;
  const forcedBy = h("span", { class: "forced-by", hidden: true });
  const bit = isBit(e);
  const shown = bit ? lamp(false, e.name) : h("output", { class: "value" }, "–");
  const state = isStatusword(e) ? h("span", { class: "cia402-state" }) : null;
  const trend = chartable(e)
    ? h("button", { type: "button", class: "trend-pick", "aria-pressed": "false", "aria-label": `Trend of ${e.name} (slave ${e.slave}, ${objectName(e)})`, onclick: () => ctx.pickTrend(entryKey(e)) }, "Trend")
    : "";
  const tr = h("tr", { id, class: `pd-entry pd-${e.direction}`, "data-slave": e.slave, "data-index": e.index, "data-subindex": e.subindex, "data-direction": e.direction },
    h("td", {}, h("span", { class: "pd-name" }, e.name || "(no name)"), " ", forcedBy),
    h("td", {}, h("code", {}, objectName(e))),
    h("td", { class: "entry-type", title: `${e.bit_length} bit at image bit ${e.bit_offset}, PDO ${hex(e.pdo)}` }, e.type || `${e.bit_length} bit`),
    h("td", {}, e.direction === "in" ? "input" : "output"),
    h("td", { class: "pd-value" }, shown, state),
    h("td", {}, trend));
  let release = null;
  if (ctx.forceColumn(e.slave)) {
    const cell = h("td", { class: "pd-force" });
    if (e.direction === "out") {
      const label = `value for ${e.name} (slave ${e.slave}, ${objectName(e)})`;
      const input = bit
        ? h("select", { class: "force-value", "aria-label": `New ${label}` }, h("option", { value: "true" }, "on"), h("option", { value: "false" }, "off"))
        : h("input", { class: "force-value", type: "text", inputmode: "decimal", size: 8, placeholder: "value", spellcheck: false, "aria-label": `New ${label}` });
      const status = h("span", { class: "muted force-status", role: "status" });
      const force = async () => {
        const parsed = parseValue(e, input.value);
        if (parsed.error) {
          status.textContent = parsed.error;
          return;
        }
        status.textContent = "";
        const forced = await ctx.confirmForce(e, parsed.value);
        if (forced) {
          status.textContent = forced.override ? "forced over the application" : "forced";
          row.update({ ...row.entry, forced_by: forced.forced_by });
        } else {
          status.textContent = "not forced";
        }
      };
      if (!bit) input.addEventListener("keydown", (ev) => {
        if (ev.key === "Enter") force();
      });
      release = h("button", {
        type: "button",
        class: "release",
        hidden: true,
        "aria-label": `Release ${e.name} (slave ${e.slave}, ${objectName(e)})`,
        onclick: async () => {
          if (!(await ctx.confirmRelease(row.entry))) {
            status.textContent = "not released";
            return;
          }
          status.textContent = "releasing…";
          try {
            await api(outputPath(e), { method: "DELETE" });
            status.textContent = "released";
            row.update({ ...row.entry, forced_by: undefined });
          } catch (err) {
            status.textContent = `refused: ${err.message}`;
          }
        },
      }, "Release");
      cell.append(writeControl(h("span", { class: "force-controls" }, input,
        h("button", { type: "button", class: "force", "aria-label": `Force ${e.name} (slave ${e.slave}, ${objectName(e)})…`, onclick: force }, "Force…"),
        release), ctx.app), status);
    }
    tr.append(cell);
  }
  const row = {
    entry: e,
    tr,
    trend,
    update(next) {
      row.entry = next;
      if (bit) setLamp(shown, Boolean(next.value), next.name);
      else shown.textContent = valueText(next);
      if (state) state.textContent = typeof next.value === "number" ? cia402State(next.value) : "";
      tr.dataset.value = String(next.value);
      const by = next.forced_by || "";
      tr.classList.toggle("forced", Boolean(by));
      tr.dataset.forcedBy = by;
      forcedBy.hidden = !by;
      forcedBy.textContent = by ? `forced by ${by}` : "";
      if (release) release.hidden = !by;
    },
  };
  return row;
}

/** #/process-data (every slave) and #/process-data/3 (one). */
export async function showProcessData(view, app, positionText) {
  const only = positionText === undefined || positionText === "" ? null : Number(positionText);
  const [slaves, layout] = await Promise.all([api("/slaves"), api("/process-data/layout")]);
  const names = new Map(slaves.map((sl) => [sl.position, sl.name || "(no name)"]));
  const pick = h("select", {
    id: "pd-slave",
    "aria-label": "Slave",
    onchange: () => {
      location.hash = pick.value === "" ? "#/process-data" : `#/process-data/${pick.value}`;
    },
  }, h("option", { value: "" }, "All slaves"),
  slaves.map((sl) => h("option", { value: String(sl.position), selected: sl.position === only }, `${sl.position}: ${names.get(sl.position)}`)));
  const cycle = h("p", { id: "pd-cycle", class: "muted" }, "waiting for the first values…");
  const live = h("span", { id: "pd-live", class: "live", role: "status" }, "connecting…");
  const head = h("div", { class: "view-head" }, h("h2", {}, "Process data"), pick, live, cycle);
  if (only !== null && !names.has(only)) {
    fill(view, head, errorLine(`no slave at position ${positionText}`));
    return null;
  }
  const entries = layout.entries.filter((e) => only === null || e.slave === only);
  if (!entries.length) {
    fill(view, head, h("p", { class: "muted" }, only === null ? "No process data is mapped (no slave exchanges cyclic data)." : `Slave ${only} maps no process data.`));
    return null;
  }

  let modal = null;
  let trendKey = null;
  let chart = null;
  const trendBox = h("div", { id: "pd-trend" });
  const rows = new Map();
  const ctx = {
    app,
    /** Whether the slave's table has the Force column: outputs to force (disabled without the write role). */
    forceColumn: (position) => entries.some((e) => e.slave === position && e.direction === "out"),
    confirmRelease: (e) => confirmWrite({
      title: "Release a forced output",
      intro: "From the next cycle on, the output takes what the control program writes again; with no program, it keeps the value it has.",
      rows: [["Slave", slaveText(e.slave, names.get(e.slave), e.station)], ["Object", `${objectName(e)} ${e.name}`],
        ["Forced value", valueText(e)], ["Forced by", e.forced_by || "–"]],
      confirm: "Release",
    }),
    confirmForce: (e, value) => confirmForce(e, names.get(e.slave), value, (m) => {
      modal = m;
    }),
    pickTrend(key) {
      trendKey = key;
      const e = rows.get(key).entry;
      chart = new LineChart({ id: "chart-trend", title: `Slave ${e.slave}: ${e.name} (${objectName(e)})`, series: [{ name: e.name }], points: TREND_POINTS, span: "last 10 s", yMin: null });
      fill(trendBox, chart.el);
      for (const r of rows.values()) if (r.trend) r.trend.setAttribute("aria-pressed", String(r === rows.get(key)));
    },
  };
  const cards = [];
  for (const position of [...new Set(entries.map((e) => e.slave))]) {
    const mine = entries.filter((e) => e.slave === position).map((e) => entryRow(e, ctx));
    for (const r of mine) rows.set(entryKey(r.entry), r);
    const titleId = `pd-title-${position}`;
    cards.push(h("section", { class: "card pd-slave", "aria-labelledby": titleId, "data-position": position },
      h("h2", { id: titleId }, `Slave ${position}: ${names.get(position)} `,
        h("a", { href: `#/slave/${position}`, class: "muted-link" }, "slave page"),
        only === null ? [" · ", h("a", { href: `#/process-data/${position}`, class: "muted-link" }, "only this slave")] : ""),
      h("div", { class: "table-scroll" },
        // Without a Force column beside tables that have one, the Trend column takes its width.
        h("table", { class: `table pd-table${entries.some((e) => e.direction === "out") && !ctx.forceColumn(position) ? " no-force" : ""}` },
          h("thead", {}, h("tr", {}, ["Name", "Object", "Type", "Direction", "Value", "Trend", ctx.forceColumn(position) ? "Force" : null]
            .filter(Boolean).map((t) => h("th", { scope: "col" }, t)))),
          h("tbody", {}, mine.map((r) => r.tr))))));
  }
  const trendCard = section("Trend", h("p", { class: "muted" }, `Sampled every ${STREAM_MS} ms; an entry's Trend button chooses what it shows.`), trendBox);
  trendCard.classList.add("pd-trend");
  fill(view, head, h("div", { class: "pd-grid" }, trendCard, cards));
  const first = entries.find((e) => e.direction === "in" && !isBit(e) && chartable(e)) || entries.find(chartable);
  if (first) ctx.pickTrend(entryKey(first));

  const interval = Math.max(STREAM_MS, Math.ceil(layout.period_ns / 1e6));
  let events = 0;
  let stale = false;
  const values = stream(`/process-data/stream?interval=${interval}ms${only === null ? "" : `&slave=${only}`}`, (data, name) => {
    if (name !== "values") return;
    events += 1;
    live.dataset.events = events;
    for (const e of data.entries) {
      const row = rows.get(entryKey(e));
      if (row) row.update(e);
      else stale = true;
    }
    cycle.textContent = `last change in cycle ${data.cycle}, working counter ${data.wkc} of ${data.expected_wkc}${data.wkc === data.expected_wkc ? "" : " (MISMATCH)"}`;
    if (stale) {
      // A rescan changed the image: show the new layout (the router builds the view again).
      values.stop();
      window.dispatchEvent(new HashChangeEvent("hashchange"));
    }
  }, (status, err) => {
    live.dataset.status = status;
    live.textContent = status === "live" ? `values: live, every ${interval} ms` : `values: ${status}${err ? ` (${err.message})` : ""}`;
  });
  const sampler = setInterval(() => {
    if (chart && trendKey) chart.push([numeric(rows.get(trendKey).entry.value)]);
  }, interval);
  return {
    stop() {
      values.stop();
      clearInterval(sampler);
      if (modal) modal.close();
    },
  };
}
