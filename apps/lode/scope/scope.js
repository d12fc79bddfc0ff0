// lode scope's page: samples arrive as Server-Sent Events from the lode process that served
// it (one `samples` message per batch period, each topic's rows as base64 float64: cycle,
// stamp [s], values), are merged into one table keyed by cycle, and drawn with uPlot once
// per animation frame. Commands go back as JSON POSTs; their replies and the pipeline's
// events are listed as they come.
'use strict';

// The token (when the server asks for one) came in this page's address: every request the
// page makes carries it, so a reconnecting stream works even if the cookie is refused.
const token = new URLSearchParams(location.search).get('token');
const api = (path) => (token ? `${path}${path.includes('?') ? '&' : '?'}token=${encodeURIComponent(token)}` : path);
const $ = (id) => document.getElementById(id);

// ---------------------------------------------------------------------------------------------
// The table: rows keyed by cycle, one column per element of every watched topic. Every array
// is twice the capacity and each row is written at i and i + CAPACITY, so any run of up to
// CAPACITY consecutive rows is one contiguous subarray that uPlot can draw without a copy.

const CAPACITY = 1 << 16;  // 65 s at 1 kHz: the longest window plus pre-trigger history
const table = {
  rows: 0,  // rows ever appended; the live ones are [rows - live, rows)
  cycles: new Float64Array(2 * CAPACITY),
  time: new Float64Array(2 * CAPACITY),
  columns: new Map(),  // "topic#k" -> {values: Float64Array, seen: bool}
  lastCycle: -1,
};
const live = () => Math.min(table.rows, CAPACITY);
const slot = (row) => row % CAPACITY;

function column(key) {
  let c = table.columns.get(key);
  if (!c) {
    c = { values: new Float64Array(2 * CAPACITY), seen: false };
    table.columns.set(key, c);
  }
  return c;
}

function resetTable() {
  table.rows = 0;
  table.lastCycle = -1;
  table.columns.clear();
}

function appendRow(cycle, time) {
  const i = slot(table.rows);
  const previous = slot(table.rows + CAPACITY - 1);
  table.cycles[i] = table.cycles[i + CAPACITY] = cycle;
  table.time[i] = table.time[i + CAPACITY] = time;
  // A topic slower than the others holds its last value (a NaN would poison uPlot's ranges).
  for (const c of table.columns.values()) c.values[i] = c.values[i + CAPACITY] = c.values[previous];
  table.lastCycle = cycle;
  return table.rows++;
}

/// The row of `cycle` among the recent ones (binary search), or -1.
function findRow(cycle) {
  let lo = table.rows - live(), hi = table.rows - 1;
  while (lo <= hi) {
    const mid = (lo + hi) >> 1, c = table.cycles[slot(mid)];
    if (c === cycle) return mid;
    if (c < cycle) lo = mid + 1; else hi = mid - 1;
  }
  return -1;
}

function setValue(row, key, value) {
  const c = column(key), i = slot(row);
  if (!c.seen) {
    // First sample of this column: fill the rows before it so the plot starts flat, not at 0.
    c.seen = true;
    c.values.fill(value);
  }
  c.values[i] = c.values[i + CAPACITY] = value;
}

// Topics arrive in separate listener threads: a row is only final once every topic that
// is flowing has reached its cycle. Samples wait per topic until then (the watermark).
const pendingByTopic = new Map();  // topic -> {rows: [Float64Array...], lastCycle, arrived}
// samples and lastCycle per topic: what arrived, and the newest cycle among it.
const stats = { samples: {}, lastCycle: {}, batches: 0, late: 0, redraws: 0, started: performance.now() };

function receiveSamples(message) {
  const now = performance.now();
  for (const t of message.topics) {
    const meta = state.byTopic.get(t.topic);
    if (!meta || meta.pipeline !== state.pipeline) continue;
    const bytes = Uint8Array.from(atob(t.data), (ch) => ch.charCodeAt(0));
    const rows = new Float64Array(bytes.buffer);
    let p = pendingByTopic.get(t.topic);
    if (!p) pendingByTopic.set(t.topic, (p = { queue: [], lastCycle: -1, arrived: now }));
    for (let r = 0; r < t.rows; ++r) p.queue.push(rows.subarray(r * t.width, (r + 1) * t.width));
    p.lastCycle = rows[(t.rows - 1) * t.width];
    p.arrived = now;
    stats.samples[t.topic] = (stats.samples[t.topic] || 0) + t.rows;
    stats.lastCycle[t.topic] = p.lastCycle;
  }
  ++stats.batches;
  mergePending(now);
}

function mergePending(now) {
  let watermark = Infinity;
  for (const p of pendingByTopic.values())
    if (now - p.arrived < 500) watermark = Math.min(watermark, p.lastCycle);  // a stopped topic holds no one back
  const heads = [...pendingByTopic.entries()].filter(([, p]) => p.queue.length);
  const index = new Map(heads.map(([topic]) => [topic, 0]));
  for (;;) {
    let best = null, bestCycle = Infinity;
    for (const [topic, p] of heads) {
      const k = index.get(topic);
      if (k < p.queue.length && p.queue[k][0] < bestCycle) { bestCycle = p.queue[k][0]; best = topic; }
    }
    if (best === null || bestCycle > watermark) break;
    const k = index.get(best);
    insertSample(best, pendingByTopic.get(best).queue[k]);
    index.set(best, k + 1);
  }
  for (const [topic, p] of heads) p.queue.splice(0, index.get(topic));
}

function insertSample(topic, row) {
  const cycle = row[0];
  let r;
  if (cycle > table.lastCycle) r = appendRow(cycle, row[1]);
  else if ((r = findRow(cycle)) < 0) { ++stats.late; return; }
  for (let k = 2; k < row.length; ++k) setValue(r, `${topic}#${k - 2}`, row[k]);
  if (trigger.armed) checkTrigger(r);
}

// ---------------------------------------------------------------------------------------------
// Signals, selection, plot

const state = {
  signals: [], byTopic: new Map(), pipeline: null, selected: [], paused: false,
  lastStamp: null, lastArrival: 0, frozen: null, cursorA: null, cursorB: null, heldRanges: {},
};
let chart = null;
const PALETTE = ['#1f77b4', '#d62728', '#2ca02c', '#9467bd', '#ff7f0e', '#17becf', '#8c564b', '#e377c2',
                 '#7f7f7f', '#bcbd22', '#393b79', '#637939'];

function onSignals(list) {
  state.signals = list;
  state.byTopic = new Map(list.map((s) => [s.topic, s]));
  const pipelines = [...new Set(list.map((s) => s.pipeline))].sort();
  const select = $('pipeline');
  if (select.options.length !== pipelines.length || pipelines.some((p, i) => select.options[i].value !== p)) {
    select.replaceChildren(...pipelines.map((p) => new Option(p, p)));
    if (state.pipeline && pipelines.includes(state.pipeline)) select.value = state.pipeline;
  }
  if (!state.pipeline && pipelines.length) choosePipeline(pipelines[0]);
  else renderSignalList();
}

function choosePipeline(pipeline) {
  state.pipeline = pipeline;
  $('pipeline').value = pipeline;
  state.selected = [];
  resetTable();
  pendingByTopic.clear();
  renderSignalList();
  rebuildChart();
  watchShadows();
  loadParameters();
}

function renderSignalList() {
  const topics = state.signals.filter((s) => s.pipeline === state.pipeline);
  const list = $('signal-list');
  const known = new Set([...list.querySelectorAll('input')].map((i) => i.dataset.key));
  const keys = topics.flatMap((s) => s.names.map((n, k) => `${s.topic}#${k}`));
  if (keys.length === known.size && keys.every((k) => known.has(k))) return;
  list.replaceChildren(...topics.map((s) => {
    const div = document.createElement('div');
    div.className = 'topic';
    div.innerHTML = `<div class="name" title="${s.topic}">${s.block}.${s.port} <span class="unit">${s.rate_hz} Hz</span></div>`;
    s.names.forEach((name, k) => {
      const label = document.createElement('label');
      const box = document.createElement('input');
      box.type = 'checkbox';
      box.dataset.key = `${s.topic}#${k}`;
      box.checked = state.selected.some((x) => x.key === box.dataset.key);
      box.addEventListener('change', () => toggleSignal(s, k, box.checked));
      const unit = s.units[k] && s.units[k] !== '1' ? ` [${s.units[k]}]` : '';
      label.append(box, ` ${name}`, Object.assign(document.createElement('span'), { className: 'unit', textContent: unit }));
      div.append(label);
    });
    return div;
  }));
}

async function watch(topics) {
  const r = await post('/api/watch', { topics });
  if (!r.ok) addReply({ kind: 'watch' }, { ok: false, message: r.errors.join('; ') });
}

function toggleSignal(meta, k, on) {
  const key = `${meta.topic}#${k}`;
  state.selected = state.selected.filter((s) => s.key !== key);
  if (on) {
    // block.port.element: a shadow's pose and disagreement have the same element names.
    state.selected.push({ key, topic: meta.topic, label: `${meta.block}.${meta.port}.${meta.names[k]}`, unit: meta.units[k] || '' });
    watch([meta.topic]);
  }
  rebuildChart();
}

function rebuildChart() {
  const source = $('trigger-source');
  const previous = source.value;
  source.replaceChildren(...state.selected.map((s) => new Option(s.label, s.key)));
  if (state.selected.some((s) => s.key === previous)) source.value = previous;
  if (chart) chart.destroy();
  chart = null;
  if (!state.selected.length) return;
  const units = [...new Set(state.selected.map((s) => s.unit || '1'))];
  const scales = { x: { time: false } };
  for (const u of units) scales[u] = { range: (self, min, max) => yRange(self, min, max, u) };
  const axes = [{ label: 's' }, ...units.slice(0, 2).map((u, i) => ({
    scale: u, label: u, side: i ? 1 : 3, grid: { show: i === 0 }, size: 70, values: tickLabels }))];
  const plot = $('plot');
  chart = new uPlot({
    width: Math.max(300, plot.clientWidth - 4), height: Math.max(240, window.innerHeight - 330),
    scales, axes,
    series: [{ label: 't [s]' }, ...state.selected.map((s, i) => ({
      label: s.label + (s.unit && s.unit !== '1' ? ` [${s.unit}]` : ''), scale: s.unit || '1',
      stroke: PALETTE[i % PALETTE.length], width: 1, points: { show: false } }))],
    cursor: { drag: { x: true, y: false } },
    hooks: { draw: [drawOverlays], setSelect: [() => { state.zoomed = true; }] },
  }, emptyData(), plot);
  chart.over.addEventListener('click', placeCursor);
  chart.over.addEventListener('dblclick', () => { state.zoomed = false; });
  applyYRange();
}

/// Micrometres and microradians are the stage's scale: uPlot's default labels would round
/// them all to 0, so small (and huge) ticks are written in exponent form.
function tickLabels(u, splits) {
  const largest = Math.max(...splits.map((v) => Math.abs(v)));
  if (largest !== 0 && (largest < 1e-2 || largest >= 1e5)) return splits.map((v) => (v === 0 ? '0' : v.toExponential(2)));
  return splits.map((v) => String(Number(v.toPrecision(6))));
}

function emptyData() { return [new Float64Array(0), ...state.selected.map(() => new Float64Array(0))]; }

/// The rows of times [from, to] as uPlot data (views into the table, no copy).
function windowData(from, to) {
  const n = live();
  if (!n) return null;
  const first = table.rows - n;
  const search = (t) => {  // first row with time >= t
    let lo = first, hi = table.rows;
    while (lo < hi) { const mid = (lo + hi) >> 1; if (table.time[slot(mid)] < t) lo = mid + 1; else hi = mid; }
    return lo;
  };
  const a = search(from), b = search(to + 1e-12);
  const i = slot(a), len = b - a;
  const view = (arr) => arr.subarray(i, i + len);
  return [view(table.time), ...state.selected.map((s) => view(column(s.key).values))];
}

/// Autoscale: uPlot's own range around the data; off: the typed limits (or, with none, the
/// range in force when autoscale was switched off, so the view holds still).
function yRange(u, min, max, scale) {
  if ($('autoscale').checked) return uPlot.rangeNum(min, max, 0.1, true);
  const lo = parseFloat($('ymin').value), hi = parseFloat($('ymax').value);
  if (Number.isFinite(lo) && Number.isFinite(hi) && lo < hi) return [lo, hi];
  const held = state.heldRanges[scale];
  return held || uPlot.rangeNum(min, max, 0.1, true);
}

function applyYRange() {
  if (!chart) return;
  state.heldRanges = {};
  if (!$('autoscale').checked)
    for (const [name, s] of Object.entries(chart.scales)) if (name !== 'x') state.heldRanges[name] = [s.min, s.max];
  chart.redraw(true);
}

function frame() {
  requestAnimationFrame(frame);
  if (!chart || state.paused || state.zoomed) return;
  const W = parseFloat($('window').value);
  let data, from, to;
  if (state.frozen) {
    ({ data, from, to } = state.frozen);
  } else {
    if (state.lastStamp === null) return;
    // Roll smoothly between batches: the pipeline's time now, estimated from the last
    // sample and the wall clock since it came, never past the data.
    const estimate = state.lastStamp + (performance.now() - state.lastArrival) / 1000 - 0.06;
    to = Math.min(state.lastStamp, Math.max(estimate, state.lastStamp - 0.5));
    from = to - W;
    data = windowData(from, to);
    if (!data) return;
  }
  chart.batch(() => {
    chart.setData(data, false);
    chart.setScale('x', { min: from, max: to });
  });
  ++stats.redraws;
}

function drawOverlays(u) {
  const ctx = u.ctx;
  ctx.save();
  const line = (t, color, label) => {
    if (t === null || t < u.scales.x.min || t > u.scales.x.max) return;
    const x = Math.round(u.valToPos(t, 'x', true));
    ctx.strokeStyle = color;
    ctx.setLineDash([4, 3]);
    ctx.beginPath(); ctx.moveTo(x, u.bbox.top); ctx.lineTo(x, u.bbox.top + u.bbox.height); ctx.stroke();
    ctx.fillStyle = color;
    ctx.fillText(label, x + 3, u.bbox.top + 12);
  };
  line(state.cursorA, '#444', 'A');
  line(state.cursorB, '#a0a', 'B');
  if (state.frozen) line(state.frozen.triggerTime, '#d00', 'T');
  ctx.restore();
}

function valueAt(data, series, t) {
  const x = data[0];
  let lo = 0, hi = x.length - 1;
  if (hi < 0) return NaN;
  while (lo < hi) { const mid = (lo + hi) >> 1; if (x[mid] < t) lo = mid + 1; else hi = mid; }
  return data[series][lo];
}

function placeCursor(e) {
  if (!chart) return;
  const t = chart.posToVal(e.offsetX, 'x');
  if (e.shiftKey) state.cursorB = t; else state.cursorA = t;
  const data = chart.data;
  const lines = [];
  const fmt = (v) => (Number.isFinite(v) ? v.toPrecision(6) : '–');
  if (state.cursorA !== null) lines.push(`A  t ${fmt(state.cursorA)} s`);
  if (state.cursorB !== null) lines.push(`B  t ${fmt(state.cursorB)} s`);
  if (state.cursorA !== null && state.cursorB !== null) {
    const dt = state.cursorB - state.cursorA;
    lines.push(`Δt ${fmt(dt)} s  1/Δt ${fmt(1 / dt)} Hz`);
  }
  state.selected.forEach((s, i) => {
    const a = state.cursorA !== null ? valueAt(data, i + 1, state.cursorA) : NaN;
    const b = state.cursorB !== null ? valueAt(data, i + 1, state.cursorB) : NaN;
    lines.push(`${s.label}: A ${fmt(a)}  B ${fmt(b)}  Δ ${fmt(b - a)} ${s.unit}`);
  });
  $('cursors').textContent = lines.join('\n');
  chart.redraw(false);
}

// ---------------------------------------------------------------------------------------------
// Trigger: a level crossing of one selected signal, halscope-like. `normal` re-arms after each
// capture, `single` holds the first one. A capture is the window around the crossing, with
// `pre` percent of it before; it is copied out of the table so it outlives the ring.

const trigger = { armed: false, at: null, source: null };

function armTrigger() {
  const mode = $('trigger-mode').value;
  state.frozen = null;
  trigger.at = null;
  trigger.armed = mode !== 'off' && !!$('trigger-source').value;
  trigger.source = $('trigger-source').value;
  trigger.fromRow = table.rows;
  $('trigger-state').textContent = mode === 'off' ? '–' : trigger.armed ? 'armed' : 'pick a signal';
}

function checkTrigger(row) {
  const W = parseFloat($('window').value);
  const pre = Math.min(100, Math.max(0, parseFloat($('trigger-pre').value) || 0)) / 100;
  if (trigger.at === null) {
    if (row <= trigger.fromRow || row - 1 < table.rows - live()) return;
    const c = table.columns.get(trigger.source);
    if (!c) return;
    const level = parseFloat($('trigger-level').value) || 0;
    const before = c.values[slot(row - 1)], now = c.values[slot(row)];
    const rising = $('trigger-edge').value === 'rising';
    if (rising ? before < level && now >= level : before > level && now <= level) {
      // Need the pre-trigger part in the table, else the capture would start late.
      if (table.time[slot(row)] - pre * W < table.time[slot(table.rows - live())]) return;
      trigger.at = table.time[slot(row)];
    }
    return;
  }
  const from = trigger.at - pre * W, to = from + W;
  if (table.time[slot(row)] < to) return;
  const view = windowData(from, to);
  state.frozen = { data: view.map((a) => a.slice()), from, to, triggerTime: trigger.at };
  ++stats.triggers;
  $('trigger-state').textContent = `triggered at ${trigger.at.toFixed(4)} s`;
  if ($('trigger-mode').value === 'normal') {
    trigger.at = null;
    trigger.fromRow = table.rows;
  } else {
    trigger.armed = false;
  }
}
stats.triggers = 0;

// ---------------------------------------------------------------------------------------------
// Status strip, events, health

const statusFields = (k) => $('status').querySelector(`[data-k="${k}"]`);
const lastStatus = { at: 0, received: 0 };
function onTiming(t) {
  if (t.pipeline !== state.pipeline) return;
  const f = (v, d = 1) => (Number.isFinite(v) ? v.toFixed(d) : '–');
  statusFields('rate').textContent = `${t.rate_hz} Hz`;
  statusFields('cycle').textContent = t.cycle;
  statusFields('overruns').textContent = t.overruns;
  statusFields('overruns').className = t.overruns ? 'warn' : '';
  statusFields('missed').textContent = t.missed_periods;
  statusFields('wake').textContent = `${f(t.wake_latency.p50_us)}/${f(t.wake_latency.p99_us)}/${f(t.wake_latency.max_us)}`;
  statusFields('cycle_p99').textContent = f(t.cycle_time.p99_us, 2);
  statusFields('telemetry_dropped').textContent = t.telemetry_dropped;
  state.timing = t;
}

function onStatus(s) {
  const now = performance.now();
  if (lastStatus.at) {
    const rate = (s.samples_received - lastStatus.received) / ((now - lastStatus.at) / 1000);
    statusFields('sample_rate').textContent = Math.max(0, rate).toFixed(0);
  }
  lastStatus.at = now;
  lastStatus.received = s.samples_received;
  const dropped = s.samples_dropped + s.messages_dropped + stats.late;
  statusFields('scope_dropped').textContent = dropped;
  statusFields('scope_dropped').className = dropped ? 'warn' : '';
  state.scopeStatus = s;
}

const events = [];
function onEvent(e) {
  events.push(e);
  const li = document.createElement('li');
  li.innerHTML = `<span class="kind kind-${e.kind}"></span> `;
  li.firstChild.textContent = e.kind;
  li.append(`${e.pipeline} cycle ${e.cycle} t ${e.stamp_s.toFixed(3)} s  ${e.text}`);
  const list = $('event-list');
  list.prepend(li);
  while (list.children.length > 500) list.lastChild.remove();
}

/// Shadows publish <shadow>.nis and <shadow>.disagreement: watched as soon as the pipeline is
/// chosen, shown as their latest values with a promote button.
function shadowTopics() {
  return state.signals.filter((s) => s.pipeline === state.pipeline && (s.port === 'nis' || s.port === 'disagreement'));
}

function watchShadows() {
  const topics = shadowTopics();
  const list = $('shadow-list');
  if (!topics.length) { list.textContent = 'no shadow publishes .nis or .disagreement'; return; }
  watch(topics.map((s) => s.topic));
  const shadows = [...new Set(topics.map((s) => s.block))].sort();
  list.className = '';
  list.replaceChildren(...shadows.map((name) => {
    const div = document.createElement('div');
    div.className = 'shadow';
    div.dataset.shadow = name;
    div.innerHTML = `<b>${name}</b> <button type="button">Promote</button><div class="metric"></div>`;
    div.querySelector('button').addEventListener('click', () => command({ kind: 'promote', shadow: name }));
    return div;
  }));
}

function updateShadows() {
  const row = table.rows - 1;
  if (row < 0) return;
  const fmt = (v) => (Number.isFinite(v) ? v.toPrecision(4) : '–');
  for (const div of $('shadow-list').querySelectorAll('.shadow')) {
    const lines = [];
    for (const s of shadowTopics().filter((t) => t.block === div.dataset.shadow)) {
      const values = s.names.map((n, k) => table.columns.get(`${s.topic}#${k}`)?.values[slot(row)]);
      const text = s.names.map((n, k) => `${n} ${fmt(values[k])}${s.units[k] && s.units[k] !== '1' ? ' ' + s.units[k] : ''}`);
      lines.push(`${s.port}: ${text.join(', ')}`);
    }
    div.querySelector('.metric').textContent = lines.join(' · ');
  }
}

// ---------------------------------------------------------------------------------------------
// Commands

async function post(path, body) {
  const r = await fetch(api(path), { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body) });
  if (!r.ok) return { ok: false, message: `HTTP ${r.status}: ${await r.text()}`, errors: [`HTTP ${r.status}`] };
  return r.json();
}

const replies = [];
function addReply(request, reply) {
  replies.push({ request, reply });
  const li = document.createElement('li');
  li.className = reply.ok ? 'ok' : 'error';
  const what = request.kind === 'set' ? `set ${request.target} ${request.value}`
    : request.kind === 'swap' ? `swap ${request.block} ${request.plugin}`
    : request.kind === 'promote' ? `promote ${request.shadow}` : request.kind;
  li.textContent = `${what} → ${reply.ok ? 'ok' : 'error'}: ${reply.message}`;
  $('reply-list').prepend(li);
}

async function command(request) {
  const reply = await post('/api/command', { pipeline: state.pipeline, ...request });
  addReply(request, reply);
  return reply;
}

async function loadParameters() {
  const list = $('parameter-list');
  if (!state.pipeline) return;
  const r = await fetch(api(`/api/parameters?pipeline=${encodeURIComponent(state.pipeline)}`)).then((x) => x.json());
  if (!r.ok) { list.className = 'help error'; list.textContent = r.message; return; }
  list.className = '';
  const table_ = document.createElement('table');
  for (const p of r.parameters) {
    const tr = table_.insertRow();
    tr.dataset.name = p.name;
    const range = p.boolean ? 'true|false' : `[${p.min}, ${p.max}]${p.integer ? ' integer' : ''}`;
    const nameCell = tr.insertCell();
    nameCell.append(p.name, document.createElement('br'),
                    Object.assign(document.createElement('span'), { className: 'unit', textContent: range }));
    const input = document.createElement('input');
    if (p.boolean) {
      input.type = 'checkbox';
      input.checked = p.value === '1' || p.value === 'true';
    } else {
      Object.assign(input, { type: 'number', min: p.min, max: p.max, step: p.integer ? 1 : 'any', value: p.value });
    }
    input.title = `${range} ${p.unit}  ${p.description}`;
    const button = document.createElement('button');
    button.type = 'button';
    button.textContent = 'Set';
    const cell = tr.insertCell();
    const reply = document.createElement('div');
    reply.className = 'reply';
    cell.append(input, ' ', Object.assign(document.createElement('span'), { className: 'unit', textContent: p.unit }), ' ', button, reply);
    button.addEventListener('click', async () => {
      const value = p.boolean ? String(input.checked) : input.value;
      const answer = await command({ kind: 'set', target: p.name, value });
      reply.className = `reply ${answer.ok ? 'ok' : 'error'}`;
      reply.textContent = answer.message;
      if (answer.ok && !p.boolean) input.value = answer.value;
    });
  }
  list.replaceChildren(table_);
}

// ---------------------------------------------------------------------------------------------
// Wiring

function connect() {
  const stream = new EventSource(api('/api/stream'));
  const connection = statusFields('connection');
  stream.onopen = () => { connection.textContent = 'live'; connection.className = 'ok'; };
  stream.onerror = () => {
    connection.className = 'bad';
    if (stream.readyState !== EventSource.CLOSED) {
      connection.textContent = 'reconnecting';  // the browser retries on its own
      return;
    }
    // Refused (503: the scope has as many pages open as it serves) or gone: try again later.
    connection.textContent = 'refused (too many pages open?), retrying';
    setTimeout(connect, 5000);
  };
  stream.addEventListener('signals', (e) => onSignals(JSON.parse(e.data)));
  stream.addEventListener('samples', (e) => {
    receiveSamples(JSON.parse(e.data));
    if (table.rows) {
      state.lastStamp = table.time[slot(table.rows - 1)];
      state.lastArrival = performance.now();
    }
  });
  stream.addEventListener('timing', (e) => onTiming(JSON.parse(e.data)));
  stream.addEventListener('event', (e) => onEvent(JSON.parse(e.data)));
  stream.addEventListener('status', (e) => onStatus(JSON.parse(e.data)));
}

$('pipeline').addEventListener('change', (e) => choosePipeline(e.target.value));
$('pause').addEventListener('click', () => {
  state.paused = !state.paused;
  state.zoomed = false;
  $('pause').textContent = state.paused ? 'Run' : 'Pause';
});
for (const id of ['autoscale', 'ymin', 'ymax']) $(id).addEventListener('change', applyYRange);
for (const id of ['trigger-mode', 'trigger-source', 'trigger-edge', 'trigger-level', 'trigger-pre', 'window'])
  $(id).addEventListener('change', armTrigger);
$('reload-parameters').addEventListener('click', loadParameters);
$('swap-button').addEventListener('click', () => command({
  kind: 'swap', block: $('swap-block').value.trim(), plugin: $('swap-plugin').value.trim(),
  params: $('swap-params').value.trim(), shadow_cycles: parseInt($('swap-shadow-cycles').value, 10) || 0,
  cold: $('swap-cold').checked }));
window.addEventListener('resize', () => chart && chart.setSize({ width: $('plot').clientWidth - 4, height: chart.height }));
setInterval(updateShadows, 250);

// What tests and curious users can read from the console.
window.lodeScope = { stats, state, table, events, replies, get chart() { return chart; } };
connect();
requestAnimationFrame(frame);
