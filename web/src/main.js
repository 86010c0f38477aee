// retime edit: the page. State lives on the server (one session per tab); this file wires the
// viewer, the curve editor, the method panel and the live websocket together.
import "./style.css";
import { Viewer, probeWebGL } from "./viewer.js";
import { CurveEditor, SpeedPlot, TimeAxis } from "./plots.js";

const $ = (id) => document.getElementById(id);

// ---- messages ------------------------------------------------------------------------------
function toast(message, kind = "error", title = null) {
  const box = document.createElement("div");
  box.className = "toast" + (kind === "info" ? " info" : "");
  box.setAttribute("role", kind === "error" ? "alert" : "status");
  if (title) { const b = document.createElement("b"); b.textContent = title; box.appendChild(b); }
  box.appendChild(document.createTextNode(message));
  $("toasts").appendChild(box);
  while ($("toasts").children.length > 4) $("toasts").firstChild.remove();
  setTimeout(() => box.remove(), kind === "error" ? 9000 : 5000);
}

function setStatus(kind, text) {
  $("status").className = "status " + kind;
  $("status-text").textContent = text;
}

async function api(path, { method = "GET", body = undefined, binary = false } = {}) {
  let res;
  try {
    res = await fetch(path, {
      method,
      headers: body !== undefined ? { "content-type": "application/json" } : {},
      body: body !== undefined ? JSON.stringify(body) : undefined,
    });
  } catch (e) {
    throw new Error("the editor's server cannot be reached (was it stopped?)");
  }
  if (!res.ok) {
    let msg = `${res.status} ${res.statusText}`;
    try { const j = await res.json(); if (j && j.error) msg = j.error; } catch (e) { /* not JSON */ }
    throw new Error(msg);
  }
  return binary ? res.arrayBuffer() : res.json();
}

// ---- state ---------------------------------------------------------------------------------
const state = {
  session: null, clip: null, methods: [], method: "linear", params: {},
  solution: null, seq: 0, sentAt: new Map(), lastSolvedSeq: -1, lastFinalSeq: -1,
  playing: true, playT: 0, rate: 1, lastFrame: null,
  latencies: [], // drag -> reconverged curve on screen (ms)
};
window.__retime = state; // read by the browser tests

let viewer = null, editor = null, speedPlot = null, ws = null, wsRetry = 0;
const axis = new TimeAxis();

// ---- live loop -----------------------------------------------------------------------------
let queued = null, flushScheduled = false;

function send(ops, eventTime = performance.now()) {
  const seq = ++state.seq;
  state.sentAt.set(seq, eventTime);
  state.sendTime = state.sendTime || new Map();
  state.sendTime.set(seq, performance.now());
  if (state.sentAt.size > 500) state.sentAt.delete(state.sentAt.keys().next().value);
  const msg = JSON.stringify({ seq, ops });
  if (ws && ws.readyState === WebSocket.OPEN) {
    ws.send(msg);
    setStatus("busy", "solving…");
  } else {
    // no live connection: fall back to plain HTTP
    api(`/api/session/${state.session}/edit`, { method: "POST", body: { seq, ops } })
      .then((sol) => onSolution(sol)).catch((e) => { toast(e.message); restoreInputs(); refresh(); });
  }
  return seq;
}

// drags send each move at once (browsers already deliver at most one pointermove per frame); only
// when the socket backs up are moves coalesced to one per animation frame, the newest winning
function queueMove(op, eventTime) {
  if (ws && ws.readyState === WebSocket.OPEN && ws.bufferedAmount < 4096 && !queued) { send([op], eventTime); return; }
  queued = { op, eventTime };
  if (!flushScheduled) {
    flushScheduled = true;
    requestAnimationFrame(() => {
      flushScheduled = false;
      if (queued) { send([queued.op], queued.eventTime); queued = null; }
    });
  }
}

function flushMoves() {
  if (queued) { send([queued.op], queued.eventTime); queued = null; }
}

function connect() {
  const proto = location.protocol === "https:" ? "wss:" : "ws:";
  ws = new WebSocket(`${proto}//${location.host}/api/session/${state.session}/live`);
  ws.onopen = () => { wsRetry = 0; setStatus("live", "live"); };
  ws.onmessage = (ev) => {
    let msg;
    try { msg = JSON.parse(ev.data); } catch (e) { return; }
    if (msg.type === "solution") onSolution(msg);
    else if (msg.type === "status") setStatus(msg.message ? "busy" : "live", msg.message || "live");
    else if (msg.type === "error") {
      toast(msg.message, "error", "Could not apply the edit");
      restoreInputs();
      if (/no such session/.test(msg.message)) restart();
    }
  };
  ws.onclose = () => {
    setStatus("down", "reconnecting…");
    const delay = Math.min(5000, 300 * 2 ** wsRetry++);
    setTimeout(() => { if (state.session) connect(); }, delay);
  };
}

function onSolution(sol) {
  const recv = performance.now();
  if (sol.seq != null && sol.seq < state.lastSolvedSeq) return; // an older answer arriving late
  if (sol.seq != null) state.lastSolvedSeq = sol.seq;
  state.solution = sol;
  state.method = sol.method;
  if (sol.params) state.params[sol.method] = { ...(state.params[sol.method] || {}), ...sol.params };
  editor.set(sol.points, sol.curve, sol.source_duration, state.clip.fps, sol.keytimes);
  speedPlot.set(sol.curve, sol.speed, sol.feasibility);
  $("feas-legend").hidden = !sol.feasibility;
  updatePanel();
  updateScrub();
  state.dirty = true;
  if (sol.final) {
    if (sol.seq != null) state.lastFinalSeq = sol.seq;
    setStatus("live", "live");
    const t0 = state.sentAt.get(sol.seq);
    if (t0 !== undefined) {
      state.sentAt.delete(sol.seq);
      // "on screen": after the frame that shows the new curve has been painted
      requestAnimationFrame(() => setTimeout(() => {
        const ms = performance.now() - t0;
        const sent = state.sendTime.get(sol.seq);
        state.latencies.push({ seq: sol.seq, ms, solve_ms: sol.info.solve_ms ?? null, method: sol.method,
          queued_ms: sent - t0, network_ms: recv - sent, paint_ms: performance.now() - recv });
        showStats(ms, sol);
      }, 0));
    }
  }
}

// after a refused edit, put the fields back to what the server has
function restoreInputs() {
  if (!state.solution) return;
  if (document.activeElement && document.activeElement.tagName === "INPUT") document.activeElement.blur();
  $("duration").value = state.solution.duration.toFixed(3);
  builtFor = null; // rebuild the parameter fields from the server's values
  updatePanel();
}

function showStats(ms, sol) {
  const info = sol.info || {};
  const lines = [`last edit → curve on screen: <b>${ms.toFixed(0)} ms</b>`];
  if (info.solve_ms != null) lines.push(`solve: ${Number(info.solve_ms).toFixed(1)} ms`);
  for (const [k, v] of Object.entries(info)) {
    if (k === "solve_ms" || v === null) continue;
    lines.push(`${k.replace(/_/g, " ")}: ${typeof v === "number" ? +v.toPrecision(4) : v}`);
  }
  $("stats").innerHTML = lines.join("<br>");
}

// ---- panel ---------------------------------------------------------------------------------
function buildMethods() {
  const box = $("methods");
  box.replaceChildren();
  for (const m of state.methods) {
    const b = document.createElement("button");
    b.textContent = m.label;
    b.dataset.method = m.name;
    b.setAttribute("role", "tab");
    b.title = m.available ? m.description : m.reason;
    b.disabled = !m.available;
    b.addEventListener("click", () => { if (m.name !== state.method) send([{ op: "method", method: m.name }]); });
    box.appendChild(b);
  }
}

function buildParams() {
  const box = $("params");
  box.replaceChildren();
  const m = state.methods.find((x) => x.name === state.method);
  if (!m) return;
  const values = state.params[m.name] || {};
  for (const p of m.params) {
    const field = document.createElement("div");
    field.className = "field";
    const id = `param-${m.name}-${p.name}`;
    const label = document.createElement("label");
    label.htmlFor = id;
    label.textContent = p.label;
    let input;
    if (p.kind === "choice") {
      input = document.createElement("select");
      for (const [value, text] of p.choices) {
        const o = document.createElement("option");
        o.value = value; o.textContent = text;
        input.appendChild(o);
      }
      input.value = values[p.name] ?? p.default;
    } else if (p.kind === "bool") {
      input = document.createElement("input");
      input.type = "checkbox";
      input.checked = !!(values[p.name] ?? p.default);
      label.className = "check";
      label.prepend(input);
    } else {
      input = document.createElement("input");
      input.type = p.kind === "slider" ? "range" : "number";
      Object.assign(input, { min: p.min, max: p.max, step: p.step ?? "any" });
      input.value = values[p.name] ?? p.default;
    }
    input.id = id;
    input.addEventListener("change", () => {
      let v = p.kind === "bool" ? input.checked : p.kind === "number" || p.kind === "slider" ? Number(input.value) : input.value;
      state.params[m.name] = { ...(state.params[m.name] || {}), [p.name]: v };
      send([{ op: "params", method: m.name, values: { [p.name]: v } }]);
    });
    if (p.kind === "bool") field.appendChild(label);
    else {
      field.appendChild(label);
      const row = document.createElement("div");
      row.className = "inline";
      row.appendChild(input);
      if (p.kind === "slider") {  // the value beside the slider, following it while dragged
        const shown = document.createElement("output");
        shown.htmlFor = id; shown.textContent = Number(input.value).toFixed(2);
        input.addEventListener("input", () => { shown.textContent = Number(input.value).toFixed(2); });
        row.appendChild(shown);
      }
      if (p.unit) { const u = document.createElement("span"); u.className = "unit"; u.textContent = p.unit; row.appendChild(u); }
      field.appendChild(row);
    }
    if (p.help) { const h = document.createElement("div"); h.className = "help"; h.textContent = p.help; field.appendChild(h); }
    box.appendChild(field);
  }
}

let builtFor = null;
function updatePanel() {
  const sol = state.solution;
  for (const b of $("methods").children) b.classList.toggle("active", b.dataset.method === state.method);
  const m = state.methods.find((x) => x.name === state.method);
  $("method-desc").textContent = m ? m.description : "";
  editor.axes = m ? m.point_axes : "ts";
  if (builtFor !== state.method) { buildParams(); builtFor = state.method; }
  if (document.activeElement !== $("duration")) $("duration").value = sol.duration.toFixed(3);
  $("duration-ratio").textContent = `${(sol.source_duration / sol.duration).toFixed(2)}× speed`;
  $("label-retimed").innerHTML = `<span class="swatch retimed"></span>Retimed · ${sol.duration.toFixed(2)} s · ${m ? m.label : ""}`;
  updatePointTools();
}

function updatePointTools() {
  const i = editor.selected, pts = state.solution ? state.solution.points : [];
  const p = pts[i];
  const inner = p && i > 0 && i < pts.length - 1;
  $("lock").disabled = !inner;
  $("remove").disabled = !inner;
  $("lock").textContent = inner && p.locked ? "Unlock" : "Lock";
  if (!p) $("point-info").textContent = "Select a point on the timing curve.";
  else $("point-info").textContent = `${i === 0 ? "Start" : i === pts.length - 1 ? "End" : p.locked ? "Keytime" : "Point"} ${i}: output ${p.t.toFixed(3)} s ← source ${p.s.toFixed(3)} s`;
}

// ---- playback --------------------------------------------------------------------------------
function totalTime() {
  const sol = state.solution;
  return Math.max(state.clip.duration, sol ? sol.duration : 0);
}

function retimedSource(t) {
  // source time at output time t, from the per-output-frame curve
  const c = state.solution.curve, fps = state.clip.fps;
  const n = c.t.length;
  if (t >= c.t[n - 1]) return c.s[n - 1];
  const x = t * fps, k = Math.min(Math.floor(x), n - 2), w = x - k;
  return c.s[k] + w * (c.s[k + 1] - c.s[k]);
}

function draw(t) {
  state.playT = t;
  const fps = state.clip.fps;
  const sOrig = Math.min(t, state.clip.duration);
  const sRet = retimedSource(Math.min(t, state.solution.duration));
  state.shown = { t, sourceOriginal: sOrig, sourceRetimed: sRet };
  if (viewer) viewer.show(sOrig * fps, sRet * fps);
  editor.setPlayhead(Math.min(t, state.solution.duration));
  speedPlot.setPlayhead(Math.min(t, state.solution.duration));
  $("time").textContent = `${t.toFixed(2)} / ${totalTime().toFixed(2)} s`;
  if (!scrubbing) $("scrub").value = Math.round((t / totalTime()) * 1000);
}

let scrubbing = false;
function updateScrub() {
  const marks = $("scrub-marks");
  marks.replaceChildren();
  const T = totalTime();
  const pts = state.solution.points;
  pts.forEach((p, i) => {
    if (!p.locked || i === 0 || i === pts.length - 1) return;
    const m = document.createElement("div");
    m.className = "mark";
    m.style.left = `${(100 * p.t) / T}%`;
    m.title = `keytime: output ${p.t.toFixed(2)} s`;
    marks.appendChild(m);
  });
  for (const [, kt] of state.solution.keytimes || []) {
    const m = document.createElement("div");
    m.className = "mark";
    m.style.left = `${(100 * kt) / T}%`;
    m.title = `keytime: output ${kt.toFixed(2)} s`;
    marks.appendChild(m);
  }
  for (const [end, what] of [[state.clip.duration, "original ends"], [state.solution.duration, "retimed ends"]]) {
    const m = document.createElement("div");
    m.className = "end";
    m.style.left = `${(100 * end) / T}%`;
    m.title = what;
    marks.appendChild(m);
  }
  axis.max = niceMax(Math.max(state.clip.duration, state.solution.duration) * 1.04);
  drawResidualStrip();
}

// The clip's own physics (retime check), under the scrub bar where the original plays: each source
// frame's residual, grey below the threshold, red above (full red at 1 body weight).
function drawResidualStrip() {
  const strip = $("residual-strip"), check = state.check;
  strip.replaceChildren();
  if (!check || !check.available) return;
  const T = totalTime(), fps = state.clip.fps, r = check.residual;
  for (let i = 0; i < r.length;) {
    const over = r[i] > check.threshold;
    let j = i + 1;
    while (j < r.length && (r[j] > check.threshold) === over && (!over || Math.abs(r[j] - r[i]) < 0.1)) j++;
    const seg = document.createElement("div");
    seg.className = over ? "res over" : "res";
    seg.style.left = `${(100 * i) / fps / T}%`;
    seg.style.width = `${Math.max((100 * (j - i)) / fps / T, 0.15)}%`;
    if (over) seg.style.opacity = String(0.45 + 0.55 * Math.min(1, r[i]));
    seg.title = over ? `frames ${i}-${j - 1}: ${r[i].toFixed(2)} body weights of force no contact gives` : "";
    strip.appendChild(seg);
    i = j;
  }
}

async function loadCheck() {
  try {
    state.check = await api(`/api/session/${state.session}/check`);
  } catch (e) {
    state.check = { available: false, reason: e.message };
  }
  const c = state.check;
  $("check-info").textContent = c.available ? `physics of the original: ${c.verdict}` : `no physics check: ${c.reason}`;
  if (viewer && c.available) viewer.setCheck(c);
  drawResidualStrip();
  state.dirty = true;
}

function niceMax(v) { return v; }

function tick(now) {
  if (state.lastFrame !== null && state.playing && !scrubbing) {
    let t = state.playT + ((now - state.lastFrame) / 1000) * state.rate;
    const T = totalTime() + 0.4; // a short hold at the end before looping
    if (t > T) t = 0;
    draw(Math.min(t, T));
    state.playT = t;
  } else if (state.solution && state.dirty) draw(state.playT);
  state.dirty = false;
  state.lastFrame = now;
  requestAnimationFrame(tick);
}

function setPlaying(on) {
  state.playing = on;
  $("play").textContent = on ? "❚❚" : "▶";
  $("play").setAttribute("aria-label", on ? "Pause" : "Play");
}

// ---- start -------------------------------------------------------------------------------------
async function start() {
  setStatus("busy", "loading");
  const info = await api("/api/session", { method: "POST", body: {} });
  Object.assign(state, {
    session: info.session, clip: info.clip, methods: info.methods, method: info.method, params: info.params,
    solution: info.solution,
  });
  const c = info.clip;
  $("clipinfo").textContent = `${c.name} · ${c.n_frames} frames at ${+c.fps.toPrecision(6)} Hz · ${c.duration.toFixed(2)} s`
    + (c.reference ? ` · reference ${c.reference}` : "");
  $("label-original").innerHTML = `<span class="swatch original"></span>Original · ${c.duration.toFixed(2)} s`;
  buildMethods();

  editor = new CurveEditor($("curve"), axis, {
    onMove: (i, t, s, ev) => queueMove({ op: "move", index: i, t, s, hold: true }, ev.timeStamp || performance.now()),
    onDragEnd: (i) => { flushMoves(); send([{ op: "release", index: i }]); },
    onAdd: (t, s) => send([{ op: "add", t, s }]),
    onSelect: () => updatePointTools(),
    onRemove: (i) => { send([{ op: "remove", index: i }]); editor.selected = -1; },
    onLock: (i) => { const p = state.solution.points[i]; if (p) send([{ op: "lock", index: i, locked: !p.locked }]); },
  });
  speedPlot = new SpeedPlot($("speed"), axis);
  updateScrub();
  onSolution(info.solution);

  const gl = new URLSearchParams(location.search).get("viewer") === "0" ? null : probeWebGL();
  if (gl) {
    try {
      const buf = await api(`/api/session/${state.session}/positions`, { binary: true });
      // without a GPU (software WebGL) draw lighter so that editing stays responsive
      const qs = new URLSearchParams(location.search);
      const quality = gl.software ? { lite: true, shadows: false, antialias: false, pixelRatio: 0.6 } : {};
      state.webgl = { ...gl, quality };
      if (qs.has("aa")) quality.antialias = qs.get("aa") === "1";
      if (qs.has("shadows")) quality.shadows = qs.get("shadows") === "1";
      if (qs.has("pr")) quality.pixelRatio = Number(qs.get("pr"));
      if (qs.has("lite")) quality.lite = qs.get("lite") === "1";
      if (qs.has("preserve")) quality.preserve = qs.get("preserve") === "1";
      viewer = new Viewer($("viewer"), c.skeleton, new Float32Array(buf), c.n_frames, quality);
      viewer.onChange = () => { state.dirty = true; };
      state.viewer = viewer;
    } catch (e) {
      showViewerMessage(`The 3-D view could not start: ${e.message}`);
    }
  } else {
    showViewerMessage("This browser has no WebGL, so the 3-D view is off; the timing editor works.");
  }

  $("play").addEventListener("click", () => setPlaying(!state.playing));
  $("rate").addEventListener("change", () => { state.rate = Number($("rate").value); });
  $("follow").addEventListener("change", () => { if (viewer) viewer.follow = $("follow").checked; state.dirty = true; });
  $("scrub").addEventListener("input", () => { scrubbing = true; setPlaying(false); draw((Number($("scrub").value) / 1000) * totalTime()); });
  $("scrub").addEventListener("change", () => { scrubbing = false; });
  $("duration").addEventListener("change", () => {
    const v = Number($("duration").value);
    if (!(v > 0)) { toast("the duration must be a positive number of seconds"); return; }
    send([{ op: "duration", duration: v }]);
  });
  $("lock").addEventListener("click", () => editor.cb.onLock(editor.selected));
  $("remove").addEventListener("click", () => editor.cb.onRemove(editor.selected));
  $("reset").addEventListener("click", () => send([{ op: "reset" }]));
  $("export").addEventListener("click", exportFiles);
  document.addEventListener("keydown", (e) => {
    if (e.target.tagName === "INPUT" || e.target.tagName === "SELECT") return;
    if (e.key === " ") { e.preventDefault(); setPlaying(!state.playing); }
  });
  setPlaying(true);
  connect();
  requestAnimationFrame(tick);
  state.ready = true;
  loadCheck(); // seconds of physics on the server: the page works meanwhile
}

function showViewerMessage(text) {
  const m = $("viewer-message");
  m.textContent = text;
  m.hidden = false;
}

async function exportFiles() {
  const button = $("export");
  button.disabled = true;
  button.textContent = "Exporting…";
  try {
    const r = await api(`/api/session/${state.session}/export`, { method: "POST", body: {} });
    const box = $("exports");
    box.replaceChildren();
    const folder = document.createElement("div");
    folder.className = "folder";
    folder.textContent = `Written to ${r.folder}: ${r.frames} frames, ${r.duration.toFixed(2)} s`;
    box.appendChild(folder);
    for (const f of r.files) {
      const a = document.createElement("a");
      a.href = f.url;
      a.download = f.name;
      a.textContent = `⤓ ${f.name} (${(f.bytes / 1024).toFixed(0)} KiB)`;
      box.appendChild(a);
    }
    toast(`${r.files.map((f) => f.name).join(" and ")} written`, "info", "Exported");
  } catch (e) {
    toast(e.message, "error", "Export failed");
  } finally {
    button.disabled = false;
    button.textContent = "Export BVH + warp CSV";
  }
}

async function refresh() {
  try { onSolution((await api(`/api/session/${state.session}`)).solution); } catch (e) { toast(e.message); }
}

function restart() {
  toast("The session expired; starting a new one.", "info");
  setTimeout(() => location.reload(), 1500);
}

window.addEventListener("error", (e) => toast(`page error: ${e.message}`));
window.addEventListener("unhandledrejection", (e) => toast(`${e.reason && e.reason.message ? e.reason.message : e.reason}`));
start().catch((e) => {
  setStatus("down", "error");
  toast(e.message, "error", "The editor could not start");
  $("clipinfo").textContent = `could not start: ${e.message}`;
});
