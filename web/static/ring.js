// Cable redundancy (docs/redundancy.md): the segment drawn as the ring it is wired as, the
// master's primary port → every slave in ring order → back into its backup port, from
// GET /api/v1/master's `redundancy`. A broken cable is drawn cut and marked; slaves that
// neither port reaches (between two cuts, or without power) are greyed. The master cannot
// tell a cut cable from a dead slave: with slaves unreachable, both cables around them are
// drawn without communication.

import { h, s } from "./dom.js";

const SLAVE_W = 74;
const GAP = 34;
const MASTER_W = 86;
const TOP = 28;
const BOX_H = 44;
const RETURN_Y = TOP + BOX_H + 34;

/** Words for the ring's state, for the summary line and screen readers. */
export function ringText(r) {
  switch (r.state) {
    case "closed":
      return `Ring closed: all ${r.ring_slaves} slaves reached on both ports. Breaks ${r.breaks}, heals ${r.heals}.`;
    case "broken": {
      const lost = r.unreachable ? `, ${r.unreachable} unreachable` : "";
      const place =
        r.break_after === 0
          ? "at the master's primary cable"
          : r.break_after >= r.ring_slaves
            ? "at the master's backup cable"
            : `between positions ${r.break_after - 1} and ${r.break_after}`;
      return `Ring BROKEN ${place}: ${r.primary_side} on the primary port, ${r.backup_side} on the backup port${lost}. Breaks ${r.breaks}, heals ${r.heals}.`;
    }
    case "unknown":
      return "Ring state not known yet: no frame has come back.";
    default:
      return "Cable redundancy off: one port.";
  }
}

/**
 * The ring as an SVG figure, or null with redundancy off. `names` are the slaves' names by
 * position (from GET /slaves), for the labels.
 */
export function ringFigure(r, names) {
  if (!r || r.state === "off") return null;
  const n = Math.max(r.ring_slaves || 0, names.length);
  const broken = r.state === "broken";
  const after = broken ? r.break_after : null;
  const lostFrom = broken ? r.primary_side : n;
  const lostTo = broken ? r.primary_side + r.unreachable : n;
  /** Cable k runs into slave k (k = n: from the last slave back into the backup port). */
  const cut = (k) => broken && (k === after || (r.unreachable > 0 && k === lostTo));
  const x = (i) => MASTER_W + GAP + i * (SLAVE_W + GAP);
  const width = x(n) + 10;
  const height = RETURN_Y + 24;
  const mid = TOP + BOX_H / 2;
  const parts = [];
  const cable = (k, d) => {
    const gone = cut(k);
    parts.push(s("path", { d, class: `ring-cable${gone ? " ring-cable-cut" : ""}`, "data-cable": k }));
  };
  // The master with its two ports.
  parts.push(s("rect", { x: 4, y: TOP - 8, width: MASTER_W - 8, height: BOX_H + 50, rx: 6, class: "ring-master" }),
    s("text", { x: MASTER_W / 2, y: TOP + 10, class: "ring-label", "text-anchor": "middle" }, "master"),
    s("text", { x: MASTER_W - 10, y: mid + 4, class: "ring-port", "text-anchor": "end" }, "primary"),
    s("text", { x: MASTER_W - 10, y: RETURN_Y + 4, class: "ring-port", "text-anchor": "end" }, "backup"));
  // Cables: primary port → slave 0 → … → slave n-1, then back along the bottom.
  for (let k = 0; k < n; k++) {
    const from = k === 0 ? MASTER_W - 4 : x(k - 1) + SLAVE_W;
    cable(k, `M ${from} ${mid} H ${x(k)}`);
  }
  const last = n > 0 ? x(n - 1) + SLAVE_W : MASTER_W;
  cable(n, `M ${last} ${mid} H ${last + GAP / 2} V ${RETURN_Y} H ${MASTER_W - 4}`);
  // The cut: a red ✕ on the broken cable(s).
  for (let k = 0; k <= n; k++) {
    if (!cut(k)) continue;
    const cx = k < n ? x(k) - GAP / 2 : last + GAP / 2;
    const cy = k < n ? mid : (mid + RETURN_Y) / 2;
    parts.push(s("text", { x: cx, y: cy + 6, class: "ring-cut-mark", "text-anchor": "middle", "data-cut": k }, "✕"));
  }
  for (let i = 0; i < n; i++) {
    const lost = broken && i >= lostFrom && i < lostTo;
    const side = !broken ? "ring" : i < r.primary_side ? "primary" : lost ? "unreachable" : "backup";
    parts.push(s("g", { class: `ring-slave ring-slave-${side}`, "data-position": i, "data-side": side },
      s("rect", { x: x(i), y: TOP, width: SLAVE_W, height: BOX_H, rx: 4 }),
      s("text", { x: x(i) + SLAVE_W / 2, y: TOP + 18, "text-anchor": "middle", class: "ring-label" }, String(i)),
      s("text", { x: x(i) + SLAVE_W / 2, y: TOP + 34, "text-anchor": "middle", class: "ring-name" },
        lost ? "unreachable" : (names[i] || "").replace(/^ECATD-SIM /, "").slice(0, 11))));
  }
  const svg = s("svg", {
    viewBox: `0 0 ${width} ${height}`, role: "img", class: "ring-svg", "aria-label": ringText(r),
    "data-ring-state": r.state, "data-break-after": after ?? "",
  }, parts);
  return h("figure", { class: "ring" }, h("div", { class: "ring-scroll" }, svg));
}
