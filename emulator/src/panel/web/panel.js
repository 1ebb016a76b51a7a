// drive-emu live panel: reads the server-sent events of /api/stream (docs/panel.md) and
// plots them with uPlot; writes go to /api/inject and /api/record. No build step, no npm.
"use strict";

// The token: read from ?token= once, kept for this tab only (sessionStorage, so a reload
// still works) and dropped from the address bar and the history at once.
const TOKEN = (() => {
  const params = new URLSearchParams(location.search);
  let t = params.get("token");
  if (t !== null) {
    params.delete("token");
    const q = params.toString();
    history.replaceState(null, "", location.pathname + (q ? "?" + q : "") + location.hash);
    try { sessionStorage.setItem("drive-emu-panel-token", t); } catch (e) { /* no storage */ }
  } else {
    try { t = sessionStorage.getItem("drive-emu-panel-token"); } catch (e) { t = null; }
  }
  return t;
})();
const withToken = (url) =>
  TOKEN ? url + (url.includes("?") ? "&" : "?") + "token=" + encodeURIComponent(TOKEN) : url;
const KEEP_S = 60; // seconds of samples kept per axis (the longest span)

const SW_BITS = ["ready to switch on", "switched on", "operation enabled", "fault",
  "voltage enabled", "quick stop", "switch on disabled", "warning", "manufacturer 8",
  "remote", "target reached", "internal limit", "mode specific 12", "mode specific 13",
  "manufacturer 14", "manufacturer 15"];
const CW_BITS = ["switch on", "enable voltage", "quick stop", "enable operation",
  "mode specific 4", "mode specific 5", "mode specific 6", "fault reset", "halt",
  "change on set-point", "reserved 10", "manufacturer 11", "manufacturer 12",
  "manufacturer 13", "manufacturer 14", "manufacturer 15"];

const $ = (id) => document.getElementById(id);
const el = (tag, attrs = {}, text) => {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  if (text !== undefined) e.textContent = text;
  return e;
};

const state = { hello: null, axes: [], simTime: 0, messages: 0, draws: 0,
                drawTimer: 0, drawEnd: -Infinity, drawCost: 0 };

function newBuffers() {
  return { t: [], demand: [], actual: [], ferr: [], rpm: [], load: [], current: [] };
}

// A y axis as wide as its longest tick label (uPlot's fixed width cut "148,000" to ".48,000").
function axisSize(u, values, axisIdx, cycleNum) {
  const axis = u.axes[axisIdx];
  if (cycleNum > 1) return axis._size;  // uPlot converges by itself after the first pass
  let size = axis.ticks.size + axis.gap;
  const longest = (values || []).reduce((a, v) => (String(v).length > a.length ? String(v) : a), "");
  if (longest !== "") {
    u.ctx.font = axis.font[0];
    size += u.ctx.measureText(longest).width / devicePixelRatio;
  }
  return Math.ceil(size) + 2;
}

function plot(container, title, series, scales, xlabel = "t [s]") {
  const opts = {
    title, width: 560, height: 170, legend: { live: false },
    scales: Object.assign({ x: { time: false } }, scales || {}),
    series: [{ label: xlabel }].concat(series),
    axes: [{ label: xlabel }].concat(
      (series.map((s) => s.scale || "y").filter((v, i, a) => a.indexOf(v) === i)).map(
        (sc, i) => ({ scale: sc, side: i === 0 ? 3 : 1, grid: { show: i === 0 }, size: axisSize }))),
    cursor: { drag: { x: false, y: false } },
  };
  const data = [[]].concat(series.map(() => []));
  const u = new uPlot(opts, data, container);
  // As wide as its column of the grid, whatever the window.
  new ResizeObserver((entries) => {
    const w = Math.floor(entries[0].contentRect.width);
    if (w > 0 && w !== u.width) u.setSize({ width: w, height: u.height });
  }).observe(container);
  return u;
}

function buildAxis(a) {
  const card = el("div", { class: "card axis", id: "axis-" + a.index });
  const head = el("h2", {}, `node ${a.node_id} · ${a.preset} · 1 uu = ${a.user_unit}`);
  card.appendChild(head);
  const st = el("div", { class: "states" });
  st.innerHTML =
    `<span>NMT <b id="nmt-${a.index}">-</b></span>` +
    `<span>CiA 402 <b id="state-${a.index}" class="state">-</b></span>` +
    `<span>mode <b id="mode-${a.index}">-</b></span>` +
    `<span>position <b id="pos-${a.index}">-</b> uu</span>` +
    `<span>following error <b id="ferr-${a.index}">-</b> uu</span>` +
    `<span>lost <b id="lost-${a.index}">0</b></span>`;
  card.appendChild(st);
  const bits = el("div", { class: "bits" });
  bits.appendChild(bitTable("statusword", "sw-" + a.index, SW_BITS));
  bits.appendChild(bitTable("controlword", "cw-" + a.index, CW_BITS));
  card.appendChild(bits);
  const plots = el("div", { class: "plots" });
  card.appendChild(plots);
  const mk = () => { const d = el("div"); plots.appendChild(d); return d; };
  const ax = {
    info: a,
    buf: newBuffers(),
    pos: plot(mk(), "position [uu]", [
      { label: "demand 0x6062", stroke: "#888", width: 1 },
      { label: "actual 0x6064", stroke: "#1565c0", width: 1.5 }]),
    ferr: plot(mk(), "following error [uu]", [{ label: "0x60F4", stroke: "#c62828" }]),
    speed: plot(mk(), "speed", [
      { label: "motor [rpm]", stroke: "#2e7d32", scale: "rpm" },
      { label: "load [uu/s]", stroke: "#6a1b9a", scale: "uus" }]),
    current: plot(mk(), "motor current [A]", [{ label: "current", stroke: "#ef6c00" }]),
    spectrum: plot(mk(), "spectrum of 0x606C [uu/s]", [
      { label: "amplitude", stroke: "#37474f", fill: "rgba(55,71,79,0.15)" }], null, "f [Hz]"),
    plotted: null,
  };
  const verdict = el("div", { class: "verdict", id: "verdict-" + a.index }, "detector: waiting for data");
  card.appendChild(verdict);
  $("axes").appendChild(card);
  return ax;
}

function bitTable(name, id, names) {
  const t = el("table", { class: "bittable" });
  const cap = el("caption");
  cap.innerHTML = `${name} <b id="${id}">-</b>`;
  t.appendChild(cap);
  const tr = el("tr");
  for (let b = 15; b >= 0; b--) {
    const td = el("td", { id: `${id}-b${b}`, title: `bit ${b}: ${names[b]}` }, String(b));
    tr.appendChild(td);
  }
  t.appendChild(tr);
  return t;
}

function showBits(id, word) {
  $(id).textContent = "0x" + word.toString(16).toUpperCase().padStart(4, "0");
  for (let b = 0; b < 16; b++) {
    const td = $(`${id}-b${b}`);
    if (td) td.className = (word >> b) & 1 ? "on" : "";
  }
}

function onHello(h) {
  state.hello = h;
  $("axes").innerHTML = "";
  state.axes = h.axes.map(buildAxis);
  $("runinfo").textContent =
    `${h.bus === "ethercat" ? "EtherCAT" : h.iface || "in-process bus"} · ${h.tick_hz} Hz${h.lockstep ? " lock-step" : ""} · ` +
    `${h.samples_per_s} samples/s per axis`;
  $("inject-node").textContent = `(node ${h.axes[0].node_id})`;
  // the bus faults of this run's bus only
  $("can-faults").hidden = h.bus === "ethercat";
  $("ecat-faults").hidden = h.bus !== "ethercat";
  const sel = $("param-key");
  sel.innerHTML = "";
  for (const p of h.controls.set) {
    const o = el("option", { value: p.key }, p.key);
    o.dataset.min = p.min; o.dataset.max = p.max; o.dataset.unit = p.unit;
    o.dataset.initial = p.initial;
    sel.appendChild(o);
  }
  const bl = h.controls.set.find((p) => p.key.startsWith("backlash_"));
  if (bl) sel.value = bl.key;
  onParamKey();
}

function onParamKey() {
  const o = $("param-key").selectedOptions[0];
  if (!o) return;
  const v = $("param-value");
  v.min = o.dataset.min; v.max = o.dataset.max;
  if (v.dataset.key !== o.value) { v.value = o.dataset.initial; v.dataset.key = o.value; }
  $("param-unit").textContent = o.dataset.unit;
  $("param-range").textContent =
    `${o.value}: ${o.dataset.min} .. ${o.dataset.max === "null" ? "∞" : o.dataset.max} ${o.dataset.unit}`;
}

// Drop samples older than KEEP_S, in chunks of at least a tenth of what is kept: moving
// 30000 numbers per column on every message would cost more than drawing them.
function trim(buf, tmax) {
  if (buf.t.length < 16 || buf.t[0] >= tmax - KEEP_S * 1.1) return;
  let k = 0;
  while (k < buf.t.length && buf.t[k] < tmax - KEEP_S) k++;
  if (k > 0) for (const key of Object.keys(buf)) buf[key].splice(0, k);
}

function onSamples(m) {
  state.messages++;
  state.simTime = m.t_s;
  $("simtime").textContent = m.t_s.toFixed(3);
  for (const e of m.axes) {
    const ax = state.axes[e.axis];
    if (!ax) continue;
    const s = e.samples, b = ax.buf;
    for (let i = 0; i < s.t_s.length; i++) {
      b.t.push(s.t_s[i]); b.demand.push(s.position_demand_uu[i]);
      b.actual.push(s.position_actual_uu[i]); b.ferr.push(s.following_error_uu[i]);
      b.rpm.push(s.motor_speed_rpm[i]); b.load.push(s.load_speed_uu_per_s[i]);
      b.current.push(s.current_a[i]);
    }
    if (b.t.length) trim(b, b.t[b.t.length - 1]);
    const st = e.state, i = e.axis;
    $("nmt-" + i).textContent = st.nmt_name;
    const s402 = $("state-" + i);
    s402.textContent = st.cia402_state;
    s402.className = "state " + st.cia402_state.toLowerCase().replace(/ /g, "-");
    $("mode-" + i).textContent = st.mode_name;
    $("pos-" + i).textContent = st.position_actual_uu;
    $("ferr-" + i).textContent = st.following_error_uu;
    $("lost-" + i).textContent = e.lost;
    showBits("sw-" + i, st.statusword);
    showBits("cw-" + i, st.controlword);
  }
  redraw();
}

// Drawing is paced by its own cost: a message draws at once when the last drawing ended at
// least MIN_DRAW_GAP_MS ago and at least as long ago as it took; otherwise one drawing is due
// at that time and the messages that arrive meanwhile are drawn together in it. The page thus
// spends at most half its time drawing: a browser short of CPU draws less often instead of
// falling ever further behind the stream, and the messages, the controls and anything else
// on the page still get their turn. (Drawing on animation frames did the same but cost the
// browser a quarter more: measured with benches/panel_page.rs.)
const MIN_DRAW_GAP_MS = 30;

function redraw() {
  if (state.drawTimer) return;
  const wait = state.drawEnd + Math.max(MIN_DRAW_GAP_MS, state.drawCost) - performance.now();
  if (wait <= 0) draw();
  else state.drawTimer = setTimeout(() => { state.drawTimer = 0; draw(); }, wait);
}

// The time plots and the buffer columns each draws (time first). uPlot draws a line through
// more points than its width has pixels as each pixel column's lowest and highest point, so
// a long span costs about what a short one does and every peak is still drawn.
const PLOTS = { pos: ["t", "demand", "actual"], ferr: ["t", "ferr"], speed: ["t", "rpm", "load"],
                current: ["t", "current"] };

function draw() {
  if ($("pause").checked) return;
  const t0 = performance.now();
  const span = Number($("span").value);
  for (const ax of state.axes) {
    const b = ax.buf;
    if (!b.t.length) continue;
    const tmax = b.t[b.t.length - 1];
    let k = b.t.length - 1;
    while (k > 0 && b.t[k - 1] >= tmax - span) k--;
    for (const [name, cols] of Object.entries(PLOTS)) ax[name].setData(cols.map((c) => b[c].slice(k)));
    const d = ax.pos.data;
    ax.plotted = { t_s: d[0][d[0].length - 1], position_actual_uu: d[2][d[2].length - 1],
                   points: d[0].length };
  }
  state.draws++;
  // uPlot draws in a microtask queued by setData: this one runs after it.
  queueMicrotask(() => {
    state.drawEnd = performance.now();
    state.drawCost = state.drawEnd - t0;
  });
}

function onSpectrum(m) {
  const ax = state.axes[m.axis];
  if (!ax) return;
  const f = m.amplitude_uu_s.map((_, i) => i * m.resolution_hz);
  ax.spectrum.setData([f, m.amplitude_uu_s]);
  const d = m.detector;
  const peak = m.peak ? `peak ${m.peak.frequency_hz} Hz, ${m.peak.amplitude_uu_s} uu/s` : "no peak";
  const v = $("verdict-" + m.axis);
  v.textContent = `detector (last ${d.window_s} s): ${d.verdict}` +
    (d.frequency_hz ? ` · f = ${d.frequency_hz} Hz (f/k_v ${d.frequency_over_kv})` : "") +
    (d.verdict !== "inconclusive" ? ` · amplitude ${d.amplitude} ${d.unit}` : "") +
    (d.backlash_estimate != null ? ` · gap ${d.backlash_estimate} ${d.backlash_estimate_unit}` +
      ` (${d.backlash_estimate_range[0]}..${d.backlash_estimate_range[1]}, ${d.backlash_estimate_method})` : "") +
    ` · band ${m.band_hz[0]}..${m.band_hz[1]} Hz · ${peak}` + (d.reason ? ` — ${d.reason}` : "");
  v.className = "verdict " + d.verdict;
}

function onStats(m) {
  const t = $("stats");
  t.innerHTML = "";
  for (const [k, v] of Object.entries(m)) {
    if (k === "type") continue;
    const tr = el("tr");
    tr.appendChild(el("td", {}, k));
    tr.appendChild(el("td", {}, typeof v === "number" && !Number.isInteger(v) ? v.toFixed(3) : String(v)));
    t.appendChild(tr);
  }
}

function logLine(list, text, cls) {
  const li = el("li", cls ? { class: cls } : {}, text);
  $(list).prepend(li);
  while ($(list).children.length > 200) $(list).lastChild.remove();
}

function onEmcy(m) {
  logLine("emcys", `t=${m.t_s.toFixed(3)} s node ${m.node_id} ${m.raised ? "raised" : "cleared"} ${m.code} ${m.meaning}`,
    m.raised ? "bad" : "good");
}

function onInjection(m) {
  logLine("injections", `t=${m.t_s.toFixed(3)} s node ${m.node_id}: ${m.event}`);
}

function onRecording(m) {
  const a = m.active;
  $("rec-state").textContent = a ? `recording #${a.number} since t=${a.started_t_s.toFixed(3)} s` +
    (a.note ? ` (${a.note})` : "") : "off";
  const ul = $("rec-files");
  ul.innerHTML = "";
  for (const f of m.files) {
    const li = el("li");
    const link = el("a", { href: withToken("/api/record/file/" + encodeURIComponent(f)), download: f }, f);
    li.appendChild(link);
    ul.appendChild(li);
  }
}

async function post(url, body) {
  const r = await fetch(url, {
    method: "POST",
    headers: Object.assign({ "Content-Type": "application/json" },
      TOKEN ? { Authorization: "Bearer " + TOKEN } : {}),
    body: JSON.stringify(body),
  });
  const j = await r.json().catch(() => ({ error: `HTTP ${r.status}` }));
  if (!r.ok) throw new Error((j.key ? `${j.key}: ` : "") + j.error);
  return j;
}

async function inject(body) {
  $("inject-error").textContent = "";
  try {
    return await post("/api/inject", body);
  } catch (e) {
    $("inject-error").textContent = e.message;
    return null;
  }
}

function canOver(body) {
  const over = $("can-over").value.trim();
  if (over) body.over = over;
  return body;
}

function wire() {
  $("param-key").addEventListener("change", onParamKey);
  $("param-set").addEventListener("click", () => {
    const key = $("param-key").value;
    const value = Number($("param-value").value);
    inject({ set: key, value });
  });
  for (const b of document.querySelectorAll("[data-sensor]"))
    b.addEventListener("click", () => inject({ sensor: b.dataset.sensor }));
  for (const b of document.querySelectorAll("[data-glitch]"))
    b.addEventListener("click", () =>
      inject({ sensor: b.dataset.glitch, counts: Math.round(Number($("glitch-counts").value)) }));
  for (const b of document.querySelectorAll("[data-can]"))
    b.addEventListener("click", () => {
      const kind = b.dataset.can;
      if (kind === "restore") return inject({ can: "restore" });
      const body = { can: kind };
      if (kind === "drop" || kind === "delay") body.share = Number($("can-share").value);
      if (kind === "delay") body.ticks = Math.round(Number($("can-ticks").value));
      return inject(canOver(body));
    });
  for (const b of document.querySelectorAll("[data-ecat]"))
    b.addEventListener("click", () => {
      const kind = b.dataset.ecat;
      const body = { ethercat: kind };
      const over = $("ecat-over").value.trim();
      if (kind === "lost" || kind === "corrupt") body.frames = Math.round(Number($("ecat-frames").value));
      if (kind === "late") body.hold = $("ecat-hold").value.trim();
      if (kind === "out_of_op") body.al_code = $("ecat-al").value.trim();
      if (over && ["link_down", "bad_wkc", "late"].includes(kind)) body.over = over;
      return inject(body);
    });
  $("rec-start").addEventListener("click", () => post("/api/record", { action: "start" }).catch((e) => alert(e.message)));
  $("rec-stop").addEventListener("click", () => post("/api/record", { action: "stop" }).catch((e) => alert(e.message)));
  $("session-link").href = withToken("/api/session");
  $("span").addEventListener("change", redraw);
}

function connect() {
  const es = new EventSource(withToken("/api/stream"));
  es.onopen = () => { $("conn").textContent = "live"; $("conn").className = "good"; };
  es.onerror = () => { $("conn").textContent = "reconnecting"; $("conn").className = "bad"; };
  const on = (kind, f) => es.addEventListener(kind, (ev) => f(JSON.parse(ev.data)));
  on("hello", onHello);
  on("samples", onSamples);
  on("spectrum", onSpectrum);
  on("stats", onStats);
  on("emcy", onEmcy);
  on("injection", onInjection);
  on("recording", onRecording);
  on("lagged", (m) => logLine("emcys", `stream: ${m.messages} messages lost (slow client)`));
  // `?snapshot`: draw the run's recent past and close the stream, so that a headless browser's
  // --screenshot --virtual-time-budget ends (an open stream keeps its virtual time going).
  on("live", () => {
    if (!new URLSearchParams(location.search).has("snapshot")) return;
    es.close();
    $("conn").textContent = "snapshot"; $("conn").className = "";
    draw();
  });
}

// What a test (or a curious user) can ask the page: the last plotted values and states.
window.panel = {
  plotted: (axis) => state.axes[axis] && state.axes[axis].plotted,
  // The plotted actual position at drive time t_s (the last plotted point at or before it).
  plottedAt: (axis, t_s) => {
    const ax = state.axes[axis];
    if (!ax) return null;
    const d = ax.pos.data;
    let k = -1;
    for (let i = 0; i < d[0].length && d[0][i] <= t_s + 1e-9; i++) k = i;
    return k < 0 ? null : { t_s: d[0][k], position_actual_uu: d[2][k] };
  },
  state: (axis) => $("state-" + axis) && $("state-" + axis).textContent,
  // Every y axis drawn: its width and what its longest tick label needs.
  axisFit: () => state.axes.flatMap((ax) => ["pos", "ferr", "speed", "current", "spectrum"].flatMap(
    (name) => ax[name].axes.slice(1).filter((a) => a._values && a._values.length).map((a) => {
      const u = ax[name];
      u.ctx.font = a.font[0];
      const label = a._values.reduce((l, v) => (String(v).length > l.length ? String(v) : l), "");
      return { plot: name, label, size: a._size,
               need: a.ticks.size + a.gap + u.ctx.measureText(label).width / devicePixelRatio };
    }))),
  // `samples` messages taken and drawings made since the page opened.
  counts: () => ({ messages: state.messages, draws: state.draws }),
  inject,
};

wire();
connect();
