// Bars (action distributions, blend weights, beliefs) and a line chart (training curves).
// Bars are plain list items whose width is the value: readable as text, and each carries
// its exact value in data-value for tests and assistive tools.

import {h, num, pct} from "./dom.js";

/**
 * A labelled bar list. items: [{label, value, note?, highlight?}], values in [0, 1].
 * `name` labels the list ("agent 0: action probabilities").
 */
export function bars(name, items, {kind = "prob"} = {}) {
  return h("ul", {class: `bars ${kind}`, "aria-label": name},
    items.map((item) => {
      const fill = h("span", {class: "bar-fill"});
      fill.style.width = `${Math.max(0, Math.min(1, item.value)) * 100}%`;
      return h("li", {class: item.highlight ? "bar chosen" : "bar", dataset: {value: item.value}},
        h("span", {class: "bar-label"}, item.label),
        h("span", {class: "bar-track", "aria-hidden": "true"}, fill),
        h("span", {class: "bar-value"}, pct(item.value), item.note ? ` ${item.note}` : ""));
    }));
}

/** A line chart of y against x; `series` = [{name, values, colour}] sharing `xs`. */
export function lineChart(title, xs, series, {xLabel = "", yLabel = ""} = {}) {
  const width = 520, height = 220, left = 56, right = 12, top = 12, bottom = 38;
  const all = series.flatMap((s) => s.values).filter(Number.isFinite);
  if (!xs.length || !all.length) return h("p", {class: "muted"}, "no points");
  let [lo, hi] = [Math.min(...all), Math.max(...all)];
  if (lo === hi) [lo, hi] = [lo - 1, hi + 1];
  const [x0, x1] = [Math.min(...xs), Math.max(...xs)];
  const sx = (x) => left + (x1 === x0 ? 0.5 : (x - x0) / (x1 - x0)) * (width - left - right);
  const sy = (y) => top + (1 - (y - lo) / (hi - lo)) * (height - top - bottom);
  const ticks = [lo, (lo + hi) / 2, hi];
  const svg = h("svg", {viewBox: `0 0 ${width} ${height}`, class: "chart", role: "img",
    "aria-label": title},
  h("title", {}, title),
  h("line", {x1: left, y1: top, x2: left, y2: height - bottom, class: "axis"}),
  h("line", {x1: left, y1: height - bottom, x2: width - right, y2: height - bottom, class: "axis"}),
  ticks.map((t) => [
    h("line", {x1: left - 4, y1: sy(t), x2: width - right, y2: sy(t), class: "grid"}),
    h("text", {x: left - 6, y: sy(t) + 4, class: "tick", "text-anchor": "end"}, num(t, 2)),
  ]),
  [x0, x1].map((x) => h("text", {x: sx(x), y: height - bottom + 16, class: "tick",
    "text-anchor": "middle"}, String(x))),
  h("text", {x: (left + width - right) / 2, y: height - 4, class: "axis-label",
    "text-anchor": "middle"}, xLabel),
  h("text", {x: 12, y: top + (height - top - bottom) / 2, class: "axis-label",
    transform: `rotate(-90 12 ${top + (height - top - bottom) / 2})`, "text-anchor": "middle"},
  yLabel),
  series.map((s) => h("polyline", {class: "series", stroke: s.colour,
    points: xs.map((x, i) => `${sx(x).toFixed(1)},${sy(s.values[i]).toFixed(1)}`).join(" ")},
  h("title", {}, s.name))));
  return svg;
}

/** The points of a chart as a table, for screen readers and for reading exact values. */
export function dataTable(caption, columns, rows) {
  return h("details", {class: "data-table"}, h("summary", {}, `${caption}: the numbers`),
    h("table", {}, h("caption", {}, caption),
      h("thead", {}, h("tr", {}, columns.map((c) => h("th", {scope: "col"}, c)))),
      h("tbody", {}, rows.map((row) => h("tr", {}, row.map((cell) => h("td", {}, cell)))))));
}
