// The ETG.8200 mailbox gateway: state, start/stop, and live charts from its counters
// (polled each second; rates are the difference between two polls).

import { api } from "./api.js";
import { h, fill, section, facts, errorLine } from "./dom.js";
import { LineChart, bars } from "./chart.js";
import { confirmWrite, writeControl } from "./guard.js";

const PERIOD_MS = 1000;
const REASONS = ["malformed", "unknown_address", "unsupported_protocol", "timeout", "denied", "busy", "oversized", "other"];

export async function show(view, app) {
  const rate = new LineChart({ id: "chart-rps", title: "Requests per second", series: [{ name: "requests/s" }, { name: "failed/s" }], unit: "/s" });
  const failures = new LineChart({ id: "chart-failure-rate", title: "Failure rate (5 % line)", series: [{ name: "failure rate" }], unit: "%", threshold: { value: 5, label: "5 %" } });
  const latency = new LineChart({ id: "chart-latency", title: "Latency percentiles", series: [{ name: "p50" }, { name: "p99" }], unit: "µs" });
  const inflight = new LineChart({ id: "chart-inflight", title: "In flight", series: [{ name: "in flight" }] });
  const state = h("div", {});
  const reasons = h("div", { id: "failure-reasons" });
  const rateText = h("p", { id: "failure-rate", class: "big", role: "status" }, "–");
  const controls = h("div", { class: "row" });
  fill(view, h("div", { class: "view-head" }, h("h2", {}, "Mailbox gateway (ETG.8200)"), controls),
    h("div", { class: "grid" },
      section("State", state, rateText),
      h("div", { class: "card" }, failures.el),
      section("Failures by reason", reasons),
      h("div", { class: "card" }, rate.el),
      h("div", { class: "card" }, latency.el),
      h("div", { class: "card" }, inflight.el)));

  let last = null;
  const poll = async () => {
    let g;
    try {
      g = await api("/gateway");
    } catch (err) {
      fill(state, errorLine(err));
      return;
    }
    const st = g.stats;
    const now = performance.now();
    let failPct = null;
    if (last && st.total_requests >= last.total && st.started_at_ms === last.started) {
      const dt = (now - last.t) / 1000;
      const total = st.total_requests - last.total;
      const failed = st.failed_requests - last.failed;
      rate.push([total / dt, failed / dt]);
      failPct = total > 0 ? (100 * failed) / total : 0;
      failures.push([failPct]);
    }
    last = { t: now, total: st.total_requests, failed: st.failed_requests, started: st.started_at_ms };
    latency.push([st.latency.p50_us ?? null, st.latency.p99_us ?? null]);
    inflight.push([st.in_flight]);
    const overall = st.total_requests ? (100 * st.failed_requests) / st.total_requests : 0;
    rateText.textContent = `failure rate: ${failPct === null ? "–" : failPct.toFixed(1) + " %"} in the last second, ${overall.toFixed(1)} % since start (${st.failed_requests} of ${st.total_requests})`;
    rateText.dataset.overall = overall;
    rateText.classList.toggle("bad", overall > 5 || (failPct ?? 0) > 5);
    fill(state, facts([
      ["Running", g.enabled ? (g.running ? "yes" : "no (stopped)") : "no gateway (--no-gateway)"],
      ["Address", g.bound_address || g.configured_address],
      ["Port", String(g.port)],
      ["Master number", String(g.master_number)],
      ["Strict", g.strict ? "yes" : "no"],
      ["Allowed clients", g.allow.join(", ") || "–"],
      ["Forwarded", String(st.forwarded_requests)],
      ["Retries answered", String(st.retries_answered)],
    ]));
    fill(reasons, bars(REASONS.map((r) => [r.replace(/_/g, " "), st.failures[r]])));
    if (g.enabled && (!controls.firstChild || controls.dataset.running !== String(g.running))) {
      // Drawn again only when the state changes: a poll must not take the focus away.
      controls.dataset.running = String(g.running);
      const action = g.running ? "Stop gateway" : "Start gateway";
      const status = h("span", { class: "muted", role: "status" });
      fill(controls, writeControl(h("button", {
        type: "button",
        id: "gateway-toggle",
        onclick: async () => {
          const asked = await confirmWrite({
            title: action,
            intro: g.running
              ? "ecatd stops answering ETG.8200 requests; tools that use the gateway lose their access to the slaves' mailboxes."
              : "ecatd answers ETG.8200 requests again.",
            rows: [["Gateway", `${g.bound_address || g.configured_address}, UDP port ${g.port}, master ${g.master_number}`], ["Now", g.running ? "running" : "stopped"]],
            confirm: action,
          });
          if (!asked) {
            status.textContent = "not changed";
            return;
          }
          try {
            await api(g.running ? "/gateway/stop" : "/gateway/start", { method: "POST", body: {} });
          } catch (err) {
            status.textContent = `refused: ${err.message}`;
          }
          poll();
        },
      }, `${action}…`), app), status);
    }
  };
  await poll();
  const timer = setInterval(poll, PERIOD_MS);
  return { stop: () => clearInterval(timer) };
}
