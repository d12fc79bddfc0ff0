// Evaluated inside the lode scope page by chromium_page.mjs (--script), then called by --eval:
// drives the page as a person would (ticks signals, types a parameter, presses Set, Swap and Promote)
// and returns what the page showed, as JSON, for scope_test.sh to judge.
//
//   scopeChecks({signals: 10, seconds: 5, parameter: 'kf_hybrid.d', value: '0.4',
//                swap: {block, plugin, params}, promote: shadow, trigger: true, window: 10, hold: 0})
window.scopeChecks = async (o) => {
  const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));
  const until = async (condition, ms, what) => {
    const end = Date.now() + ms;
    while (!condition()) {
      if (Date.now() > end) throw new Error(`timed out after ${ms} ms waiting for ${what}`);
      await sleep(50);
    }
  };
  const scope = window.lodeScope;
  const out = {};

  await until(() => document.querySelectorAll('#signal-list input').length >= o.signals, 20000, 'the signal list');
  const boxes = [...document.querySelectorAll('#signal-list input')].slice(0, o.signals);
  for (const box of boxes) box.click();
  out.selected = boxes.map((b) => b.dataset.key);
  if (o.window) {
    const windowSelect = document.getElementById('window');
    windowSelect.value = String(o.window);
    windowSelect.dispatchEvent(new Event('change'));
    await sleep(o.window * 1000);  // fill it, so every frame draws a whole window
  }
  out.window_s = parseFloat(document.getElementById('window').value);
  await until(() => scope.stats.redraws > 10, 20000, 'the plot drawing');
  await sleep(1000);  // past the start-up: count a steady state

  // Samples received and frames drawn over `seconds`: the same window for both.
  const samples0 = { ...scope.stats.samples };
  const lastCycle0 = { ...scope.stats.lastCycle };
  const redraws0 = scope.stats.redraws;
  const started = performance.now();
  await sleep(o.seconds * 1000);
  const elapsed = (performance.now() - started) / 1000;
  out.seconds = elapsed;
  out.fps = (scope.stats.redraws - redraws0) / elapsed;
  out.rates = {};
  for (const topic of new Set(out.selected.map((k) => k.split('#')[0])))
    out.rates[topic] = { received_hz: ((scope.stats.samples[topic] || 0) - (samples0[topic] || 0)) / elapsed,
                         topic_hz: scope.state.byTopic.get(topic).rate_hz,
                         // The samples of cycles (first, last]: what another client got of
                         // the same cycles is compared with this.
                         samples: (scope.stats.samples[topic] || 0) - (samples0[topic] || 0),
                         cycles: [lastCycle0[topic], scope.stats.lastCycle[topic]] };
  out.rows = scope.table.rows;
  out.late = scope.stats.late;
  out.plotted_points = scope.chart ? scope.chart.data[0].length : 0;
  out.status = Object.fromEntries([...document.querySelectorAll('#status [data-k]')].map((e) => [e.dataset.k, e.textContent]));
  out.shadows = [...document.querySelectorAll('#shadow-list .shadow')].map((d) => d.textContent);

  if (o.hold) await sleep(o.hold * 1000);  // the caller measures the server meanwhile

  if (o.parameter) {
    await until(() => document.querySelector(`#parameter-list tr[data-name="${o.parameter}"]`), 20000, 'the parameter list');
    const row = document.querySelector(`#parameter-list tr[data-name="${o.parameter}"]`);
    row.querySelector('input').value = o.value;
    row.querySelector('button').click();
    const reply = row.querySelector('.reply');
    await until(() => reply.textContent.length > 0, 20000, 'the set reply');
    out.set_reply = reply.textContent;
    out.set_ok = reply.classList.contains('ok');
    out.set_input = row.querySelector('input').value;
    await until(() => scope.events.some((e) => e.kind === 'parameter' && e.text.includes(o.parameter)), 20000, 'the parameter event');
    out.parameter_event = scope.events.find((e) => e.kind === 'parameter' && e.text.includes(o.parameter)).text;
    out.event_list_shows_it = [...document.querySelectorAll('#event-list li')].some((li) => li.textContent.includes(out.parameter_event));
  }

  if (o.swap) {
    document.getElementById('swap-block').value = o.swap.block;
    document.getElementById('swap-plugin').value = o.swap.plugin;
    document.getElementById('swap-params').value = o.swap.params || '';
    const before = scope.replies.length;
    document.getElementById('swap-button').click();
    await until(() => scope.replies.length > before, 30000, 'the swap reply');
    out.swap_reply = scope.replies[scope.replies.length - 1].reply;
    out.reply_list_shows_it = document.querySelector('#reply-list li').textContent;
    await until(() => scope.events.some((e) => e.kind === 'swap' && e.text.includes(o.swap.plugin)), 20000, 'the swap event');
    out.swap_event = scope.events.find((e) => e.kind === 'swap').text;
  }

  if (o.promote) {
    // The shadow's Promote button: it takes the primary's place at a cycle boundary.
    const before = scope.replies.length;
    document.querySelector(`#shadow-list .shadow[data-shadow="${o.promote}"] button`).click();
    await until(() => scope.replies.length > before, 30000, 'the promote reply');
    out.promote_reply = scope.replies[scope.replies.length - 1].reply;
    const promoted = (e) => e.kind === 'swap' && e.text.startsWith(`promoted ${o.promote}`);
    await until(() => scope.events.some(promoted), 20000, 'the promotion event');
    out.promote_event = scope.events.find(promoted).text;
  }

  if (o.trigger) {
    // A level trigger on the first selected signal at the middle of what it shows now.
    const data = scope.chart.data;
    let min = Infinity, max = -Infinity;
    for (const v of data[1]) { min = Math.min(min, v); max = Math.max(max, v); }
    document.getElementById('trigger-source').value = out.selected[0];
    document.getElementById('trigger-level').value = String((min + max) / 2);
    out.trigger_level = (min + max) / 2;
    out.trigger_signal_range = [min, max];
    const mode = document.getElementById('trigger-mode');
    mode.value = 'single';
    mode.dispatchEvent(new Event('change'));
    await until(() => scope.stats.triggers > 0, 20000, 'a trigger');
    out.trigger_state = document.getElementById('trigger-state').textContent;
  }
  return JSON.stringify(out);
};
