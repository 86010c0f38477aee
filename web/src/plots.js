// The timing-curve editor and the speed plot (SVG).
const NS = "http://www.w3.org/2000/svg";

function el(name, attrs = {}, parent = null) {
  const e = document.createElementNS(NS, name);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  if (parent) parent.appendChild(e);
  return e;
}

function niceStep(range, target) {
  const raw = range / Math.max(1, target);
  const mag = Math.pow(10, Math.floor(Math.log10(raw)));
  for (const m of [1, 2, 2.5, 5, 10]) if (m * mag >= raw) return m * mag;
  return 10 * mag;
}

const fmt = (v) => (Math.abs(v) < 1e-9 ? "0" : v.toFixed(v < 10 ? (Number.isInteger(Math.round(v * 10) / 10) && Math.round(v * 10) % 10 === 0 ? 0 : 1) : 0));

// Shared horizontal axis (output time) for both plots.
export class TimeAxis {
  constructor() { this.max = 1; this.left = 48; this.right = 14; this.width = 600; }
  x(t) { return this.left + (t / this.max) * (this.width - this.left - this.right); }
  t(x) { return ((x - this.left) / (this.width - this.left - this.right)) * this.max; }
}

export class CurveEditor {
  // callbacks: onMove(i, t, s, ev), onDragEnd(i), onAdd(t, s), onSelect(i), onRemove(i), onLock(i)
  constructor(svg, axis, callbacks) {
    this.svg = svg;
    this.axis = axis;
    this.cb = callbacks;
    this.top = 12; this.bottom = 26;
    this.points = [];
    this.curve = null;
    this.S = 1;
    this.fps = 120;
    this.selected = -1;
    this.drag = null;
    this.axes = "ts"; // "s": interior points move only vertically (their output time is a spline knot)
    this.playT = 0;
    svg.addEventListener("dblclick", (e) => this._dblclick(e));
    svg.addEventListener("pointerdown", (e) => { if (e.target === svg || e.target.classList.contains("bg")) this.select(-1); });
    svg.addEventListener("keydown", (e) => this._key(e));
    new ResizeObserver(() => this.render()).observe(svg);
  }

  get height() { return this.svg.clientHeight || 230; }
  y(s) { return this.top + (1 - s / this.S) * (this.height - this.top - this.bottom); }
  s(y) { return (1 - (y - this.top) / (this.height - this.top - this.bottom)) * this.S; }

  _local(e) {
    const r = this.svg.getBoundingClientRect();
    return [e.clientX - r.left, e.clientY - r.top];
  }

  set(points, curve, S, fps, keytimes = []) {
    this.S = S; this.fps = fps;
    this.keytimes = keytimes || [];
    if (!this.drag) this.points = points.map((p) => ({ ...p }));
    else {
      // keep the point under the cursor where the user holds it; take the others from the server
      const held = this.points[this.drag.index];
      this.points = points.map((p) => ({ ...p }));
      if (held && this.points.length === this.drag.count) this.points[this.drag.index] = held;
    }
    this.curve = curve;
    this.pending = false;
    this.render();
  }

  select(i) {
    this.selected = i;
    this.render();
    this.cb.onSelect(i);
  }

  _dblclick(e) {
    const hit = e.target.closest ? e.target.closest(".cp") : null;
    if (hit) return;
    const [x, y] = this._local(e);
    const t = this.axis.t(x), s = this.s(y);
    this.cb.onAdd(t, Math.min(Math.max(s, 0), this.S));
  }

  _key(e) {
    if (this.selected < 0) return;
    if (e.key === "Delete" || e.key === "Backspace") { e.preventDefault(); this.cb.onRemove(this.selected); }
    else if (e.key === "l" || e.key === "L") { e.preventDefault(); this.cb.onLock(this.selected); }
  }

  _startDrag(e, i) {
    e.preventDefault();
    e.stopPropagation();
    this.svg.focus({ preventScroll: true });
    this.select(i);
    if (i === 0) return; // (0, 0) is fixed
    // capture on the <svg>, which stays in the document while the points are redrawn
    const target = this.svg;
    this.drag = { index: i, count: this.points.length, pointerId: e.pointerId };
    target.setPointerCapture(e.pointerId);
    target.classList.add("dragging");
    const move = (ev) => {
      if (ev.pointerId !== e.pointerId) return;
      const [x, y] = this._local(ev);
      const p = this.points[i];
      const gap = 1 / this.fps;
      let t = this.axis.t(x), s = this.s(y);
      const last = this.points.length - 1;
      if (i === last) { s = this.S; t = Math.max(t, this.points[i - 1].t + gap, 2 * gap); }
      else {
        if (this.axes === "s") t = p.t;
        t = Math.min(Math.max(t, this.points[i - 1].t + gap), this.points[i + 1].t - gap);
        s = Math.min(Math.max(s, this.points[i - 1].s + 1e-3), this.points[i + 1].s - 1e-3);
      }
      p.t = t; p.s = s;
      this.pending = true;
      this.render();
      this.cb.onMove(i, t, s, ev);
    };
    const up = (ev) => {
      if (ev.pointerId !== e.pointerId) return;
      target.removeEventListener("pointermove", move);
      target.removeEventListener("pointerup", up);
      target.removeEventListener("pointercancel", up);
      target.classList.remove("dragging");
      this.drag = null;
      this.cb.onDragEnd(i);
    };
    target.addEventListener("pointermove", move);
    target.addEventListener("pointerup", up);
    target.addEventListener("pointercancel", up);
  }

  render() {
    const svg = this.svg, ax = this.axis;
    ax.width = svg.clientWidth || ax.width;
    const W = ax.width, H = this.height;
    // the grid and axes change only with the size or the time ranges: redraw them only then
    const key = [W, H, ax.max, this.S].join(",");
    if (key !== this.staticKey || !this.gStatic || !this.gStatic.isConnected) {
      this.staticKey = key;
      svg.setAttribute("viewBox", `0 0 ${W} ${H}`);
      svg.replaceChildren();
      this.gStatic = el("g", {}, svg);
      this.gDynamic = el("g", {}, svg);
      this.gPoints = el("g", {}, svg);
      this.pointsKey = null;
      this._renderStatic(this.gStatic, W, H);
    }
    this._renderDynamic(this.gDynamic, W, H);
    this._renderPoints(this.gPoints);
  }

  _renderStatic(svg, W, H) {
    const ax = this.axis;
    el("rect", { class: "bg", x: 0, y: 0, width: W, height: H, fill: "transparent" }, svg);
    const grid = el("g", { class: "grid" }, svg), axis = el("g", { class: "axis" }, svg);
    const xs = niceStep(ax.max, W / 90);
    for (let t = 0; t <= ax.max + 1e-9; t += xs) {
      el("line", { x1: ax.x(t), x2: ax.x(t), y1: this.top, y2: H - this.bottom }, grid);
      el("text", { x: ax.x(t), y: H - this.bottom + 15, "text-anchor": "middle" }, axis).textContent = fmt(t);
    }
    const ys = niceStep(this.S, Math.max(2, (H - 40) / 40));
    for (let s = 0; s <= this.S + 1e-9; s += ys) {
      el("line", { x1: ax.x(0), x2: ax.x(ax.max), y1: this.y(s), y2: this.y(s) }, grid);
      el("text", { x: ax.x(0) - 7, y: this.y(s) + 4, "text-anchor": "end" }, axis).textContent = fmt(s);
    }
    el("text", { class: "label", x: W - this.axis.right, y: H - 2, "text-anchor": "end" }, svg).textContent = "output time (s)";
    el("text", { class: "label", x: 0, y: 0, transform: `translate(11 ${this.top}) rotate(-90)`, "text-anchor": "end" }, svg).textContent = "source time (s)";
    el("line", { class: "identity", x1: ax.x(0), y1: this.y(0), x2: ax.x(Math.min(this.S, ax.max)), y2: this.y(Math.min(this.S, ax.max)) }, svg);
  }

  _renderDynamic(svg, W, H) {
    const ax = this.axis;
    svg.replaceChildren();
    const T = this.points.length ? this.points[this.points.length - 1].t : 1;
    el("rect", { class: "bounds", x: ax.x(0), y: this.y(this.S), width: Math.max(0, ax.x(T) - ax.x(0)), height: this.y(0) - this.y(this.S) }, svg);

    // keytime guides (locked interior points)
    const n = this.points.length;
    this.points.forEach((p, i) => {
      if (!p.locked || i === 0 || i === n - 1) return;
      el("line", { class: "keyguide", x1: ax.x(p.t), x2: ax.x(p.t), y1: this.y(p.s), y2: H - this.bottom }, svg);
      el("line", { class: "keyguide", x1: ax.x(0), x2: ax.x(p.t), y1: this.y(p.s), y2: this.y(p.s) }, svg);
      el("path", { class: "keymark", d: `M${ax.x(p.t)},${H - this.bottom} l-4,6 h8 z` }, svg);
      el("path", { class: "keymark", d: `M${ax.x(0)},${this.y(p.s)} l-6,-4 v8 z` }, svg);
    });

    // keytimes that are not control points (physics keeps them as constraints): diamonds
    for (const [ks, kt] of this.keytimes || []) {
      el("line", { class: "keyguide", x1: ax.x(kt), x2: ax.x(kt), y1: this.y(ks), y2: H - this.bottom }, svg);
      el("line", { class: "keyguide", x1: ax.x(0), x2: ax.x(kt), y1: this.y(ks), y2: this.y(ks) }, svg);
      el("path", { class: "keymark", d: `M${ax.x(kt)},${H - this.bottom} l-4,6 h8 z` }, svg);
      el("path", { class: "keymark", d: `M${ax.x(0)},${this.y(ks)} l-6,-4 v8 z` }, svg);
      const g = el("path", { class: "keytime", d: `M${ax.x(kt)},${this.y(ks) - 7} l7,7 l-7,7 l-7,-7 z` }, svg);
      el("title", {}, g).textContent = `keytime: output ${kt.toFixed(3)} s plays source ${ks.toFixed(3)} s (Reset clears it)`;
    }

    // the curve
    if (this.curve) {
      const { t, s } = this.curve;
      let d = "";
      const step = Math.max(1, Math.floor(t.length / (2 * W)));
      for (let k = 0; k < t.length; k += step) d += (k ? "L" : "M") + ax.x(t[k]).toFixed(1) + "," + this.y(s[k]).toFixed(1);
      d += "L" + ax.x(t[t.length - 1]).toFixed(1) + "," + this.y(s[s.length - 1]).toFixed(1);
      el("path", { class: "curve" + (this.pending ? " pending" : ""), d, id: "curve-path" }, svg);
    }
    el("line", { class: "playhead", x1: ax.x(this.playT), x2: ax.x(this.playT), y1: this.top, y2: H - this.bottom, id: "curve-playhead" }, svg);
  }

  // Control points. A physics curve has one per 0.05 s (about 90 for a 4-second clip), all of which
  // move after each solve: when only positions changed, move the existing nodes instead of rebuilding
  // them (and their listeners), which keeps the page's work per solution small.
  _renderPoints(svg) {
    const ax = this.axis, n = this.points.length;
    const kind = (p, i) => (i === 0 || i === n - 1 ? "e" : p.locked ? "k" : "c") + (i === this.selected ? "s" : "");
    const key = this.points.map(kind).join("");
    const where = (p) => `translate(${ax.x(p.t)},${this.y(p.s)})`;
    const label = (p, i) => `${i === 0 ? "start" : i === n - 1 ? "end (drag to change the duration)" : p.locked ? "keytime" : "control point"}: output ${p.t.toFixed(3)} s plays source ${p.s.toFixed(3)} s`;
    if (key === this.pointsKey && svg.childElementCount === n) {
      const nodes = svg.children;
      this.points.forEach((p, i) => {
        nodes[i].setAttribute("transform", where(p));
        nodes[i].lastChild.textContent = label(p, i);
      });
      return;
    }
    this.pointsKey = key;
    svg.replaceChildren();
    this.points.forEach((p, i) => {
      const cls = ["cp"];
      if (p.locked) cls.push("locked");
      if (i === 0 || i === n - 1) cls.push("end");
      if (i === this.selected) cls.push("selected");
      const g = el("g", { class: cls.join(" "), "data-index": i, transform: where(p) }, svg);
      el("circle", { class: "hit", r: 11 }, g);
      if (p.locked && i > 0 && i < n - 1) el("rect", { class: "knob", x: -5.5, y: -5.5, width: 11, height: 11, rx: 2 }, g);
      else el("circle", { class: "knob", r: i === 0 || i === n - 1 ? 5 : 6 }, g);
      el("title", {}, g).textContent = label(p, i);
      g.addEventListener("pointerdown", (e) => this._startDrag(e, i));
    });
  }

  setPlayhead(t) {
    this.playT = t;
    const line = this.gDynamic && this.gDynamic.querySelector("#curve-playhead");
    if (line) { const x = this.axis.x(t); line.setAttribute("x1", x); line.setAttribute("x2", x); }
  }
}

export class SpeedPlot {
  constructor(svg, axis) {
    this.svg = svg; this.axis = axis;
    this.top = 8; this.bottom = 22;
    this.data = null;
    this.playT = 0;
    new ResizeObserver(() => this.render()).observe(svg);
  }
  get height() { return this.svg.clientHeight || 120; }
  set(curve, speed, feasibility) { this.data = { curve, speed, feasibility }; this.render(); }

  render() {
    const svg = this.svg, ax = this.axis;
    const W = svg.clientWidth || ax.width, H = this.height;
    svg.setAttribute("viewBox", `0 0 ${W} ${H}`);
    svg.replaceChildren();
    const feas = this.data && this.data.feasibility;
    const strip = feas ? 10 : 0;
    const lo = -3, hi = 3; // log2 speed range shown: 1/8x .. 8x
    const y = (v) => this.top + (1 - (Math.log2(Math.min(Math.max(v, 2 ** lo), 2 ** hi)) - lo) / (hi - lo)) * (H - this.top - this.bottom - strip);
    const grid = el("g", { class: "grid" }, svg), axis = el("g", { class: "axis" }, svg);
    for (const e of [-3, -2, -1, 0, 1, 2, 3]) {
      el("line", { class: e === 0 ? "unit" : "", x1: ax.x(0), x2: ax.x(ax.max), y1: y(2 ** e), y2: y(2 ** e) }, grid);
      el("text", { x: ax.x(0) - 7, y: y(2 ** e) + 4, "text-anchor": "end" }, axis).textContent = e >= 0 ? `${2 ** e}×` : `1/${2 ** -e}`;
    }
    if (this.data) {
      const { curve, speed } = this.data;
      let d = "", area = "";
      const step = Math.max(1, Math.floor(curve.t.length / (2 * W)));
      for (let k = 0; k < curve.t.length; k += step) {
        const X = ax.x(curve.t[k]).toFixed(1), Y = y(speed[k]).toFixed(1);
        d += (k ? "L" : "M") + X + "," + Y;
      }
      area = d + `L${ax.x(curve.t[curve.t.length - 1]).toFixed(1)},${y(1)}L${ax.x(0)},${y(1)}Z`;
      el("path", { class: "speedarea", d: area }, svg);
      el("path", { class: "speedline", d, id: "speed-path" }, svg);
      if (feas) {
        const g = el("g", { class: "feas", id: "feasibility" }, svg);
        const y0 = H - this.bottom - strip + 3;
        const n = feas.length, T = curve.t[curve.t.length - 1];
        // runs of frames with the same (quantized) feasibility become one rectangle each
        const level = (v) => Math.round(Math.min(Math.max(v, 0), 1) * 8) / 8;
        for (let k0 = 0; k0 < n;) {
          const v = level(feas[k0]);
          let k1 = k0 + 1;
          while (k1 < n && level(feas[k1]) === v) k1++;
          const t0 = (k0 / n) * T, t1 = (k1 / n) * T;
          const r = Math.round(229 + (63 - 229) * v), gg = Math.round(83 + (178 - 83) * v), b = Math.round(75 + (127 - 75) * v);
          el("rect", { x: ax.x(t0), y: y0, width: Math.max(0.5, ax.x(t1) - ax.x(t0) + 0.3), height: strip - 3, fill: `rgb(${r},${gg},${b})` }, g);
          k0 = k1;
        }
      }
    }
    const xs = niceStep(ax.max, W / 90);
    for (let t = 0; t <= ax.max + 1e-9; t += xs) el("text", { x: ax.x(t), y: H - 6, "text-anchor": "middle" }, axis).textContent = fmt(t);
    el("line", { class: "playhead", x1: ax.x(this.playT), x2: ax.x(this.playT), y1: this.top, y2: H - this.bottom, id: "speed-playhead" }, svg);
  }

  setPlayhead(t) {
    this.playT = t;
    const line = this.svg.querySelector("#speed-playhead");
    if (line) { const x = this.axis.x(t); line.setAttribute("x1", x); line.setAttribute("x2", x); }
  }
}
