// Opens one page in headless Chromium over the DevTools protocol and reports what happened:
// every console error, uncaught exception and failed resource load, the value of an
// expression once a readiness expression is true, and optionally a screenshot.
//
//   node chromium_page.mjs --url file:///x.html
//        [--ready 'window.plotReady === true'] [--eval 'JSON.stringify(window.plotStats)']
//        [--script checks.js]   (evaluated once ready, before --eval: defines what --eval calls)
//        [--screenshot out.png [--full-page 1]] [--width 1400] [--height 900] [--timeout 60]
//
// Prints one JSON object {errors: [...], value: ..., ready_ms: N} on stdout; exits 1 when
// the page logged an error or never became ready, 0 otherwise.
//
// Why DevTools rather than `chromium --dump-dom --enable-logging`: the log lines' format
// changes between Chromium versions and interleaves with Chromium's own noise, while the
// protocol's Runtime.exceptionThrown / consoleAPICalled events are a stable interface.
// Hermetic: port 0 (Chromium picks a free one and prints it), a fresh profile directory
// named after this process (the browser's temporary files in it), and the browser's whole
// process group killed at the end.
import { spawn } from 'node:child_process';
import { mkdtempSync, readFileSync, rmSync, writeFileSync } from 'node:fs';
import { createRequire } from 'node:module';
import { tmpdir } from 'node:os';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

// Node 22 has a WebSocket client built in; older Node (Debian 12 ships 18) gets `ws`, pinned
// with uPlot in apps/lode/plot/package-lock.json.
const here = dirname(fileURLToPath(import.meta.url));
const WebSocketClient = globalThis.WebSocket ??
  createRequire(join(here, '../../apps/lode/plot/package.json'))('ws').WebSocket;

const options = { width: 1400, height: 900, timeout: 60, ready: 'document.readyState === "complete"' };
for (let i = 2; i < process.argv.length; i += 2) options[process.argv[i].replace(/^--/, '')] = process.argv[i + 1];
if (!options.url) {
  console.error('usage: chromium_page.mjs --url URL [--ready EXPR] [--eval EXPR] [--screenshot PNG]');
  process.exit(2);
}
const chromium = process.env.LODE_CHROMIUM || '/usr/bin/chromium';
const profile = mkdtempSync(join(tmpdir(), `lode-chromium-${process.pid}-`));
const browser = spawn(chromium, [
  '--headless', '--no-sandbox', '--disable-gpu', '--no-first-run', '--no-default-browser-check',
  '--remote-debugging-port=0', `--user-data-dir=${profile}`,
  `--window-size=${options.width},${options.height}`, 'about:blank',
  // Its temporary files too (the singleton socket's org.chromium.Chromium.* folder, which a
  // killed browser leaves behind): inside the profile, removed with it.
], { detached: true, stdio: ['ignore', 'ignore', 'pipe'], env: { ...process.env, TMPDIR: profile } });

function cleanUp() {
  try { process.kill(-browser.pid, 'SIGKILL'); } catch { /* already gone */ }
  rmSync(profile, { recursive: true, force: true });
}
const deadline = setTimeout(() => finish(['timed out after ' + options.timeout + ' s']), Number(options.timeout) * 1000);

const endpoint = await new Promise((resolve, reject) => {
  let text = '';
  browser.stderr.on('data', (chunk) => {
    text += chunk;
    const m = text.match(/DevTools listening on (ws:\/\/\S+)/);
    if (m) resolve(m[1]);
  });
  browser.on('exit', (code) => reject(new Error(`chromium exited (${code}) before listening: ${text}`)));
}).catch((e) => { finish([String(e)]); });

const socket = new WebSocketClient(endpoint);
await new Promise((resolve) => socket.addEventListener('open', resolve));
let nextId = 1;
const pending = new Map();
const errors = [];
socket.addEventListener('message', (message) => {
  const m = JSON.parse(message.data);
  if (m.id && pending.has(m.id)) {
    const { resolve, reject } = pending.get(m.id);
    pending.delete(m.id);
    if (m.error) reject(new Error(JSON.stringify(m.error))); else resolve(m.result);
    return;
  }
  if (m.method === 'Runtime.exceptionThrown') {
    const d = m.params.exceptionDetails;
    errors.push(`exception: ${d.exception?.description ?? d.text} at ${d.url ?? ''}:${d.lineNumber}`);
  } else if (m.method === 'Runtime.consoleAPICalled' && (m.params.type === 'error' || m.params.type === 'assert')) {
    errors.push('console.error: ' + m.params.args.map((a) => a.value ?? a.description).join(' '));
  } else if (m.method === 'Log.entryAdded' && m.params.entry.level === 'error') {
    errors.push(`log: ${m.params.entry.text} ${m.params.entry.url ?? ''}`);
  }
});
function send(method, params = {}, sessionId = undefined) {
  const id = nextId++;
  socket.send(JSON.stringify({ id, method, params, sessionId }));
  return new Promise((resolve, reject) => pending.set(id, { resolve, reject }));
}

function finish(extraErrors, value = null, readyMs = null) {
  clearTimeout(deadline);
  const all = errors.concat(extraErrors);
  console.log(JSON.stringify({ errors: all, value, ready_ms: readyMs }));
  cleanUp();
  process.exit(all.length ? 1 : 0);
}

try {
  const { targetId } = await send('Target.createTarget', { url: 'about:blank' });
  const { sessionId } = await send('Target.attachToTarget', { targetId, flatten: true });
  const page = (method, params) => send(method, params, sessionId);
  await page('Runtime.enable');
  await page('Log.enable');
  await page('Page.enable');
  await page('Emulation.setDeviceMetricsOverride', {
    width: Number(options.width), height: Number(options.height), deviceScaleFactor: 1, mobile: false });
  const started = Date.now();
  await page('Page.navigate', { url: options.url });
  const evaluate = async (expression) => {
    const r = await page('Runtime.evaluate', { expression, returnByValue: true, awaitPromise: true });
    if (r.exceptionDetails) throw new Error(`${expression}: ${r.exceptionDetails.exception?.description}`);
    return r.result.value;
  };
  while (!(await evaluate(`(() => { try { return !!(${options.ready}); } catch { return false; } })()`)))
    await new Promise((r) => setTimeout(r, 20));
  const readyMs = Date.now() - started;
  if (options.script) await evaluate(readFileSync(options.script, 'utf8'));
  const value = options.eval ? await evaluate(options.eval) : null;
  if (options.screenshot) {
    const shot = await page('Page.captureScreenshot', { format: 'png', captureBeyondViewport: options['full-page'] === '1' });
    writeFileSync(options.screenshot, Buffer.from(shot.data, 'base64'));
  }
  finish([], value, readyMs);
} catch (e) {
  finish([String(e)]);
}
