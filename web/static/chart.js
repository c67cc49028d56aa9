// A small live line chart in SVG: the last `points` samples of one or more series, an
// optional threshold line (the gateway's 5 % failure rate), axis labels as text, and the
// latest values in a legend that says in words what each colour is.

import { h, s, fill } from "./dom.js";

const W = 600;
const H = 180;
const PAD = { left: 48, right: 10, top: 10, bottom: 22 };

function niceMax(value) {
  if (!(value > 0)) return 1;
  const p = Math.pow(10, Math.floor(Math.log10(value)));
  for (const m of [1, 2, 2.5, 5, 10]) if (m * p >= value) return m * p;
  return 10 * p;
}

function format(value, unit) {
  if (value === null || value === undefined || Number.isNaN(value)) return "–";
  const text = Math.abs(value) >= 100 ? value.toFixed(0) : Math.abs(value) >= 10 ? value.toFixed(1) : value.toFixed(2);
  return unit ? `${text} ${unit}` : text;
}

export class LineChart {
  /**
   * `id`: element id of the chart; `title`; `series`: [{name, key}] (colours from the
   * stylesheet by index); `unit`; `threshold`: {value, label}; `yMin`, the bottom of the y
   * range (null: from the data, 0 unless a value is negative); `points` samples, which
   * `span` names on the time axis (one a second by default).
   */
  constructor({ id, title, series, unit = "", threshold = null, yMin = 0, points = 60, span = null }) {
    this.series = series;
    this.unit = unit;
    this.threshold = threshold;
    this.yMin = yMin;
    this.points = points;
    this.span = span || `last ${points} s`;
    this.data = series.map(() => []);
    this.svg = s("svg", { viewBox: `0 0 ${W} ${H}`, role: "img", "aria-label": title, class: "chart-svg", id });
    this.legend = h("ul", { class: "legend" });
    this.el = h("figure", { class: "chart" }, h("figcaption", {}, title), this.svg, this.legend);
    this.draw();
  }

  /** Adds one sample per series (null for a gap). */
  push(values) {
    values.forEach((v, i) => {
      const d = this.data[i];
      d.push(v);
      if (d.length > this.points) d.shift();
    });
    this.draw();
  }

  /** The latest value of series `i`. */
  last(i = 0) {
    const d = this.data[i];
    return d.length ? d[d.length - 1] : null;
  }

  draw() {
    const all = this.data.flat().filter((v) => v !== null && !Number.isNaN(v));
    const top = niceMax(Math.max(this.threshold ? this.threshold.value * 1.5 : 0, ...all, 0));
    const low = Math.min(...all, 0);
    const bottom = this.yMin ?? (low < 0 ? -niceMax(-low) : 0);
    const x = (i) => PAD.left + (i * (W - PAD.left - PAD.right)) / (this.points - 1);
    const y = (v) => H - PAD.bottom - ((v - bottom) / (top - bottom)) * (H - PAD.top - PAD.bottom);
    const grid = [0, 0.5, 1].map((f) => {
      const v = bottom + f * (top - bottom);
      return [
        s("line", { x1: PAD.left, x2: W - PAD.right, y1: y(v), y2: y(v), class: "grid" }),
        s("text", { x: PAD.left - 6, y: y(v) + 4, class: "axis", "text-anchor": "end" }, format(v, "")),
      ];
    });
    const lines = this.data.map((d, si) => {
      const offset = this.points - d.length;
      let path = "";
      let pen = false;
      d.forEach((v, i) => {
        if (v === null || Number.isNaN(v)) {
          pen = false;
          return;
        }
        path += `${pen ? "L" : "M"}${x(i + offset).toFixed(1)},${y(v).toFixed(1)}`;
        pen = true;
      });
      return s("path", { d: path || "M0,0", class: `line series-${si}`, "data-series": this.series[si].name, "data-last": this.last(si) ?? "" });
    });
    const threshold = this.threshold
      ? [
          s("line", { x1: PAD.left, x2: W - PAD.right, y1: y(this.threshold.value), y2: y(this.threshold.value), class: "threshold" }),
          s("text", { x: W - PAD.right - 4, y: y(this.threshold.value) - 4, class: "axis threshold-label", "text-anchor": "end" }, this.threshold.label),
        ]
      : [];
    fill(this.svg,
      grid,
      s("text", { x: PAD.left, y: H - 6, class: "axis" }, this.span),
      threshold,
      lines);
    fill(this.legend, this.series.map((se, i) =>
      h("li", {}, h("span", { class: `swatch series-${i}`, "aria-hidden": "true" }), `${se.name}: `,
        h("strong", { "data-series": se.name }, format(this.last(i), this.unit)))));
  }
}

/** A horizontal bar list (failures by reason): [label, value] rows, widths by the largest. */
export function bars(rows) {
  const max = Math.max(1, ...rows.map(([, v]) => v));
  return h("ul", { class: "bars" }, rows.map(([label, value]) =>
    h("li", {},
      h("span", { class: "bar-label" }, label),
      // Optimum at 0: any count shows in the "bad" colour.
      h("meter", { min: 0, max, low: 0, high: 0, optimum: 0, value, "aria-label": label }),
      h("span", { class: "bar-value" }, String(value)))));
}
