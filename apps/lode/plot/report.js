// The `lode plot` page: draws the report's JSON document (written by apps/lode/plot_html.cpp)
// with uPlot. Long curves arrive as base64 Float32 chunks plus a min/max pyramid; each view
// decodes only what it shows: min/max per pixel bucket when zoomed out (every excursion
// stays visible), the samples themselves once few enough are in view.
'use strict';
(() => {
  const report = JSON.parse(document.getElementById('report-data').textContent);
  const figureOnly = (location.hash.match(/figure=([\w-]+)/) || [])[1];
  const COLORS = ['#1f77b4', '#d62728', '#9467bd', '#ff7f0e', '#8c564b', '#e377c2', '#17becf', '#bcbd22'];
  const EVENT_COLORS = { fault: '#d62728', swap: '#9467bd', health: '#ff7f0e', set: '#2ca02c', param: '#2ca02c' };

  // ---- stored arrays ---------------------------------------------------------------------
  const chunkCache = new Map();
  function decodeBlob(id, Type) {
    const key = id + Type.name;
    let values = chunkCache.get(key);
    if (!values) {
      const text = document.getElementById('b' + id).textContent;
      const binary = atob(text);
      const bytes = new Uint8Array(binary.length);
      for (let i = 0; i < binary.length; ++i) bytes[i] = binary.charCodeAt(i);
      values = new Type(bytes.buffer);
      chunkCache.set(key, values);
    }
    return values;
  }
  /// Values [from, to) of a stored array (plot_html.cpp BlobStore) as numbers, offset added.
  function readStored(stored, from, to, Type = Float32Array) {
    const out = new Float64Array(Math.max(0, to - from));
    const offset = stored.offset || 0;
    for (let c = Math.floor(from / stored.chunk); c * stored.chunk < to; ++c) {
      const chunk = decodeBlob(stored.blobs[c], Type);
      const base = c * stored.chunk;
      const a = Math.max(from, base), b = Math.min(to, base + chunk.length);
      for (let i = a; i < b; ++i) out[i - from] = chunk[i - base] + offset;
    }
    return out;
  }

  // ---- the time grid ---------------------------------------------------------------------
  const grid = report.time;
  const timeAt = grid.samples
    ? (i) => readStored(grid.samples, i, i + 1, Float64Array)[0]
    : (i) => grid.t0 + i * grid.dt;
  function indexAtOrAfter(t) {
    if (!grid.samples) return Math.min(grid.length, Math.max(0, Math.ceil((t - grid.t0) / grid.dt - 1e-9)));
    let lo = 0, hi = grid.length;
    while (lo < hi) { const mid = (lo + hi) >> 1; if (timeAt(mid) < t) lo = mid + 1; else hi = mid; }
    return lo;
  }
  function times(from, to) {
    if (grid.samples) return readStored(grid.samples, from, to, Float64Array);
    const out = new Float64Array(to - from);
    for (let i = from; i < to; ++i) out[i - from] = grid.t0 + i * grid.dt;
    return out;
  }

  /// Samples [from, to) of a curve; an estimation error is its estimate minus the truth.
  const traceByLabel = new Map();
  for (const axis of report.signals) for (const t of axis.traces) traceByLabel.set(`${axis.axis}\n${t.label}`, t);
  function samplesOf(trace, from, to) {
    if (trace.samples) return readStored(trace.samples, from, to);
    const [a, b] = trace.difference.map((label) => traceByLabel.get(`${trace.axis}\n${label}`));
    const x = samplesOf(a, from, to), y = samplesOf(b, from, to);
    for (let i = 0; i < x.length; ++i) x[i] -= y[i];
    return x;
  }
  for (const axis of report.errors) for (const t of axis.traces) t.axis = axis.axis;

  /// What a time plot of `traces` shows between t0 and t1 at `pixels` wide: [x, y1, y2, ...].
  function timeView(traces, scale, t0, t1, pixels) {
    const from = Math.max(0, indexAtOrAfter(t0) - 1);
    const to = Math.min(grid.length, indexAtOrAfter(t1) + 1);
    const n = to - from;
    const levels = traces.length ? traces[0].levels : [];
    const wanted = Math.max(1, n / (2 * pixels));
    const level = n > 3 * pixels ? levels.findIndex((l) => l.bucket >= wanted) : -1;
    const toNumbers = (values) => Array.from(values, (v) => (Number.isFinite(v) ? v * scale : null));
    if (level < 0 && (n <= 3 * pixels || levels.length === 0)) {
      return [Array.from(times(from, to)), ...traces.map((t) => toNumbers(samplesOf(t, from, to)))];
    }
    // Two points per bucket, its minimum then its maximum: a vertical stroke per pixel.
    const chosen = level < 0 ? levels.length - 1 : level;
    const bucket = levels[chosen].bucket;
    const b0 = Math.floor(from / bucket), b1 = Math.ceil(to / bucket);
    const x = [];
    for (let b = b0; b < b1; ++b) {
      x.push(timeAt(b * bucket));
      x.push(timeAt(Math.min(grid.length - 1, b * bucket + (bucket >> 1))));
    }
    const ys = traces.map((t) => {
      const lo = readStored(t.levels[chosen].min, b0, b1), hi = readStored(t.levels[chosen].max, b0, b1);
      const y = new Array(2 * (b1 - b0));
      for (let k = 0; k < b1 - b0; ++k) {
        y[2 * k] = Number.isFinite(lo[k]) ? lo[k] * scale : null;
        y[2 * k + 1] = Number.isFinite(hi[k]) ? hi[k] * scale : null;
      }
      return y;
    });
    return [x, ...ys];
  }

  // ---- markers drawn on every time axis ---------------------------------------------------
  function drawMarkers(u, extra) {
    const ctx = u.ctx, { left, top, width, height } = u.bbox;
    const xpos = (t) => u.valToPos(t, 'x', true);
    ctx.save();
    ctx.beginPath();
    ctx.rect(left, top, width, height);
    ctx.clip();
    const [h0, h1] = report.hold;
    if (h1 > h0) {
      ctx.fillStyle = 'rgba(0,0,0,0.05)';
      ctx.fillRect(xpos(h0), top, xpos(h1) - xpos(h0), height);
    }
    ctx.font = `${10 * devicePixelRatio}px sans-serif`;
    for (const e of report.events) {
      const x = xpos(e.t);
      if (x < left || x > left + width) continue;
      ctx.strokeStyle = EVENT_COLORS[e.kind] || '#888';
      ctx.setLineDash([4 * devicePixelRatio, 3 * devicePixelRatio]);
      ctx.beginPath(); ctx.moveTo(x, top); ctx.lineTo(x, top + height); ctx.stroke();
      ctx.fillStyle = ctx.strokeStyle;
      ctx.fillText(e.kind, x + 3, top + 12 * devicePixelRatio);
    }
    ctx.setLineDash([]);
    ctx.strokeStyle = '#d62728';
    ctx.lineWidth = 2 * devicePixelRatio;
    for (const t of report.overruns) {
      const x = xpos(t);
      ctx.beginPath(); ctx.moveTo(x, top + height); ctx.lineTo(x, top + height - 8 * devicePixelRatio); ctx.stroke();
    }
    if (extra) extra(u, ctx, xpos);
    ctx.restore();
  }

  // ---- time plots: linked zoom and pan ----------------------------------------------------
  const linked = [];
  let syncing = false;
  const fullRange = report.range[1] > report.range[0] ? report.range : [report.range[0], report.range[0] + 1];

  class TimePlot {
    /// view(t0, t1, pixels) -> uPlot data; `home` is the range a double-click returns to.
    constructor(container, { series, view, home, yLabel, link, extraMarks, height = 260 }) {
      this.view = view;
      this.home = home;
      this.link = link;
      const width = Math.max(400, Math.min(1200, container.clientWidth || 1100));
      const opts = {
        width, height,
        series: [{ label: 'time [s]' }, ...series],
        scales: { x: { time: false } },
        axes: [{ label: 'time [s]' }, { label: yLabel, size: 70 }],
        legend: { live: true },
        cursor: {
          drag: { x: true, y: false },
          bind: { dblclick: () => () => { this.zoom(...this.home); return null; } },
        },
        hooks: {
          setSelect: [(u) => {
            if (u.select.width < 3) return;
            const a = u.posToVal(u.select.left, 'x'), b = u.posToVal(u.select.left + u.select.width, 'x');
            u.setSelect({ width: 0, height: 0 }, false);
            this.zoom(a, b);
          }],
          draw: [(u) => drawMarkers(u, extraMarks)],
        },
      };
      opts.cursor.drag.setScale = false;
      this.plot = new uPlot(opts, view(home[0], home[1], width), container);
      this.plot.setScale('x', { min: home[0], max: home[1] });
      this.bindWheelAndPan();
      if (link) linked.push(this);
    }
    zoom(a, b) {
      if (!(b > a)) return;
      if (this.link && !syncing) {
        syncing = true;
        for (const p of linked) p.show(a, b);
        syncing = false;
      } else {
        this.show(a, b);
      }
    }
    show(a, b) {
      const u = this.plot;
      u.batch(() => {
        u.setData(this.view(a, b, u.bbox.width / devicePixelRatio || u.width));
        u.setScale('x', { min: a, max: b });
      });
    }
    bindWheelAndPan() {
      const u = this.plot, over = u.over;
      over.addEventListener('wheel', (e) => {
        e.preventDefault();
        const { min, max } = u.scales.x;
        const at = u.posToVal(e.offsetX, 'x');
        const f = e.deltaY < 0 ? 0.8 : 1.25;
        this.zoom(at - (at - min) * f, at + (max - at) * f);
      }, { passive: false });
      over.addEventListener('mousedown', (e) => {
        if (!e.shiftKey) return;
        e.stopPropagation();
        e.preventDefault();
        const startX = e.clientX, { min, max } = u.scales.x;
        const perPixel = (max - min) / (u.bbox.width / devicePixelRatio);
        const move = (m) => { const d = (m.clientX - startX) * perPixel; this.zoom(min - d, max - d); };
        const up = () => { window.removeEventListener('mousemove', move); window.removeEventListener('mouseup', up); };
        window.addEventListener('mousemove', move);
        window.addEventListener('mouseup', up);
      }, true);
    }
  }

  // ---- page building ----------------------------------------------------------------------
  const element = (tag, attrs = {}, text = '') => {
    const e = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
    if (text) e.textContent = text;
    return e;
  };
  const body = (id) => document.querySelector(`#${id} .body`);
  const figures = new Map(report.figures.map((f) => [f.id, f]));
  /// A figure's container (titled), or null when the page shows another figure alone.
  function figure(section, id) {
    if (figureOnly && figureOnly !== id) return null;
    const f = figures.get(id);
    const box = element('div', { class: 'figure', id: 'figure-' + id });
    box.appendChild(element('div', { class: 'title' }, f ? f.title : id));
    body(section).appendChild(box);
    return box;
  }
  const fmt = (v, digits = 3) => (v === null || v === undefined || Number.isNaN(v) ? '-' : Number(v).toPrecision(digits));
  function table(headers, rows) {
    const t = element('table');
    const head = element('tr');
    headers.forEach((h, i) => head.appendChild(element('th', i === 0 ? { class: 'text' } : {}, h)));
    t.appendChild(head);
    for (const r of rows) {
      const tr = element('tr');
      r.forEach((c, i) => tr.appendChild(element('td', typeof c === 'string' && i === 0 ? { class: 'text' } : {}, String(c))));
      t.appendChild(tr);
    }
    return t;
  }
  const styleOf = (trace, i) => {
    if (trace.role === 'reference') return { stroke: '#000', dash: [6, 4], width: 1.2 };
    if (trace.role === 'truth') return { stroke: '#2ca02c', width: 1.5 };
    return { stroke: COLORS[i % COLORS.length], width: 1 };
  };
  const seriesOf = (traces) => traces.map((t, i) => ({ label: t.label, ...styleOf(t, i), spanGaps: false }));
  const displayOf = (axisName) => {
    const a = report.signals.find((s) => s.axis === axisName);
    return a ? a.display : { scale: 1, unit: '' };
  };

  function axisPlots(section, prefix, axes) {
    if (!axes.length) { body(section).appendChild(element('p', { class: 'empty' }, 'nothing to show')); return; }
    axes.forEach((axis, i) => {
      const box = figure(section, `${prefix}-${i}`);
      if (!box) return;
      const { scale, unit } = axis.display;
      new TimePlot(box, {
        series: seriesOf(axis.traces), home: fullRange, link: true, yLabel: `${axis.axis} [${unit}]`,
        view: (a, b, px) => timeView(axis.traces, scale, a, b, px),
      });
    });
  }

  function stepPlots() {
    if (!report.steps.length) { body('steps').appendChild(element('p', { class: 'empty' }, 'no step in the reference')); return; }
    report.steps.forEach((s, i) => {
      const box = figure('steps', `step-${i}`);
      if (!box) return;
      const axis = report.signals.find((a) => a.axis === s.axis);
      if (!axis) return;
      const { scale, unit } = axis.display;
      const length = s.window_end_s - s.time_s;
      const home = [s.time_s - 0.1 * length, s.window_end_s];
      const final = s.final_reference;
      const marks = (u, ctx, xpos) => {
        const { left, top, width, height } = u.bbox;
        const ypos = (v) => u.valToPos(v * scale, 'y', true);
        if (final !== undefined && final !== null) {
          // The settling band around the final reference.
          ctx.fillStyle = 'rgba(44,160,44,0.12)';
          const hi = ypos(final + s.settling_band), lo = ypos(final - s.settling_band);
          ctx.fillRect(left, hi, width, lo - hi);
          if (s.overshoot_pct > 0) {
            ctx.strokeStyle = '#ff7f0e'; ctx.setLineDash([2, 3]);
            const peak = ypos(final + Math.sign(s.amplitude) * s.overshoot_pct / 100 * Math.abs(s.amplitude));
            ctx.beginPath(); ctx.moveTo(left, peak); ctx.lineTo(left + width, peak); ctx.stroke();
          }
          if (s.steady_state_error !== null) {
            ctx.strokeStyle = '#17becf'; ctx.setLineDash([8, 3]);
            const y = ypos(final + s.steady_state_error);
            ctx.beginPath(); ctx.moveTo(left, y); ctx.lineTo(left + width, y); ctx.stroke();
          }
        }
        ctx.setLineDash([]);
        const vline = (t, color, label) => {
          if (t === null || t === undefined || !Number.isFinite(t)) return;
          const x = xpos(t);
          ctx.strokeStyle = color; ctx.fillStyle = color;
          ctx.beginPath(); ctx.moveTo(x, top); ctx.lineTo(x, top + height); ctx.stroke();
          ctx.fillText(label, x + 3, top + height - 6 * devicePixelRatio);
        };
        vline(s.rise_start_s, '#1f77b4', '10 %');
        if (s.rise_start_s !== null && s.rise_time_s !== null) vline(s.rise_start_s + s.rise_time_s, '#1f77b4', '90 %');
        if (s.settling_time_s !== null) vline(s.time_s + s.settling_time_s, '#2ca02c', 'settled');
      };
      const traces = axis.traces.filter((t) => t.role !== 'error');
      new TimePlot(box, {
        series: seriesOf(traces), home, link: false, yLabel: `${s.axis} [${unit}]`, extraMarks: marks,
        view: (a, b, px) => timeView(traces, scale, a, b, px),
      });
      const ms = (v) => (v === null ? 'never' : (v * 1e3).toFixed(1) + ' ms');
      box.appendChild(element('p', { class: 'marks' },
        `step of ${fmt(s.amplitude * scale)} ${unit} at ${s.time_s.toFixed(3)} s: rise (10-90 %) ${ms(s.rise_time_s)}, ` +
        `overshoot ${fmt(s.overshoot_pct)} % (orange), settling into +-${fmt(s.settling_band * scale)} ${unit} ` +
        `(green band) ${ms(s.settling_time_s)}, steady-state error ${fmt(s.steady_state_error * scale)} ${unit} (cyan)`));
    });
  }

  // Tick labels of a log axis: uPlot's default rounds 1e-15 to "0"; powers of ten far from 1
  // read best as 1e-15.
  const logTicks = (u, splits) => splits.map((v) => (v == null ? '' : (v >= 1e-3 && v < 1e5 ? String(+v.toPrecision(3)) : v.toExponential(0))));

  function spectrumPlots() {
    if (!report.psd.length) { body('psd').appendChild(element('p', { class: 'empty' }, 'hold window too short for a spectrum')); return; }
    report.psd.forEach((axis, i) => {
      const box = figure('psd', `psd-${i}`);
      if (!box) return;
      const { scale, unit } = displayOf(axis.axis);
      // Traces of one axis share the segment length, so one frequency vector serves all.
      const f = axis.traces[0].frequency_hz;
      const data = [f, ...axis.traces.map((t) => t.density.map((v) => (v === null || v <= 0 ? null : v * scale * scale)))];
      new uPlot({
        width: Math.min(1200, box.clientWidth || 1100), height: 280,
        series: [{ label: 'f [Hz]' }, ...axis.traces.map((t, k) => ({
          label: `${t.label} (${t.segments} segments)`, stroke: t.label.endsWith('.truth') || k === 0 ? '#2ca02c' : COLORS[k % COLORS.length], width: 1 }))],
        scales: { x: { time: false, distr: 3 }, y: { distr: 3 } },
        axes: [{ label: 'frequency [Hz]', values: logTicks }, { label: `${axis.axis} [${unit}²/Hz]`, size: 80, values: logTicks }],
      }, data, box);
    });
  }

  function histogramPlot(box, title, histogram) {
    const holder = element('div');
    box.appendChild(holder);
    if (!histogram || !histogram.count) {
      holder.appendChild(element('p', { class: 'empty' }, `${title}: no samples` +
        (title.startsWith('wake') ? ' (the simulated clock does not wake up)' : '')));
      return;
    }
    // Only the bins that counted something are recorded. Each is drawn over its own width (the
    // recorder's histogram has 32 bins per octave: width 1 ns up to 64 ns, then 1/32 of the
    // octave), with a break before it when the bin below it counted nothing, so that a rare
    // outlier is a short step far out, not a line joining it to the bulk.
    const widthNs = (e) => (e <= 64 ? 1 : 2 ** (Math.floor(Math.log2(e - 1)) - 5));
    const edges = [], counts = [];
    let previous = null;
    histogram.upper_edge_ns.forEach((e, i) => {
      const lower = e - widthNs(e);
      if (previous === null || lower > previous) { edges.push(lower / 1e3); counts.push(null); }
      edges.push(e / 1e3);
      counts.push(histogram.count_per_bin[i]);
      previous = e;
    });
    new uPlot({
      width: 380, height: 200, title,
      series: [{ label: 'us' }, { label: 'cycles', stroke: '#1f77b4', fill: 'rgba(31,119,180,0.3)',
        paths: uPlot.paths.stepped({ align: 1 }),
        // A dot on each bin with empty bins on both sides: a lone outlier is one bin wide.
        points: { show: true, size: 5, fill: '#1f77b4',
          filter: () => counts.flatMap((c, k) => (c !== null && counts[k - 1] === null && (k + 1 >= counts.length || counts[k + 1] === null) ? [k] : [])) } }],
      // From 0.5, so that a bin of one cycle (often the maximum) stands above the axis.
      scales: { x: { time: false, distr: 3 }, y: { distr: 3, range: (u, min, max) => [0.5, Math.max(2, max) * 1.5] } },
      axes: [{ label: 'time [us]', values: logTicks }, { label: 'cycles', values: logTicks }],
    }, [edges, counts], holder);
  }

  function timingPlots() {
    const t = report.timing;
    if (!t) { body('timing').appendChild(element('p', { class: 'empty' }, 'this recording holds no timing (lode record, or a recording made before timing was recorded)')); return; }
    let box = figure('timing', 'timing-latency');
    if (box) {
      const row = element('div', { class: 'small-multiples' });
      box.appendChild(row);
      histogramPlot(row, 'wake-up latency', t.wake_latency);
      histogramPlot(row, 'whole cycle', t.cycle_time);
    }
    box = figure('timing', 'timing-blocks');
    if (box) {
      const row = element('div', { class: 'small-multiples' });
      box.appendChild(row);
      for (const [label, h] of Object.entries(t.block_exec_time)) histogramPlot(row, label, h);
    }
    box = figure('timing', 'timing-overruns');
    if (box) {
      // Cumulative overruns against time: a step per overrun (the run logs the last ones).
      const at = report.overruns;
      const xs = [fullRange[0], ...at, fullRange[1]];
      const ys = [0, ...at.map((_, k) => k + 1), at.length];
      new TimePlot(box, {
        series: [{ label: 'overruns so far', stroke: '#d62728', width: 1.5, paths: uPlot.paths.stepped({ align: 1 }) }],
        home: fullRange, link: true, yLabel: 'overruns', height: 180,
        view: () => [xs, ys],
      });
      box.appendChild(element('p', { class: 'marks' }, `${t.overruns} overruns, ${t.missed_periods} missed periods in ` +
        `${t.cycles} cycles` + (t.overruns > at.length ? ` (the times of the last ${at.length} are kept)` : '')));
    }
  }

  function summaryTables() {
    const root = body('summary');
    if (figureOnly) { document.getElementById('summary').classList.add('hidden-for-figure'); }
    root.appendChild(element('h3', {}, 'Recordings'));
    root.appendChild(table(['file', 'source', 'pipeline', 'cycles', 'rate [Hz]', 'output digest'],
      report.files.map((f) => [f.label, f.source || '-', f.pipeline || '-', f.cycles ?? '-', f.rate_hz ?? '-',
        f.output_digest || f.recording_partial || '-'])));
    const s = report.summary || {};
    const noise = s.position_noise;
    if (noise) {
      root.appendChild(element('h3', {}, `Position noise (std) in the hold window [${noise.window_s.map((v) => v.toFixed(2)).join(', ')}] s`));
      const rows = [];
      for (const [who, stats] of Object.entries(noise))
        if (who !== 'window_s') for (const [axis, a] of Object.entries(stats)) {
          const { scale, unit } = displayOf(axis);
          rows.push([who, axis, `${fmt(a.std * scale)} ${unit}`, a.samples]);
        }
      root.appendChild(table(['series', 'axis', 'std', 'samples'], rows));
    }
    root.appendChild(element('h3', {}, 'Estimation error per estimator (from the hold window on)'));
    root.appendChild(report.error_table.length ? table(['estimator', 'how found', 'axis', 'bias', 'rms', 'max |e|', 'std in hold'],
      report.error_table.map((e) => {
        const { scale, unit } = displayOf(e.axis);
        const v = (x) => `${fmt(x === null ? null : x * scale)} ${unit}`;
        return [e.estimator, e.detail, e.axis, v(e.bias), v(e.rms), v(e.max_abs), v(e.hold_std)];
      })) : element('p', { class: 'empty' }, 'no truth to compare with'));
    if (s.tracking_error) {
      root.appendChild(element('h3', {}, 'Tracking error (reference - truth)'));
      root.appendChild(table(['axis', 'rms', 'max |e|'], Object.entries(s.tracking_error).map(([axis, a]) => {
        const { scale, unit } = displayOf(axis);
        return [axis, `${fmt(a.rms * scale)} ${unit}`, `${fmt(a.max_abs * scale)} ${unit}`];
      })));
    }
    if (report.steps.length) {
      root.appendChild(element('h3', {}, 'Step responses'));
      const ms = (v) => (v === null ? 'never' : (v * 1e3).toFixed(1));
      root.appendChild(table(['axis', 'at [s]', 'step', 'rise [ms]', 'overshoot [%]', 'settling [ms]', 'band', 'steady-state error'],
        report.steps.map((st) => {
          const { scale, unit } = displayOf(st.axis);
          return [st.axis, st.time_s.toFixed(3), `${fmt(st.amplitude * scale)} ${unit}`, ms(st.rise_time_s),
            fmt(st.overshoot_pct), ms(st.settling_time_s), `+-${fmt(st.settling_band * scale)} ${unit}`,
            `${fmt(st.steady_state_error * scale)} ${unit}`];
        })));
    }
    const t = report.timing;
    if (t) {
      root.appendChild(element('h3', {}, `Timing: ${t.cycles} cycles, ${t.overruns} overruns, ${t.missed_periods} missed periods`));
      const rows = [['wake-up latency', t.wake_latency], ['whole cycle', t.cycle_time], ...Object.entries(t.block_exec_time)]
        .filter(([, h]) => h && h.count)
        .map(([name, h]) => [name, h.count, fmt(h.summary_us.p50_us), fmt(h.summary_us.p99_us), fmt(h.summary_us.p999_us), fmt(h.summary_us.max_us)]);
      root.appendChild(table(['what', 'count', 'p50 [us]', 'p99 [us]', 'p99.9 [us]', 'max [us]'], rows));
      const timed = Object.values(t.block_exec_time).map((h) => (h ? h.count : 0));
      if (timed.length && Math.max(...timed) < t.executed)
        root.appendChild(element('p', { class: 'marks' }, `The blocks were timed in ${Math.max(...timed)} of the ` +
          `${t.executed} cycles run (a simulated run times one cycle in 64): their percentiles come from those.`));
    }
  }

  function textSections() {
    const events = body('events');
    events.appendChild(report.events.length
      ? table(['time [s]', 'cycle', 'kind', 'text'], report.events.map((e) => [e.t.toFixed(4), e.cycle, e.kind, e.text]))
      : element('p', { class: 'empty' }, 'no events'));
    const notes = body('notes');
    if (report.notes.length) for (const n of report.notes) notes.appendChild(element('p', {}, n));
    else notes.appendChild(element('p', { class: 'empty' }, 'none'));
    body('config').appendChild(element('pre', {}, report.config || '(no configuration recorded)'));
    const toc = document.getElementById('toc');
    for (const s of document.querySelectorAll('section'))
      toc.appendChild(element('a', { href: '#' + s.id }, s.querySelector('h2').textContent.split(' ')[0]));
  }

  if (figureOnly) {
    document.body.classList.add('one-figure');
    for (const s of document.querySelectorAll('section')) s.classList.add('hidden-for-figure');
  }
  summaryTables();
  axisPlots('signals', 'signals', report.signals);
  axisPlots('errors', 'errors', report.errors);
  stepPlots();
  spectrumPlots();
  timingPlots();
  textSections();
  if (figureOnly) {
    const shown = document.getElementById('figure-' + figureOnly);
    if (shown) shown.closest('section').classList.remove('hidden-for-figure');
  }
  window.lodeReport = {
    ready: true,
    figures: report.figures.length,
    drawn: document.querySelectorAll('.figure').length,
    sections: Array.from(document.querySelectorAll('section')).map((s) => s.id),
    decodedChunks: () => chunkCache.size,
    /// Zooms every linked plot to [a, b] as a drag would; returns how long it took (ms).
    zoom: (a, b) => { const t0 = performance.now(); if (linked.length) linked[0].zoom(a, b); return performance.now() - t0; },
  };
})();
