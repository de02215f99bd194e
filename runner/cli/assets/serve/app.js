// The lab page of `runner serve`: plain JavaScript over the server's JSON API, plots by the
// bundled uPlot. `window.lab` keeps the state the browser tests and the benchmark read.
"use strict";

const lab = {
  model: null,        // the model's details (GET /api/models/ID)
  result: null,       // the last run (POST .../simulate)
  plots: [],          // the uPlot of each plotted output
  changed: {},        // name -> value text sent as `set` (display units)
  latency: [],        // ms from a changed value to the next frame showing the new plots
  drawn: [],          // ms from a changed value to the plots drawn on their canvases
  runs: 0,            // runs drawn
  scene: null,        // the last animation geometry (POST .../scene)
  frame: 0,           // the animation's current sample index
  playing: false,
  sweep: null,        // the last sweep's report
  error: null,
};
window.lab = lab;

const $ = (id) => document.getElementById(id);

async function api(path, body) {
  const init = body === undefined ? {} : { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body) };
  const response = await fetch(path, init);
  const type = response.headers.get("Content-Type") || "";
  if (!response.ok) {
    const detail = type.startsWith("application/json") ? (await response.json()).error : await response.text();
    throw new Error(detail || response.statusText);
  }
  return type.startsWith("application/json") ? response.json() : response.blob();
}

function status(text, isError) {
  $("status").textContent = text;
  $("status").classList.toggle("error", !!isError);
  lab.error = isError ? text : null;
}

// ---- units ---------------------------------------------------------------------------------

function variable(name) {
  return lab.model.variables.find((v) => v.name === name);
}

// The unit a variable is shown in, and SI -> shown (display = factor * SI + offset, FMI's rule).
function shownUnit(v) {
  return v && v.display ? v.display.unit : (v && v.unit) || "";
}
function toShown(v, si) {
  return v && v.display ? v.display.factor * si + v.display.offset : si;
}
function axisLabel(name) {
  const unit = shownUnit(variable(name));
  return unit && unit !== "1" ? `${name} (${unit})` : name;
}

// ---- the model list ------------------------------------------------------------------------

async function loadModels() {
  const models = await api("/api/models");
  const list = $("model-list");
  for (const m of models) {
    const li = document.createElement("li");
    const a = document.createElement("a");
    a.href = "#" + m.id;
    a.id = "model-" + m.id;
    a.textContent = m.id;
    const span = document.createElement("span");
    span.textContent = m.description || "";
    a.appendChild(span);
    li.appendChild(a);
    list.appendChild(li);
  }
  window.addEventListener("hashchange", route);
  route();
}

function route() {
  const id = decodeURIComponent(location.hash.slice(1));
  if (id) openModel(id).catch((e) => status(e.message, true));
}

// ---- one model -----------------------------------------------------------------------------

async function openModel(id) {
  pause();
  lab.model = await api("/api/models/" + encodeURIComponent(id));
  lab.changed = {};
  lab.result = null;
  lab.scene = null;
  lab.sweep = null;
  lab.runs = 0;
  lab.latency = [];
  lab.drawn = [];
  document.querySelectorAll("nav a").forEach((a) => a.classList.toggle("current", a.id === "model-" + id));
  $("intro").hidden = true;
  $("model").hidden = false;
  $("model-name").textContent = lab.model.name;
  $("model-description").textContent = lab.model.description || "";
  $("download-fmu").href = `/api/models/${encodeURIComponent(id)}/fmu`;
  $("download-fmu").setAttribute("download", id + ".fmu");
  buildParameters();
  buildSweepPanel();
  $("animation-panel").hidden = !lab.model.animation;
  lab.plots.forEach((p) => p.destroy());
  lab.plots = [];
  $("plots").textContent = "";
  $("sweep-plot").textContent = "";
  await simulate(null);
}

// The toolkit's solver controls: parameters of the FMU's integrator, not of the model.
const CONTROLS = ["solver", "fixed_step", "abs_tol", "max_step", "n_steps", "n_rhs"];

// Parameters and inputs a value can be given to: scalar numbers that may be set.
function settable() {
  return lab.model.variables.filter((v) => v.settable && (v.causality === "parameter" || v.causality === "input"));
}

// Slider limits in the shown unit: the declared range, else one around the start value.
function sliderRange(v) {
  const start = v.start ?? 0;
  let lo = v.min ?? (start >= 0 ? 0 : 2 * start);
  let hi = v.max ?? (start > 0 ? 2 * start : start < 0 ? 0 : 1);
  if (v.max == null && v.min != null && hi <= lo) hi = lo + Math.max(1, Math.abs(lo));
  lo = toShown(v, lo);
  hi = toShown(v, hi);
  return lo <= hi ? [lo, hi] : [hi, lo];
}

// A number as typed in a field: up to 12 significant digits, no trailing noise.
function fieldText(x) {
  return String(Number(x.toPrecision(12)));
}

function buildParameters() {
  const form = $("parameters");
  form.textContent = "";
  // The model's own parameters first, then the solver controls of the FMU's integrator.
  const ordered = settable().sort((a, b) => CONTROLS.includes(a.name) - CONTROLS.includes(b.name));
  let controlsHeading = false;
  for (const v of ordered) {
    if (CONTROLS.includes(v.name) && !controlsHeading) {
      const h = document.createElement("h4");
      h.textContent = "Solver controls";
      form.appendChild(h);
      controlsHeading = true;
    }
    const div = document.createElement("div");
    div.className = "param";
    div.dataset.name = v.name;
    const label = document.createElement("label");
    label.textContent = v.name;
    label.title = v.description || "";
    label.htmlFor = "field-" + v.name;
    const row = document.createElement("div");
    row.className = "row";
    const field = document.createElement("input");
    field.id = "field-" + v.name;
    field.name = v.name;
    const shown = v.start == null ? 0 : toShown(v, v.start);
    if (v.kind === "Boolean") {
      field.type = "checkbox";
      field.checked = !!v.start;
      field.addEventListener("change", () => change(v, String(field.checked), div));
      row.appendChild(field);
    } else {
      const [lo, hi] = sliderRange(v);
      field.type = "number";
      field.step = "any";
      field.value = fieldText(shown);
      if (v.min != null) field.min = fieldText(lo);
      if (v.max != null) field.max = fieldText(hi);
      const slider = document.createElement("input");
      slider.type = "range";
      slider.id = "slider-" + v.name;
      slider.min = lo;
      slider.max = hi;
      slider.step = v.kind === "Real" ? (hi - lo) / 500 || "any" : 1;
      slider.value = shown;
      slider.setAttribute("aria-label", v.name);
      const unit = document.createElement("span");
      unit.className = "unit";
      unit.textContent = shownUnit(v);
      field.addEventListener("input", () => {
        if (field.value === "" || !isFinite(Number(field.value))) return;
        slider.value = field.value;
        change(v, field.value, div);
      });
      slider.addEventListener("input", () => {
        field.value = fieldText(Number(slider.value));
        change(v, field.value, div);
      });
      row.append(field, slider, unit);
    }
    div.append(label, row);
    form.appendChild(div);
  }
  $("reset").onclick = () => {
    buildParameters();
    lab.changed = {};
    simulate(performance.now());
  };
}

// A value changed: the run goes to the server as `--set NAME=VALUE UNIT` would (the server
// converts the shown unit exactly as the command line does).
function change(v, text, div) {
  const unit = v.display ? " " + v.display.unit : "";
  lab.changed[v.name] = v.kind === "Real" ? text + unit : text;
  div.classList.add("changed");
  simulate(performance.now());
}

// ---- runs: one at a time; a change while one runs is run next (the latest value only) --------

let running = false;
let pending = null;
// True while a run is in flight or waiting to be sent.
Object.defineProperty(lab, "busy", { get: () => running || pending !== null });

async function simulate(changedAt) {
  if (running) {
    pending = pending ?? changedAt;
    return;
  }
  running = true;
  try {
    // Only the columns drawn: the plotted outputs and the phase plot's two.
    const wanted = new Set(lab.model.plotted);
    for (const id of ["phase-x", "phase-y"]) if ($(id).dataset.model === lab.model.id && $(id).value) wanted.add($(id).value);
    const body = { set: { ...lab.changed }, variables: [...wanted] };
    const result = await api(`/api/models/${encodeURIComponent(lab.model.id)}/simulate`, body);
    if (result.model !== lab.model.id) return;
    lab.result = result;
    draw(result, changedAt);
    status(result.ended_early ? `The run ended early: ${result.ended_early}` : `${result.time.length} samples; run ${result.run_ms.toFixed(1)} ms`);
    // The scene follows once the values settle (not for every step of a slider drag).
    if (lab.model.animation && pending === null) loadScene();
  } catch (e) {
    status(e.message, true);
  } finally {
    running = false;
    if (pending !== null) {
      const next = pending;
      pending = null;
      simulate(next);
    }
  }
}

function column(result, name) {
  const k = result.names.indexOf(name);
  return k < 0 ? null : result.columns[k];
}

// Vertical lines at the events, labelled with what changed.
function eventPlugin() {
  return {
    hooks: {
      draw: [
        (u) => {
          const events = (lab.result && lab.result.events) || [];
          const ctx = u.ctx;
          ctx.save();
          ctx.strokeStyle = "#b5410f";
          ctx.fillStyle = "#b5410f";
          ctx.setLineDash([5, 4]);
          ctx.font = `${11 * devicePixelRatio}px sans-serif`;
          // uPlot leaves the alignment of its last axis label on the context.
          ctx.textBaseline = "alphabetic";
          const right = u.bbox.left + u.bbox.width;
          for (const e of events) {
            const x = u.valToPos(e.time, "x", true);
            if (x < u.bbox.left || x > u.bbox.left + u.bbox.width) continue;
            ctx.beginPath();
            ctx.moveTo(x, u.bbox.top);
            ctx.lineTo(x, u.bbox.top + u.bbox.height);
            ctx.stroke();
            // Right of its line, or left of it where the text would leave the plot.
            const fits = x + 3 + ctx.measureText(e.text).width <= right;
            ctx.textAlign = fits ? "left" : "right";
            ctx.fillText(e.text, fits ? x + 3 : x - 3, u.bbox.top + 12 * devicePixelRatio);
          }
          ctx.restore();
        },
      ],
    },
  };
}

const sync = typeof uPlot !== "undefined" ? uPlot.sync("time") : null;

// Tick labels with as many decimals as the tick spacing needs: uPlot's own keep three, and a
// sweep metric that changes in its fifth digit showed one label repeated down the axis.
function tickLabels(u, splits, axis, space, increment) {
  // The decimals of the spacing itself: 0.25 needs two, 1e-7 seven.
  const [mantissa, exponent] = Number(increment.toPrecision(12)).toExponential().split("e");
  const decimals = Math.min(15, Math.max(0, (mantissa.split(".")[1] || "").length - Number(exponent)));
  return splits.map((v) => (v === null || v === undefined ? "" : String(Number(v.toFixed(decimals)))));
}

// Room for the longest tick label and the axis label beside it.
function labelRoom(u, values) {
  return 30 + 7 * Math.max(5, ...(values || []).map((v) => String(v).length));
}

function plotWidth() {
  return Math.max(320, $("results").clientWidth - 10);
}

function draw(result, changedAt) {
  const names = lab.model.plotted.filter((n) => result.names.includes(n));
  const time = result.time;
  // In the display unit where there is one; an SI column is plotted as it came (no copy).
  const data = names.map((n) => {
    const v = variable(n);
    return v && v.display ? column(result, n).map((si) => toShown(v, si)) : column(result, n);
  });
  if (lab.plots.length !== names.length) {
    lab.plots.forEach((p) => p.destroy());
    $("plots").textContent = "";
    lab.plots = names.map((n, k) => new uPlot({
      width: plotWidth(),
      height: 140,
      cursor: { sync: { key: sync.key } },
      legend: { show: false },
      scales: { x: { time: false } },
      axes: [{ label: k === names.length - 1 ? "time (s)" : "", values: tickLabels }, { label: axisLabel(n), size: 70, values: tickLabels }],
      series: [{ label: "t" }, { label: n, stroke: "#343e58", width: 1.5 }],
      plugins: [eventPlugin()],
    }, [time, data[k]], $("plots")));
  } else {
    lab.plots.forEach((p, k) => p.setData([time, data[k]]));
  }
  drawPhase();
  lab.runs += 1;
  if (changedAt !== null && changedAt !== undefined) {
    // uPlot draws in a microtask queued by setData (before this one): the canvases hold the new
    // run here; the browser shows them from its next frame on, measured there.
    Promise.resolve().then(() => lab.drawn.push(performance.now() - changedAt));
    requestAnimationFrame(() => lab.latency.push(performance.now() - changedAt));
  }
}

// ---- phase plot ----------------------------------------------------------------------------

function fillPhaseSelects() {
  const names = lab.result.recorded;
  for (const [id, fallback] of [["phase-x", 0], ["phase-y", 1]]) {
    const select = $(id);
    const keep = select.value;
    if (select.dataset.model === lab.model.id && select.options.length === names.length) continue;
    select.textContent = "";
    for (const n of names) select.add(new Option(axisLabel(n), n));
    select.dataset.model = lab.model.id;
    const plotted = lab.model.plotted.filter((n) => names.includes(n));
    select.value = names.includes(keep) ? keep : plotted[fallback] ?? names[Math.min(fallback, names.length - 1)];
    // A column not fetched yet comes with the next run.
    select.onchange = () => (column(lab.result, select.value) ? drawPhase() : simulate(null));
  }
}

// Nice tick values covering [lo, hi].
function ticks(lo, hi, count) {
  const span = hi - lo || Math.abs(lo) || 1;
  const raw = span / count;
  const mag = Math.pow(10, Math.floor(Math.log10(raw)));
  const step = [1, 2, 5, 10].map((m) => m * mag).find((s) => s >= raw);
  const out = [];
  for (let t = Math.ceil(lo / step) * step; t <= hi + step * 1e-9; t += step) out.push(Math.abs(t) < step * 1e-9 ? 0 : t);
  return out;
}

function drawPhase() {
  if (!lab.result) return;
  fillPhaseSelects();
  const xn = $("phase-x").value, yn = $("phase-y").value;
  if (!column(lab.result, xn) || !column(lab.result, yn)) return;
  const xs = column(lab.result, xn).map((s) => toShown(variable(xn), s));
  const ys = column(lab.result, yn).map((s) => toShown(variable(yn), s));
  const canvas = $("phase");
  const ctx = canvas.getContext("2d");
  const W = canvas.width, H = canvas.height, L = 70, B = 40, T = 10, R = 15;
  ctx.clearRect(0, 0, W, H);
  let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
  for (let i = 0; i < xs.length; i++) {
    if (xs[i] !== null && isFinite(xs[i])) { x0 = Math.min(x0, xs[i]); x1 = Math.max(x1, xs[i]); }
    if (ys[i] !== null && isFinite(ys[i])) { y0 = Math.min(y0, ys[i]); y1 = Math.max(y1, ys[i]); }
  }
  if (!isFinite(x0)) { x0 = 0; x1 = 0; }
  if (!isFinite(y0)) { y0 = 0; y1 = 0; }
  if (!(x1 > x0)) { x0 -= 1; x1 += 1; }
  if (!(y1 > y0)) { y0 -= 1; y1 += 1; }
  const px = (x) => L + (x - x0) / (x1 - x0) * (W - L - R);
  const py = (y) => H - B - (y - y0) / (y1 - y0) * (H - B - T);
  ctx.font = "11px sans-serif";
  ctx.strokeStyle = "#ccd3e0";
  ctx.fillStyle = "#333";
  // Tick labels centred under their line, and right-aligned left of the plot, clear of the
  // vertical axis label.
  ctx.textAlign = "center";
  for (const t of ticks(x0, x1, 6)) {
    ctx.beginPath(); ctx.moveTo(px(t), T); ctx.lineTo(px(t), H - B); ctx.stroke();
    ctx.fillText(Number(t.toPrecision(6)), px(t), H - B + 14);
  }
  ctx.textAlign = "right";
  for (const t of ticks(y0, y1, 5)) {
    ctx.beginPath(); ctx.moveTo(L, py(t)); ctx.lineTo(W - R, py(t)); ctx.stroke();
    ctx.fillText(Number(t.toPrecision(6)), L - 6, py(t) + 4);
  }
  ctx.textAlign = "center";
  ctx.fillText(axisLabel(xn), L + (W - L - R) / 2, H - 6);
  ctx.save(); ctx.translate(12, T + (H - B - T) / 2); ctx.rotate(-Math.PI / 2); ctx.fillText(axisLabel(yn), 0, 0); ctx.restore();
  ctx.textAlign = "left";
  ctx.strokeStyle = "#343e58";
  ctx.lineWidth = 1.5;
  ctx.beginPath();
  let pen = false;
  for (let i = 0; i < xs.length; i++) {
    if (xs[i] === null || ys[i] === null || !isFinite(xs[i]) || !isFinite(ys[i])) { pen = false; continue; }
    if (pen) ctx.lineTo(px(xs[i]), py(ys[i])); else ctx.moveTo(px(xs[i]), py(ys[i]));
    pen = true;
  }
  ctx.stroke();
  ctx.fillStyle = "#b5410f";
  for (const e of lab.result.events) {
    const i = e.index;
    if (xs[i] !== null && ys[i] !== null) { ctx.beginPath(); ctx.arc(px(xs[i]), py(ys[i]), 4, 0, 2 * Math.PI); ctx.fill(); }
  }
  lab.phase = { x: xn, y: yn, points: xs.length };
}

// ---- animation -----------------------------------------------------------------------------

let sceneRequest = 0;

async function loadScene() {
  const mine = ++sceneRequest;
  try {
    const scene = await api(`/api/models/${encodeURIComponent(lab.model.id)}/scene`, { set: { ...lab.changed } });
    if (mine !== sceneRequest) return;
    lab.scene = scene;
    const frame = $("frame");
    frame.max = scene.frames.length - 1;
    const at = Math.min(Number(frame.value), scene.frames.length - 1);
    frame.value = at;
    frame.oninput = () => { pause(); showFrame(Number(frame.value)); };
    $("play").onclick = () => (lab.playing ? pause() : play());
    showFrame(at);
  } catch (e) {
    status(e.message, true);
  }
}

let timer = null;

function play() {
  if (!lab.scene) return;
  lab.playing = true;
  $("play").textContent = "Pause";
  const frame = $("frame");
  if (Number(frame.value) >= lab.scene.frames.length - 1) frame.value = 0;
  const started = performance.now(), from = Number(frame.value), fps = lab.scene.fps;
  const step = () => {
    if (!lab.playing) return;
    const k = from + Math.floor((performance.now() - started) / 1000 * fps);
    if (k >= lab.scene.frames.length - 1) {
      showFrame(lab.scene.frames.length - 1);
      pause();
      return;
    }
    if (k !== Number(frame.value)) showFrame(k);
    timer = requestAnimationFrame(step);
  };
  timer = requestAnimationFrame(step);
}

function pause() {
  lab.playing = false;
  if (timer !== null) cancelAnimationFrame(timer);
  timer = null;
  $("play").textContent = "Play";
}

const COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf"];

// Frame k of the scene, drawn to scale (equal metres per pixel on both axes).
function showFrame(k) {
  const s = lab.scene;
  $("frame").value = k;
  const i = s.frames[k];
  lab.frame = i;
  const canvas = $("animation");
  const ctx = canvas.getContext("2d");
  const W = canvas.width, H = canvas.height;
  ctx.clearRect(0, 0, W, H);
  const [x0, x1, y0, y1] = s.views[i];
  const scale = Math.min(W / (x1 - x0), H / (y1 - y0));
  const ox = (W - scale * (x1 - x0)) / 2, oy = (H - scale * (y1 - y0)) / 2;
  const px = (x) => ox + (x - x0) * scale;
  const py = (y) => H - oy - (y - y0) * scale;
  const at = (p, j) => [s.points[p].x[j], s.points[p].y[j]];
  ctx.strokeStyle = "#8a8f99";
  ctx.lineWidth = 1;
  for (const level of s.levels) {
    if (!isFinite(level)) continue;
    ctx.beginPath(); ctx.moveTo(0, py(level)); ctx.lineTo(W, py(level)); ctx.stroke();
  }
  s.trails.forEach((t, n) => {
    ctx.strokeStyle = COLORS[n % COLORS.length];
    ctx.lineWidth = 2;
    ctx.beginPath();
    let pen = false;
    for (let j = 0; j <= i; j++) {
      const [x, y] = at(t.point, j);
      if (!t.shown[j] || x === null || y === null) { pen = false; continue; }
      if (pen) ctx.lineTo(px(x), py(y)); else ctx.moveTo(px(x), py(y));
      pen = true;
    }
    ctx.stroke();
  });
  ctx.strokeStyle = "#343e58";
  ctx.lineWidth = 5;
  ctx.lineJoin = "round";
  const joints = new Set();
  for (const link of s.links) {
    if (!link.shown[i]) continue;
    ctx.beginPath();
    link.points.forEach((p, n) => {
      const [x, y] = at(p, i);
      if (n === 0) ctx.moveTo(px(x), py(y)); else ctx.lineTo(px(x), py(y));
      joints.add(p);
    });
    ctx.stroke();
  }
  s.trails.forEach((t) => { if (t.shown[i]) joints.add(t.point); });
  ctx.lineWidth = 2;
  ctx.font = "12px sans-serif";
  for (const p of joints) {
    const [x, y] = at(p, i);
    if (x === null || y === null) continue;
    ctx.fillStyle = s.points[p].fixed ? "#343e58" : "#fff";
    ctx.beginPath(); ctx.arc(px(x), py(y), 5, 0, 2 * Math.PI); ctx.fill(); ctx.stroke();
    ctx.fillStyle = "#1d2333";
    ctx.fillText(s.points[p].name, px(x) + 9, py(y) - 9);
  }
  $("stamp").textContent = s.stamps[i];
}

// ---- sweep ---------------------------------------------------------------------------------

function buildSweepPanel() {
  const select = $("sweep-param");
  select.textContent = "";
  const params = settable().filter((v) => v.kind === "Real" || v.kind === "Integer");
  for (const v of params) select.add(new Option(v.name, v.name));
  // The experiment's sweep when it has one: NAME=START:STOP:STEP, or NAME=V1,V2,... (the panel
  // then spans the values in 20 steps).
  let given = (lab.model.sweep.param[0] || "").match(/^\s*([^=]+)=\s*([^:]+):([^:]+):(.+)$/);
  const listed = given ? null : (lab.model.sweep.param[0] || "").match(/^\s*([^=]+)=(.+)$/);
  if (listed) {
    const values = listed[2].split(",").map(Number);
    if (values.length > 1 && values.every(isFinite)) {
      const [lo, hi] = [Math.min(...values), Math.max(...values)];
      given = [null, listed[1], fieldText(lo), fieldText(hi), fieldText((hi - lo) / 20)];
    }
  }
  const setRange = (name) => {
    const v = variable(name);
    if (!v) return;
    // Half to twice the start value, within the declared range. Not the whole declared range:
    // a minimum of 0 is often a value the model refuses (a length, a mass).
    const start = v.start ?? 1;
    const lo = start > 0 ? start / 2 : start < 0 ? 2 * start : 0;
    const hi = start > 0 ? 2 * start : start < 0 ? start / 2 : 1;
    const within = (x) => Math.min(v.max ?? Infinity, Math.max(v.min ?? -Infinity, x));
    $("sweep-from").value = fieldText(within(lo));
    $("sweep-to").value = fieldText(within(hi));
    $("sweep-step").value = fieldText((Number($("sweep-to").value) - Number($("sweep-from").value)) / 20);
    $("sweep-unit").textContent = v.unit ? `(${v.unit}, SI as in runner sweep)` : "";
  };
  if (given && params.some((v) => v.name === given[1].trim())) {
    select.value = given[1].trim();
    setRange(select.value);
    $("sweep-from").value = given[2].trim();
    $("sweep-to").value = given[3].trim();
    $("sweep-step").value = given[4].trim();
  } else if (params.length) {
    setRange(params[0].name);
  }
  select.onchange = () => setRange(select.value);
  const firstOutput = lab.model.plotted[0] || "";
  $("sweep-metric").value = lab.model.sweep.metric[0] || (firstOutput ? `peak=max(${firstOutput})` : "");
  $("sweep-progress").value = 0;
  $("sweep-status").textContent = "";
  $("sweep-csv").hidden = true;
  $("sweep-run").onclick = runSweep;
  $("sweep-cancel").onclick = cancelSweep;
  $("sweep-run").disabled = params.length === 0;
}

let sweepJob = null;

async function runSweep() {
  const param = `${$("sweep-param").value}=${$("sweep-from").value}:${$("sweep-to").value}:${$("sweep-step").value}`;
  const body = { param: [param], metric: [$("sweep-metric").value], set: { ...lab.changed } };
  const sweepStatus = $("sweep-status");
  sweepStatus.classList.remove("error");
  try {
    const started = await api(`/api/models/${encodeURIComponent(lab.model.id)}/sweep`, body);
    sweepJob = started.job;
    lab.sweep = { job: started.job, total: started.total, rows: [], finished: false };
    $("sweep-run").disabled = true;
    $("sweep-cancel").disabled = false;
    $("sweep-progress").max = started.total;
    $("sweep-progress").value = 0;
    $("sweep-csv").hidden = true;
    pollSweep(started.job);
  } catch (e) {
    sweepStatus.textContent = e.message;
    sweepStatus.classList.add("error");
  }
}

async function pollSweep(job) {
  if (job !== sweepJob) return;
  try {
    const report = await api(`/api/sweeps/${job}?from=${lab.sweep.rows.length}`);
    lab.sweep.rows.push(...report.rows);
    lab.sweep.params = report.params;
    lab.sweep.metrics = report.metrics;
    $("sweep-progress").value = lab.sweep.rows.length;
    $("sweep-status").textContent = `${lab.sweep.rows.length} of ${report.total} points`;
    if (report.finished) {
      lab.sweep.finished = true;
      lab.sweep.error = report.error;
      lab.sweep.seconds = report.seconds;
      $("sweep-run").disabled = false;
      $("sweep-cancel").disabled = true;
      const failed = lab.sweep.rows.filter((r) => r.status !== "ok").length;
      $("sweep-status").textContent = report.error
        ? `stopped: ${report.error}`
        : `${report.total} points in ${report.seconds.toFixed(2)} s${failed ? `; ${failed} failed (see the CSV's status)` : ""}`;
      $("sweep-status").classList.toggle("error", !!report.error);
      $("sweep-csv").href = `/api/sweeps/${job}/csv`;
      $("sweep-csv").hidden = false;
      drawSweep();
      return;
    }
    setTimeout(() => pollSweep(job), 150);
  } catch (e) {
    $("sweep-status").textContent = e.message;
    $("sweep-status").classList.add("error");
    $("sweep-run").disabled = false;
  }
}

async function cancelSweep() {
  if (sweepJob !== null) await fetch(`/api/sweeps/${sweepJob}`, { method: "DELETE" });
}

// The metric against the parameter, its peak marked.
function drawSweep() {
  const rows = lab.sweep.rows.slice().sort((a, b) => a.point[0] - b.point[0]);
  const xs = rows.map((r) => r.point[0]);
  const ys = rows.map((r) => (r.metrics && isFinite(r.metrics[0]) ? r.metrics[0] : null));
  let peak = -1;
  ys.forEach((y, k) => { if (y !== null && (peak < 0 || y > ys[peak])) peak = k; });
  lab.sweep.peak = peak < 0 ? null : { x: xs[peak], y: ys[peak] };
  $("sweep-plot").textContent = "";
  const name = lab.sweep.params[0], metric = lab.sweep.metrics[0];
  const v = variable(name);
  const marker = {
    hooks: {
      draw: [(u) => {
        if (!lab.sweep.peak) return;
        const ctx = u.ctx, x = u.valToPos(lab.sweep.peak.x, "x", true), y = u.valToPos(lab.sweep.peak.y, "y", true);
        ctx.save();
        ctx.fillStyle = "#b5410f";
        ctx.beginPath(); ctx.arc(x, y, 5 * devicePixelRatio, 0, 2 * Math.PI); ctx.fill();
        ctx.font = `${12 * devicePixelRatio}px sans-serif`;
        const text = `peak ${Number(lab.sweep.peak.y.toPrecision(5))} at ${name} = ${Number(lab.sweep.peak.x.toPrecision(6))}`;
        // uPlot leaves the alignment of its last axis label on the context.
        ctx.textAlign = "left";
        ctx.textBaseline = "alphabetic";
        const width = ctx.measureText(text).width;
        const left = Math.max(u.bbox.left, Math.min(x + 8, u.bbox.left + u.bbox.width - width));
        // Below the point when the point is at the top of the plot.
        const top = y - 8 - 12 * devicePixelRatio < u.bbox.top ? y + 20 * devicePixelRatio : y - 8;
        ctx.fillText(text, left, top);
        ctx.restore();
      }],
    },
  };
  lab.sweepPlot = new uPlot({
    width: plotWidth(),
    height: 260,
    scales: { x: { time: false } },
    axes: [{ label: v && v.unit ? `${name} (${v.unit})` : name, values: tickLabels }, { label: metric, size: labelRoom, values: tickLabels }],
    series: [{ label: name }, { label: metric, stroke: "#343e58", width: 2, points: { show: true } }],
    plugins: [marker],
  }, [xs, ys], $("sweep-plot"));
}

// ---- downloads -----------------------------------------------------------------------------

async function downloadCsv() {
  try {
    const blob = await api(`/api/models/${encodeURIComponent(lab.model.id)}/simulate`, { set: { ...lab.changed }, format: "csv" });
    const a = document.createElement("a");
    a.href = URL.createObjectURL(blob);
    a.download = lab.model.id + ".csv";
    document.body.appendChild(a);
    a.click();
    a.remove();
    setTimeout(() => URL.revokeObjectURL(a.href), 10000);
  } catch (e) {
    status(e.message, true);
  }
}

window.addEventListener("DOMContentLoaded", () => {
  $("download-csv").onclick = downloadCsv;
  loadModels().catch((e) => status(e.message, true));
});
