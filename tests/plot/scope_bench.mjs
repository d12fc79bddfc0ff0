// Which chart library can be a live scope: redraws 10 series x 10 000 points (a 10 s window
// at 1 kHz) every animation frame, the window advancing 1000/60 samples a frame, and counts
// the frames per second and the time each redraw takes, in headless Chromium.
//
//   node tests/plot/scope_bench.mjs DYGRAPH_JS UPLOT_JS UPLOT_CSS [SECONDS]
//
// Each library is fed its native layout (dygraphs: rows [x, y1..y10]; uPlot: one typed array
// per series), both cut from a precomputed ring so data generation costs the same for both.
import { execFileSync } from 'node:child_process';
import { readFileSync, writeFileSync, mkdtempSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join, dirname } from 'node:path';
import { fileURLToPath } from 'node:url';

const [dygraphJs, uplotJs, uplotCss, secondsArg] = process.argv.slice(2);
const seconds = Number(secondsArg || 5);
const here = dirname(fileURLToPath(import.meta.url));
const work = mkdtempSync(join(tmpdir(), `lode-scope-bench-${process.pid}-`));

const common = `
const SERIES = 10, WINDOW = 10000, RATE = 1000, TOTAL = WINDOW * 4;
const time = new Float64Array(TOTAL), values = [];
for (let k = 0; k < TOTAL; ++k) time[k] = k / RATE;
for (let s = 0; s < SERIES; ++s) {
  const v = new Float64Array(TOTAL);
  for (let k = 0; k < TOTAL; ++k) v[k] = Math.sin(2 * Math.PI * (0.5 + s) * k / RATE) + 0.1 * Math.random();
  values.push(v);
}
let start = 0, frames = 0, busy = 0;
const began = performance.now();
async function frame() {
  const t0 = performance.now();
  start = (start + Math.round(RATE / 60)) % (TOTAL - WINDOW);
  redraw(start);
  // uPlot draws in a microtask queued by setData(): wait for it so both count their drawing.
  await new Promise((resolve) => queueMicrotask(resolve));
  busy += performance.now() - t0;
  ++frames;
  const elapsed = (performance.now() - began) / 1000;
  if (elapsed < ${seconds}) requestAnimationFrame(frame);
  else window.benchResult = { fps: frames / elapsed, mean_redraw_ms: busy / frames, frames };
}
`;

const pages = {
  dygraphs: `<!doctype html><html><head><meta charset="utf-8"><script>${readFileSync(dygraphJs, 'utf8')}</script></head>
<body><div id="chart" style="width:1200px;height:600px"></div><script>${common}
const rows = [];
for (let k = 0; k < TOTAL; ++k) { const r = [time[k]]; for (let s = 0; s < SERIES; ++s) r.push(values[s][k]); rows.push(r); }
const chart = new Dygraph(document.getElementById('chart'), rows.slice(0, WINDOW), { animatedZooms: false });
function redraw(start) { chart.updateOptions({ file: rows.slice(start, start + WINDOW) }); }
requestAnimationFrame(frame);
</script></body></html>`,
  uplot: `<!doctype html><html><head><meta charset="utf-8"><style>${readFileSync(uplotCss, 'utf8')}</style>
<script>${readFileSync(uplotJs, 'utf8')}</script></head>
<body><div id="chart"></div><script>${common}
const slice = (start) => [time.subarray(start, start + WINDOW), ...values.map((v) => v.subarray(start, start + WINDOW))];
const chart = new uPlot({ width: 1200, height: 600, series: [{}, ...values.map(() => ({ stroke: 'blue' }))] },
                        slice(0), document.getElementById('chart'));
function redraw(start) { chart.setData(slice(start)); }
requestAnimationFrame(frame);
</script></body></html>`,
};

const results = {};
for (const [name, html] of Object.entries(pages)) {
  const file = join(work, `${name}.html`);
  writeFileSync(file, html);
  const out = execFileSync(process.execPath, [join(here, 'chromium_page.mjs'),
    '--url', `file://${file}`, '--ready', 'window.benchResult !== undefined',
    '--eval', 'window.benchResult', '--timeout', String(seconds + 60)], { encoding: 'utf8' });
  results[name] = JSON.parse(out).value;
}
rmSync(work, { recursive: true, force: true });
console.log(JSON.stringify(results, null, 2));
