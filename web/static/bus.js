// The bus: cycle time and jitter, frames lost, working counter, polled each second.

import { api } from "./api.js";
import { h, fill, section, facts, errorLine } from "./dom.js";
import { LineChart } from "./chart.js";

const PERIOD_MS = 1000;

export async function show(view) {
  const cycle = new LineChart({ id: "chart-cycle", title: "Cycle time", series: [{ name: "p50" }, { name: "p99" }], unit: "µs" });
  const jitter = new LineChart({ id: "chart-jitter", title: "Jitter", series: [{ name: "p50" }, { name: "p99" }], unit: "µs" });
  const lost = new LineChart({ id: "chart-lost", title: "Frames lost and wrong working counters per second", series: [{ name: "frames lost/s" }, { name: "wrong WKC/s" }], unit: "/s" });
  const wkc = new LineChart({ id: "chart-wkc", title: "Working counter", series: [{ name: "last" }, { name: "expected" }] });
  const totals = h("div", {});
  fill(view, h("div", { class: "view-head" }, h("h2", {}, "Bus")),
    h("div", { class: "grid" }, section("Totals", totals),
      h("div", { class: "card" }, cycle.el), h("div", { class: "card" }, jitter.el),
      h("div", { class: "card" }, lost.el), h("div", { class: "card" }, wkc.el)));
  let last = null;
  const poll = async () => {
    let b;
    try {
      b = await api("/bus");
    } catch (err) {
      fill(totals, errorLine(err));
      return;
    }
    const now = performance.now();
    cycle.push([b.cycle_time.p50_us ?? null, b.cycle_time.p99_us ?? null]);
    jitter.push([b.jitter.p50_us ?? null, b.jitter.p99_us ?? null]);
    if (last) {
      const dt = (now - last.t) / 1000;
      lost.push([(b.frames_lost - last.lost) / dt, (b.cycles_wrong_wkc - last.wrong) / dt]);
    }
    last = { t: now, lost: b.frames_lost, wrong: b.cycles_wrong_wkc };
    wkc.push([b.last_wkc, b.expected_wkc]);
    fill(totals, facts([
      ["Cycle period", b.period_us ? `${b.period_us} µs` : "no cyclic exchange"],
      ["Frames sent / received", `${b.frames_sent} / ${b.frames_received}`],
      ["Frames lost", String(b.frames_lost)],
      ["Cycles completed / lost / late", `${b.cycles_completed} / ${b.cycles_lost} / ${b.cycles_late}`],
      ["Working counter", `${b.last_wkc} of ${b.expected_wkc} expected${b.last_wkc === b.expected_wkc ? "" : " (MISMATCH)"}`],
      ["Wrong working counters", String(b.cycles_wrong_wkc)],
      ["Process image", `${b.image_bytes} bytes`],
      ["Link errors", String(b.link_errors)],
    ]));
  };
  await poll();
  const timer = setInterval(poll, PERIOD_MS);
  return { stop: () => clearInterval(timer) };
}
