// The explore page: loads the run from the JSON API, draws it (plot.js), filters, shows a
// selected point, rolls it out on demand with progress, plays its video and exports it.
"use strict";

const S = { run: null, front: [], evaluations: [], hv: null, selected: null, poll: null, player: null };
const $ = (id) => document.getElementById(id);

async function api(path, body) {
  const init = body === undefined ? {} : { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body) };
  const response = await fetch(path, init);
  const doc = await response.json();
  if (!response.ok) throw new Error(doc.error || `${response.status} ${response.statusText}`);
  return doc;
}

const fmt = (v, digits = 4) => (v === null || v === undefined ? "n/a" : Number(v).toPrecision(digits));
const pct = (v) => (v === null || v === undefined ? "n/a" : `${Math.round(100 * v)} %`);
const newtons = (v) => (v === null || v === undefined ? "n/a" : `${v.toFixed(1)} N`);
const shortName = (name) => name.split(".").pop();
const isMulti = () => S.run.runs.length > 1;
const rowOf = (run, index) => S.evaluations.find((r) => r.run === run && r.index === index);

function element(tag, attrs = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  for (const c of children) e.append(c);
  return e;
}

function table(el, head, rows) {
  el.replaceChildren(element("tr", {}, ...head.map((h) => element("th", {}, h))));
  for (const row of rows) el.append(row);
}

// -- filters ---------------------------------------------------------------------------------
function limits() {
  const read = (id) => ($(id).value === "" ? null : Number($(id).value));
  return { minSuccess: read("min-success"), maxForce: read("max-force") };
}

function filtering() {
  const { minSuccess, maxForce } = limits();
  return minSuccess !== null || maxForce !== null;
}

function meets(row) {
  const { minSuccess, maxForce } = limits();
  if (!filtering()) return null;
  // a validated row is held to its validation success, as select does
  const success = row.validated !== null ? row.validated : row.success_rate;
  return (minSuccess === null || (success !== null && success >= minSuccess))
    && (maxForce === null || (row.peak_contact_force !== null && row.peak_contact_force <= maxForce));
}

// -- drawing ---------------------------------------------------------------------------------
function redraw() {
  drawPareto($("pareto"), {
    evaluations: S.evaluations, front: S.front, xi: +$("axis-x").value, yi: +$("axis-y").value,
    objectiveNames: S.run.objectives, runs: S.run.runs.map((r) => r.label),
    colourBy: isMulti() ? $("colour-by").value : "success", selected: S.selected, meets, onSelect: select,
  });
  drawHypervolume($("hypervolume"), { curves: S.hv.curves, runs: S.run.runs.map((r) => r.label), nInit: S.run.n_init });
  frontTable();
  const n = S.front.filter((r) => meets(r)).length;
  $("filter-count").textContent = filtering() ? `${n} of ${S.front.length} Pareto solutions meet the filters`
    : `${S.front.length} Pareto solutions, no filter`;
}

function frontTable() {
  const validated = S.front.some((r) => r.validated !== null);
  const head = [...(isMulti() ? ["run"] : []), "k", ...S.run.parameters.map((p) => `${shortName(p.name)} [${p.unit}]`),
    ...S.run.objectives.map((o) => `obj ${o}`), "success", "max F", ...(validated ? ["validated"] : [])];
  table($("front-table"), head, S.front.map((r) => {
    const m = meets(r);
    const chosen = S.selected && S.selected.run === r.run && S.selected.index === r.index;
    const tr = element("tr", { class: `${m === null ? "" : m ? "meets" : "fails"}${chosen ? " selected" : ""}`, "data-run": r.run, "data-k": r.k },
      ...(isMulti() ? [element("td", {}, S.run.runs[r.run].label)] : []), element("td", {}, String(r.k)),
      ...r.params.map((v) => element("td", {}, fmt(v))), ...r.objectives.map((v) => element("td", {}, fmt(v, 5))),
      element("td", {}, pct(r.success_rate)), element("td", {}, newtons(r.peak_contact_force)),
      ...(validated ? [element("td", {}, r.validated === null ? "-" : pct(r.validated))] : []));
    tr.addEventListener("click", () => select(r.run, r.index));
    return tr;
  }));
}

// -- the selected point ----------------------------------------------------------------------
function select(run, index) {
  S.selected = { run, index };
  const row = rowOf(run, index);
  const where = isMulti() ? ` (${S.run.runs[run].label})` : "";
  $("detail").hidden = false;
  $("detail-title").textContent = row.k === null ? `Evaluation ${index}${where}: not on the Pareto front`
    : `Pareto solution k = ${row.k}${where}`;
  table($("params"), ["parameter", "value", "unit", "bounds"], S.run.parameters.map((p, i) =>
    element("tr", { "data-name": p.name }, element("td", {}, p.name), element("td", {}, fmt(row.params[i], 6)),
      element("td", {}, p.unit), element("td", {}, `[${p.lower}, ${p.upper}]`))));
  table($("objectives"), ["in training", "value"], [
    ...S.run.objectives.map((o, i) => element("tr", {}, element("td", {}, `objective ${o} (reward)`), element("td", {}, fmt(row.objectives[i], 6)))),
    element("tr", {}, element("td", {}, `success rate (${S.run.worlds} worlds)`), element("td", {}, pct(row.success_rate))),
    element("tr", {}, element("td", {}, "peak contact force (mean over worlds)"), element("td", {}, newtons(row.peak_contact_force))),
    element("tr", {}, element("td", {}, "peak commanded force (mean over worlds)"), element("td", {}, newtons(row.peak_commanded_force))),
    element("tr", {}, element("td", {}, "batch (iteration)"), element("td", {}, String(row.iteration))),
  ]);
  $("export").disabled = row.k === null;
  $("export").textContent = row.k === null ? "export (Pareto solutions only)" : `export to selected-${row.k}/`;
  $("export-result").textContent = "";
  $("worlds").replaceChildren();
  $("video").replaceChildren();
  $("job-message").textContent = "";
  redraw();
  refresh(false);
}

async function refresh(start) {
  if (!S.selected) return;
  const { run, index } = S.selected;
  const path = `/api/solution/${run}/${index}`;
  const config = +$("video-config").value;
  clearTimeout(S.poll);
  let doc;
  try {
    doc = start ? await api(path, { config }) : await api(`${path}?config=${config}`);
  } catch (err) {
    $("job-message").textContent = err.message;
    return;
  }
  if (!S.selected || S.selected.run !== run || S.selected.index !== index) return;  // another point was chosen meanwhile
  showSolution(doc);
  const job = doc.job;
  const busy = job && (job.state === "queued" || job.state === "running");
  $("progress").hidden = !busy;
  $("simulate").disabled = busy;
  if (busy) {
    $("progress-bar").value = job.fraction;
    $("progress-text").textContent = `${job.stage} (${Math.round(job.elapsed_s)} s)`;
    S.poll = setTimeout(() => refresh(false), 500);
  }
  $("job-message").textContent = job && job.message ? job.message : "";
}

function showSolution(doc) {
  if (doc.worlds) showWorlds(doc.worlds);
  if (doc.video) showVideo(doc.video);
  else $("video").replaceChildren();
}

function showWorlds(w) {
  const select = $("video-config");
  const known = w.configs.filter((c) => c.known);
  if (select.options.length !== known.length) {
    const value = select.value;
    select.replaceChildren(...known.map((c, i) => element("option", { value: i }, c.name)));
    select.value = value;
  }
  const mark = (s) => element("span", { class: s.success ? "ok" : "ko",
    title: `peak contact force ${newtons(s.peak_contact_force)}, final position error ${s.position_error === null ? "n/a" : (1000 * s.position_error).toFixed(0) + " mm"}` },
    s.success ? "✓" : "✗");
  const t = element("table", { id: "worlds-table" });
  table(t, ["start configuration", "success", "worlds", "peak contact force (mean)"], w.configs.map((c) =>
    element("tr", { "data-config": c.name }, element("td", {}, `${c.name}${c.known ? "" : " (unseen)"}`), element("td", {}, pct(c.success_rate)),
      element("td", {}, ...c.worlds.map(mark)), element("td", {}, newtons(c.worlds.reduce((a, s) => a + (s.peak_contact_force || 0), 0) / c.worlds.length)))));
  $("worlds").replaceChildren(element("div", { class: "muted" },
    `${pct(w.success_rate)} of ${w.configs.length * w.per_config} worlds (${w.per_config} per start configuration, seed ${w.seed}, as evaluate)`), t);
}

function showVideo(v) {
  clearInterval(S.player);
  const box = $("video");
  const caption = element("div", { class: "muted" }, v.world);
  if (v.kind === "mp4") {
    box.replaceChildren(element("video", { src: v.urls[0], controls: "", loop: "", autoplay: "", muted: "" }), caption);
    return;
  }
  const img = element("img", { id: "frame", src: v.urls[0], alt: "rendered episode" });
  const slider = element("input", { type: "range", min: 0, max: v.urls.length - 1, value: 0 });
  const button = element("button", { type: "button" }, "play");
  let t = 0;
  const show = (i) => { t = i; img.src = v.urls[t]; slider.value = t; };
  slider.addEventListener("input", () => show(+slider.value));
  button.addEventListener("click", () => {
    if (S.player) { clearInterval(S.player); S.player = null; button.textContent = "play"; return; }
    button.textContent = "pause";
    S.player = setInterval(() => show((t + 1) % v.urls.length), 1000 / v.fps);
  });
  v.urls.forEach((u) => { new Image().src = u; });  // preload, so playback does not stutter
  box.replaceChildren(img, element("div", { class: "actions" }, button, slider, element("span", { class: "muted" }, `${v.urls.length} frames at ${v.fps} Hz`)), caption);
}

// -- actions ---------------------------------------------------------------------------------
async function exportSelected() {
  const row = rowOf(S.selected.run, S.selected.index);
  try {
    const doc = await api("/api/export", { run: row.run, k: row.k });
    $("export-result").textContent = `wrote ${doc.written.join(", ")}`;
  } catch (err) {
    $("export-result").textContent = err.message;
  }
}

async function pickBest() {
  const { minSuccess, maxForce } = limits();
  const query = new URLSearchParams();
  if (minSuccess !== null) query.set("min_success", minSuccess);
  if (maxForce !== null) query.set("max_force", maxForce);
  $("pick-error").textContent = "";
  try {
    const doc = await api(`/api/choose?${query}`);
    select(doc.run, S.front.find((r) => r.run === doc.run && r.k === doc.k).index);
  } catch (err) {
    $("pick-error").textContent = err.message;
  }
}

async function load() {
  try {
    [S.run, S.front, S.evaluations, S.hv] = await Promise.all([api("/api/run"), api("/api/front").then((d) => d.rows),
      api("/api/evaluations").then((d) => d.rows), api("/api/hypervolume")]);
  } catch (err) {
    $("load-error").hidden = false;
    $("load-error").textContent = `cannot load the run: ${err.message}`;
    return;
  }
  $("task").textContent = `— ${S.run.task}`;
  $("goal").textContent = `goal ${S.run.goal}`;
  $("path").textContent = `${S.run.path}: ${S.run.runs.length > 1 ? S.run.runs.length + " repetitions, " : ""}${S.run.worlds} worlds per evaluation, ${S.run.episode_seconds} s episodes`;
  $("counts").textContent = `${S.evaluations.length} evaluations, ${S.front.length} Pareto solutions`;
  for (const id of ["axis-x", "axis-y"]) $(id).replaceChildren(...S.run.objectives.map((o, i) => element("option", { value: i }, o)));
  $("axis-y").value = Math.min(1, S.run.objectives.length - 1);
  $("colour-by-label").hidden = !isMulti();
  for (const id of ["axis-x", "axis-y", "colour-by"]) $(id).addEventListener("change", redraw);
  for (const id of ["min-success", "max-force"]) $(id).addEventListener("input", redraw);
  $("pick-best").addEventListener("click", pickBest);
  $("export").addEventListener("click", exportSelected);
  $("simulate").addEventListener("click", () => refresh(true));
  $("video-config").addEventListener("change", () => refresh(false));
  redraw();
  document.body.dataset.ready = "true";  // the page is drawn (tests wait for this)
}

load();
