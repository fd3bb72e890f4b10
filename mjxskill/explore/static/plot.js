// The two charts of the explore page, drawn with D3 as SVG: one element per point, so a point
// can be clicked, titled and counted. Objectives are rewards, larger is better.
"use strict";

const MARGIN = { top: 16, right: 96, bottom: 44, left: 64 };
const RUN_COLOURS = d3.schemeTableau10;

function runColour(run) { return RUN_COLOURS[run % RUN_COLOURS.length]; }

function frame(svgEl) {
  const svg = d3.select(svgEl);
  svg.selectAll("*").remove();
  const width = +svg.attr("width") - MARGIN.left - MARGIN.right;
  const height = +svg.attr("height") - MARGIN.top - MARGIN.bottom;
  const g = svg.append("g").attr("transform", `translate(${MARGIN.left},${MARGIN.top})`);
  return { svg, g, width, height };
}

function axes(f, x, y, xLabel, yLabel) {
  f.g.append("g").attr("transform", `translate(0,${f.height})`).call(d3.axisBottom(x).ticks(7));
  f.g.append("g").call(d3.axisLeft(y).ticks(6));
  f.g.append("text").attr("class", "axis-label").attr("x", f.width / 2).attr("y", f.height + 36)
    .attr("text-anchor", "middle").text(xLabel);
  f.g.append("text").attr("class", "axis-label").attr("transform", "rotate(-90)")
    .attr("x", -f.height / 2).attr("y", -48).attr("text-anchor", "middle").text(yLabel);
}

function padded(extent) {
  const [lo, hi] = extent;
  const pad = hi > lo ? 0.05 * (hi - lo) : 1;
  return [lo - pad, hi + pad];
}

// opts: evaluations, front (rows with run, index, k, objectives, success_rate, peak_contact_force, ...),
// xi, yi (objective indices), objectiveNames, runs (labels), colourBy ("success" | "run"),
// selected ({run, index} or null), meets (row -> true | false | null: no filter), onSelect.
function drawPareto(svgEl, opts) {
  const f = frame(svgEl);
  const xy = (r) => [r.objectives[opts.xi], r.objectives[opts.yi]];
  const finite = (r) => xy(r).every((v) => v !== null);
  const all = opts.evaluations.filter(finite);
  const x = d3.scaleLinear().domain(padded(d3.extent(all.concat(opts.front.filter(finite)), (r) => xy(r)[0]))).range([0, f.width]);
  const y = d3.scaleLinear().domain(padded(d3.extent(all.concat(opts.front.filter(finite)), (r) => xy(r)[1]))).range([f.height, 0]);
  const label = (i) => `objective ${opts.objectiveNames[i]} (reward, larger is better)`;
  axes(f, x, y, label(opts.xi), label(opts.yi));
  const viridis = (s) => (s === null ? "#999" : d3.interpolateViridis(s));
  const fill = (r) => (opts.colourBy === "run" ? runColour(r.run) : viridis(r.success_rate));
  const pct = (s) => (s === null ? "n/a" : `${Math.round(100 * s)} %`);
  const title = (r) => `${opts.runs[r.run]} · ${r.k === null || r.k === undefined ? "evaluation " + r.index : "Pareto k=" + r.k}`
    + ` · success ${pct(r.success_rate)} · peak contact force ${r.peak_contact_force === null ? "n/a" : r.peak_contact_force.toFixed(1) + " N"}`;
  const pick = (event, r) => opts.onSelect(r.run, r.index);

  f.g.append("g").selectAll("circle").data(all).join("circle")
    .attr("class", "evaluation").attr("r", 3.5).attr("cx", (r) => x(xy(r)[0])).attr("cy", (r) => y(xy(r)[1]))
    .attr("fill", fill).on("click", pick).append("title").text(title);

  const byRun = d3.group(opts.front.filter(finite), (r) => r.run);
  for (const [run, rows] of byRun) {
    const sorted = rows.slice().sort((a, b) => xy(a)[0] - xy(b)[0]);
    f.g.append("path").attr("class", "front-line").attr("data-run", run)
      .attr("stroke", opts.runs.length > 1 ? runColour(run) : "#c0182a")
      .attr("d", d3.line().x((r) => x(xy(r)[0])).y((r) => y(xy(r)[1]))(sorted));
  }
  const state = (r) => { const m = opts.meets(r); return m === null ? "" : m ? " meets" : " fails"; };
  f.g.append("g").selectAll("circle").data(opts.front.filter(finite)).join("circle")
    .attr("class", (r) => "front" + state(r)).attr("r", 6)
    .attr("data-run", (r) => r.run).attr("data-k", (r) => r.k).attr("data-index", (r) => r.index)
    .attr("cx", (r) => x(xy(r)[0])).attr("cy", (r) => y(xy(r)[1])).attr("fill", fill)
    .on("click", pick).append("title").text(title);

  const chosen = opts.selected && opts.evaluations.find((r) => r.run === opts.selected.run && r.index === opts.selected.index);
  if (chosen && finite(chosen)) {
    f.g.append("circle").attr("class", "selected-ring").attr("r", 11)
      .attr("cx", x(xy(chosen)[0])).attr("cy", y(xy(chosen)[1]));
  }
  legend(f, opts);
}

function legend(f, opts) {
  const g = f.g.append("g").attr("transform", `translate(${f.width + 18},0)`);
  if (opts.colourBy === "run") {
    opts.runs.forEach((name, i) => {
      g.append("circle").attr("cx", 5).attr("cy", 8 + 16 * i).attr("r", 5).attr("fill", runColour(i));
      g.append("text").attr("x", 14).attr("y", 12 + 16 * i).text(name);
    });
    return;
  }
  const h = Math.min(200, f.height);
  const grad = f.svg.append("defs").append("linearGradient").attr("id", "viridis").attr("x1", 0).attr("x2", 0).attr("y1", 1).attr("y2", 0);
  d3.range(0, 1.01, 0.1).forEach((t) => grad.append("stop").attr("offset", t).attr("stop-color", d3.interpolateViridis(t)));
  g.append("rect").attr("width", 12).attr("height", h).attr("fill", "url(#viridis)");
  g.append("g").attr("transform", "translate(12,0)").call(d3.axisRight(d3.scaleLinear().domain([0, 1]).range([h, 0])).ticks(5, "%"));
  g.append("text").attr("class", "axis-label").attr("transform", "rotate(90)").attr("x", h / 2).attr("y", -50)
    .attr("text-anchor", "middle").text("success rate");
  g.append("circle").attr("cx", 6).attr("cy", h + 22).attr("r", 6).attr("class", "legend-front").attr("fill", "#fff");
  g.append("text").attr("x", 16).attr("y", h + 26).text("Pareto");
}

// opts: curves ([{run, evaluations, hypervolume}]), runs (labels), nInit.
function drawHypervolume(svgEl, opts) {
  const f = frame(svgEl);
  const points = opts.curves.flatMap((c) => c.evaluations.map((n, i) => [n, c.hypervolume[i]])).filter((p) => p[1] !== null);
  if (!points.length) {
    f.g.append("text").attr("x", f.width / 2).attr("y", f.height / 2).attr("text-anchor", "middle")
      .text("hypervolume: none until the random warm-up is complete");
    return;
  }
  const x = d3.scaleLinear().domain([0, d3.max(points, (p) => p[0])]).range([0, f.width]);
  const y = d3.scaleLinear().domain(padded(d3.extent(points, (p) => p[1]))).range([f.height, 0]);
  axes(f, x, y, "evaluations (parameter sets)", "hypervolume (reward²)");
  f.g.append("line").attr("x1", x(opts.nInit)).attr("x2", x(opts.nInit)).attr("y1", 0).attr("y2", f.height)
    .attr("stroke", "#999").attr("stroke-dasharray", "4 3");
  f.g.append("text").attr("x", x(opts.nInit) + 4).attr("y", 10).attr("class", "muted").text("end of warm-up");
  for (const c of opts.curves) {
    const pts = c.evaluations.map((n, i) => [n, c.hypervolume[i]]).filter((p) => p[1] !== null);
    f.g.append("path").attr("class", "hv-line").attr("fill", "none").attr("stroke", runColour(c.run)).attr("stroke-width", 1.8)
      .attr("d", d3.line().x((p) => x(p[0])).y((p) => y(p[1]))(pts));
  }
}
