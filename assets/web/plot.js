// A small strip chart on a canvas: a few series over the last points, autoscaled, redrawn at most
// once an animation frame. No library: the page works offline.
'use strict';

const PLOT_COLOURS = ['#4ea1ff', '#ffb347', '#6bd48c', '#ff6b6b', '#c792ea', '#f78c6c', '#89ddff', '#ffcb6b'];

class Plot {
  // names: one per series; options: {capacity, stacked, log, unit}
  constructor(canvas, legend, options = {}) {
    this.canvas = canvas;
    this.legend = legend;
    this.capacity = options.capacity || 300;
    this.stacked = !!options.stacked;
    this.names = [];
    this.xs = [];
    this.ys = [];  // ys[k][i]
    this.pending = false;
    this.cursor = null;  // the timeline's shown time [s]: a vertical line, null for none
  }

  setCursor(x) {
    if (x === this.cursor) return;
    this.cursor = x;
    this.request();
  }

  setSeries(names) {
    if (names.join('|') === this.names.join('|')) return;
    this.names = names;
    this.clear();
    this.legend.innerHTML = '';
    names.forEach((n, k) => {
      const s = document.createElement('span');
      s.style.color = PLOT_COLOURS[k % PLOT_COLOURS.length];
      s.textContent = n;
      this.legend.appendChild(s);
    });
  }

  clear() {
    this.xs = [];
    this.ys = this.names.map(() => []);
    this.request();
  }

  push(x, values) {
    if (this.xs.length && x < this.xs[this.xs.length - 1]) this.clear();  // time went back: a reset
    this.xs.push(x);
    values.forEach((v, k) => this.ys[k] && this.ys[k].push(Number.isFinite(v) ? v : NaN));
    if (this.xs.length > this.capacity) {
      this.xs.shift();
      this.ys.forEach((y) => y.shift());
    }
    this.request();
  }

  request() {
    if (this.pending) return;
    this.pending = true;
    requestAnimationFrame(() => {
      this.pending = false;
      this.draw();
    });
  }

  draw() {
    const c = this.canvas, g = c.getContext('2d');
    const w = c.width, h = c.height, left = 46, bottom = 18, top = 6, right = 6;
    g.clearRect(0, 0, w, h);
    g.lineWidth = 1;
    g.font = '11px system-ui, sans-serif';
    g.fillStyle = '#8b95a1';
    g.strokeStyle = '#333a43';
    g.strokeRect(left, top, w - left - right, h - top - bottom);
    const n = this.xs.length;
    if (n < 2) return;
    // Stacked: the series add up (stages of a step).
    const rows = this.ys.map((y) => y.slice());
    if (this.stacked)
      for (let k = 1; k < rows.length; ++k) rows[k] = rows[k].map((v, i) => (rows[k - 1][i] || 0) + (v || 0));
    // The range: from 0 (or below, for energies measured from the start) to a round maximum.
    let ymax = 0, ymin = 0;
    rows.forEach((y) => y.forEach((v) => {
      if (Number.isFinite(v)) { ymax = Math.max(ymax, v); ymin = Math.min(ymin, v); }
    }));
    if (ymax <= 0 && ymin >= 0) ymax = 1;
    ymax = ymax > 0 ? niceCeil(ymax) : 0;
    ymin = ymin < 0 ? -niceCeil(-ymin) : 0;
    const x0 = this.xs[0], x1 = this.xs[n - 1], span = Math.max(x1 - x0, 1e-9);
    const px = (x) => left + ((x - x0) / span) * (w - left - right);
    const py = (y) => h - bottom - ((y - ymin) / (ymax - ymin)) * (h - top - bottom);
    g.fillText(fmt(ymax), 2, top + 9);
    g.fillText(fmt(ymin), 2, h - bottom);
    if (ymin < 0) {
      g.fillText('0', 2, py(0) + 4);
      g.beginPath();
      g.moveTo(left, py(0));
      g.lineTo(w - right, py(0));
      g.stroke();
    }
    g.fillText(`${x0.toFixed(1)} s`, left, h - 4);
    const end = `${x1.toFixed(1)} s`;
    g.fillText(end, w - right - g.measureText(end).width, h - 4);
    for (let k = rows.length - 1; k >= 0; --k) {
      const colour = PLOT_COLOURS[k % PLOT_COLOURS.length];
      g.beginPath();
      let pen = false;
      rows[k].forEach((v, i) => {
        if (!Number.isFinite(v)) { pen = false; return; }
        const X = px(this.xs[i]), Y = py(Math.max(ymin, Math.min(v, ymax)));
        if (pen) g.lineTo(X, Y); else g.moveTo(X, Y);
        pen = true;
      });
      if (this.stacked) {
        g.lineTo(px(x1), py(Math.max(0, ymin)));
        g.lineTo(px(x0), py(Math.max(0, ymin)));
        g.closePath();
        g.fillStyle = colour + '99';
        g.fill();
      } else {
        g.strokeStyle = colour;
        g.lineWidth = 1.5;
        g.stroke();
      }
    }
    if (this.cursor !== null && this.cursor >= x0 && this.cursor <= x1) {
      g.strokeStyle = '#ffffff';
      g.lineWidth = 1;
      g.setLineDash([3, 3]);
      g.beginPath();
      g.moveTo(Math.round(px(this.cursor)) + 0.5, top);
      g.lineTo(Math.round(px(this.cursor)) + 0.5, h - bottom);
      g.stroke();
      g.setLineDash([]);
    }
  }
}

function niceCeil(v) {
  const e = Math.pow(10, Math.floor(Math.log10(v)));
  for (const m of [1, 2, 2.5, 5, 10]) if (m * e >= v) return m * e;
  return 10 * e;
}

function fmt(v) {
  if (v === 0) return '0';
  if (Math.abs(v) >= 1000 || Math.abs(v) < 0.01) return v.toExponential(0);
  return String(+v.toPrecision(3));
}
