// Line plots on a 2D canvas: the run's per-step stats beside the animation, and the convergence traces of
// `mgcloth bench convergence`. Small on purpose: no chart library to ship.

export const PALETTE = ['#1f77b4', '#ff7f0e', '#2ca02c', '#d62728', '#9467bd', '#8c564b', '#e377c2', '#7f7f7f',
                        '#bcbd22', '#17becf'];

function niceStep(range, target) {
  const raw = range / Math.max(1, target);
  const p = 10 ** Math.floor(Math.log10(raw));
  for (const m of [1, 2, 2.5, 5, 10]) if (m * p >= raw) return m * p;
  return 10 * p;
}

function formatTick(v, step) {
  if (v === 0) return '0';
  const a = Math.abs(v);
  if (a >= 1e5 || a < 1e-3) return v.toExponential(1).replace('e+', 'e').replace('.0e', 'e');
  const mantissa = step / 10 ** Math.floor(Math.log10(step));
  const decimals = -Math.floor(Math.log10(step)) + (Math.abs(mantissa - 2.5) < 1e-9 ? 1 : 0);
  return v.toFixed(Math.min(Math.max(decimals, 0), 6));
}

export class LinePlot {
  /**
   * @param {HTMLCanvasElement} canvas
   * @param {{title?: string, xLabel?: string, yLabel?: string, logY?: boolean, floor?: number,
   *          hLines?: number[], markers?: boolean, onPick?: (x: number) => void}} options
   */
  constructor(canvas, options = {}) {
    this.canvas = canvas;
    this.options = options;
    this.series = [];
    this.marker = null;
    this.view = null;
    if (options.onPick) {
      canvas.addEventListener('click', (e) => {
        if (!this.view) return;
        const r = canvas.getBoundingClientRect();
        const { x0, x1, left, width } = this.view;
        options.onPick(x0 + ((e.clientX - r.left - left) / width) * (x1 - x0));
      });
    }
  }

  /** @param {{name: string, x: number[], y: number[], color?: string}[]} series */
  setSeries(series) {
    this.series = series;
    this.draw();
  }

  setMarker(x) {
    this.marker = x;
    this.draw();
  }

  draw() {
    const c = this.canvas, o = this.options;
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, c.clientWidth), h = Math.max(1, c.clientHeight);
    if (c.width !== Math.round(w * dpr) || c.height !== Math.round(h * dpr)) {
      c.width = Math.round(w * dpr);
      c.height = Math.round(h * dpr);
    }
    const g = c.getContext('2d');
    g.setTransform(dpr, 0, 0, dpr, 0, 0);
    g.clearRect(0, 0, w, h);
    g.fillStyle = '#fff';
    g.fillRect(0, 0, w, h);
    const font = Math.max(10, Math.min(14, h / 16));
    g.font = `${font}px system-ui, sans-serif`;

    const floor = o.floor ?? 1e-16;
    const fy = o.logY ? (v) => Math.log10(Math.max(v, floor)) : (v) => v;
    let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
    for (const s of this.series) {
      for (let i = 0; i < s.x.length; ++i) {
        const x = s.x[i], y = s.y[i];
        if (!Number.isFinite(x) || !Number.isFinite(y) || (o.logY && !(y > 0))) continue;
        x0 = Math.min(x0, x); x1 = Math.max(x1, x);
        const v = fy(y);
        y0 = Math.min(y0, v); y1 = Math.max(y1, v);
      }
    }
    if (!Number.isFinite(x0)) { x0 = 0; x1 = 1; y0 = 0; y1 = 1; }
    if (o.xMin !== undefined) x0 = Math.min(x0, o.xMin);
    if (x1 === x0) x1 = x0 + 1;
    if (o.logY) {
      for (const l of o.hLines || []) { y0 = Math.min(y0, Math.log10(l)); y1 = Math.max(y1, Math.log10(l)); }
      // A fifth of a decade beyond the data, not a whole one: the curves use the height.
      y0 -= 0.2; y1 += 0.2;
    } else {
      if (y1 === y0) { y0 -= Math.abs(y0) * 0.1 || 1; y1 += Math.abs(y1) * 0.1 || 1; }
      const pad = (y1 - y0) * 0.06;
      y0 -= pad; y1 += pad;
    }

    const left = 8 + g.measureText('−0.000e-00').width * 0.75, right = 12;
    const top = (o.title ? font * 1.9 : font * 0.8), bottom = font * (o.xLabel ? 3.2 : 1.8);
    const width = Math.max(1, w - left - right), height = Math.max(1, h - top - bottom);
    this.view = { x0, x1, left, width };
    const px = (x) => left + ((x - x0) / (x1 - x0)) * width;
    const py = (v) => top + (1 - (v - y0) / (y1 - y0)) * height;

    // Grid and ticks.
    g.strokeStyle = '#e6e6e6';
    g.fillStyle = '#444';
    g.lineWidth = 1;
    g.textAlign = 'right';
    g.textBaseline = 'middle';
    if (o.logY) {
      const every = Math.max(1, Math.ceil((y1 - y0) / 8));
      for (let e = Math.ceil(y0); e <= y1; ++e) {
        if ((e - Math.ceil(y0)) % every) continue;
        const y = py(e);
        g.beginPath(); g.moveTo(left, y); g.lineTo(left + width, y); g.stroke();
        g.fillText(`1e${e}`, left - 5, y);
      }
    } else {
      const step = niceStep(y1 - y0, Math.max(3, Math.floor(height / (font * 2.2))));
      for (let v = Math.ceil(y0 / step) * step; v <= y1 + step * 1e-9; v += step) {
        const y = py(v);
        g.beginPath(); g.moveTo(left, y); g.lineTo(left + width, y); g.stroke();
        g.fillText(formatTick(Math.abs(v) < step * 1e-9 ? 0 : v, step), left - 5, y);
      }
    }
    g.textAlign = 'center';
    g.textBaseline = 'top';
    const xs = niceStep(x1 - x0, Math.max(2, Math.floor(width / (font * 6))));
    for (let v = Math.ceil(x0 / xs) * xs; v <= x1 + xs * 1e-9; v += xs) {
      const x = px(v);
      g.beginPath(); g.moveTo(x, top); g.lineTo(x, top + height); g.stroke();
      g.fillText(formatTick(Math.abs(v) < xs * 1e-9 ? 0 : v, xs), x, top + height + 4);
    }
    g.strokeStyle = '#999';
    g.strokeRect(left, top, width, height);

    // Reference levels (e.g. relative errors 1e-2, 1e-3, 1e-4).
    g.setLineDash([5, 4]);
    g.strokeStyle = '#bbb';
    for (const l of o.hLines || []) {
      const y = py(fy(l));
      g.beginPath(); g.moveTo(left, y); g.lineTo(left + width, y); g.stroke();
    }
    g.setLineDash([]);

    // Series.
    g.save();
    g.beginPath();
    g.rect(left, top, width, height);
    g.clip();
    this.series.forEach((s, k) => {
      const color = s.color || PALETTE[k % PALETTE.length];
      g.strokeStyle = color;
      g.fillStyle = color;
      g.lineWidth = 1.8;
      g.beginPath();
      let pen = false;
      for (let i = 0; i < s.x.length; ++i) {
        if (!Number.isFinite(s.x[i]) || !Number.isFinite(s.y[i])) { pen = false; continue; }
        const X = px(s.x[i]), Y = py(fy(s.y[i]));
        if (pen) g.lineTo(X, Y); else g.moveTo(X, Y);
        pen = true;
      }
      g.stroke();
      if (o.markers) {
        const every = Math.max(1, Math.floor(s.x.length / 40));
        for (let i = 0; i < s.x.length; i += every) {
          if (!Number.isFinite(s.y[i])) continue;
          g.beginPath();
          g.arc(px(s.x[i]), py(fy(s.y[i])), 2.6, 0, 2 * Math.PI);
          g.fill();
        }
      }
    });
    if (this.marker !== null && Number.isFinite(this.marker)) {
      g.strokeStyle = '#d62728';
      g.lineWidth = 1.5;
      const x = px(this.marker);
      g.beginPath(); g.moveTo(x, top); g.lineTo(x, top + height); g.stroke();
    }
    g.restore();

    // Labels, title, legend.
    g.fillStyle = '#222';
    if (o.title) {
      g.font = `600 ${font}px system-ui, sans-serif`;
      g.textAlign = 'center';
      g.textBaseline = 'top';
      g.fillText(o.title, left + width / 2, font * 0.4);
      g.font = `${font}px system-ui, sans-serif`;
    }
    if (o.xLabel) {
      g.textAlign = 'center';
      g.textBaseline = 'bottom';
      g.fillText(o.xLabel, left + width / 2, h - 3);
    }
    if (o.yLabel) {
      g.save();
      g.translate(font * 0.9, top + height / 2);
      g.rotate(-Math.PI / 2);
      g.textAlign = 'center';
      g.textBaseline = 'middle';
      g.fillText(o.yLabel, 0, 0);
      g.restore();
    }
    if (this.series.length > 1) {
      const lw = Math.max(...this.series.map((s) => g.measureText(s.name).width)) + font * 2.6;
      const lh = font * 1.3, lx = left + width - lw - 6, ly = top + 6;
      g.fillStyle = 'rgba(255,255,255,0.85)';
      g.fillRect(lx, ly, lw, lh * this.series.length + 6);
      g.strokeStyle = '#ccc';
      g.strokeRect(lx, ly, lw, lh * this.series.length + 6);
      g.textAlign = 'left';
      g.textBaseline = 'middle';
      this.series.forEach((s, k) => {
        const y = ly + 3 + lh * (k + 0.5);
        g.strokeStyle = g.fillStyle = s.color || PALETTE[k % PALETTE.length];
        g.lineWidth = 2;
        g.beginPath(); g.moveTo(lx + 6, y); g.lineTo(lx + font * 1.8, y); g.stroke();
        g.fillStyle = '#222';
        g.fillText(s.name, lx + font * 2.2, y);
      });
    }
  }
}

/** Parses a CSV with a header line into {columns, rows}; fields are not quoted in mgcloth's files. */
export function parseCsv(text) {
  const lines = text.split(/\r?\n/).filter((l) => l.length > 0);
  if (lines.length === 0) return { columns: [], rows: [] };
  const columns = lines[0].split(',');
  const rows = lines.slice(1).map((l) => {
    const f = l.split(',');
    const r = {};
    columns.forEach((c, i) => { r[c] = f[i]; });
    return r;
  });
  return { columns, rows };
}
