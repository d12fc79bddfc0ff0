#!/usr/bin/env bash
# `lode plot` end to end: record a short demo run, report it (with a replay of it through
# another estimator set beside it), check every section is in the page, open the page in
# headless Chromium over the DevTools protocol (chromium_page.mjs) and fail on any console
# error or exception, zoom it, and photograph its figures with --png.
set -u
LODE=$1
SRC=$2
source "$SRC/tests/integration/test_lib.sh"  # TMP (private, removed at exit), ok/bad/check_rc/contains
PAGE="$SRC/tests/plot/chromium_page.mjs"
export LODE_CHROMIUM=${LODE_CHROMIUM:-/usr/bin/chromium}
for tool in node "$LODE_CHROMIUM"; do
  command -v "$tool" >/dev/null || { echo "SKIP: $tool not installed"; exit 77; }
done

"$LODE" run "$SRC/config/kawato_planar.yaml" --duration 3 --record "$TMP/demo.h5" --quiet --no-telemetry \
  --no-local-control >"$TMP/run.out" 2>&1
check_rc "record a demo run" 0 $? "$TMP/run.out"
"$LODE" replay "$TMP/demo.h5" --config "$SRC/config/replay/kawato_planar_cv.yaml" --output "$TMP/replay.h5" \
  --quiet >"$TMP/replay.out" 2>&1
check_rc "replay it through the constant-velocity Kalman filter" 0 $? "$TMP/replay.out"

# lode replay --report R.html: the same report, the replay's estimate beside the recording's.
"$LODE" replay "$TMP/demo.h5" --config "$SRC/config/replay/kawato_planar_cv.yaml" --output "$TMP/compared.h5" \
  --quiet --report "$TMP/comparison.html" >"$TMP/compare.out" 2>&1
check_rc "lode replay --report comparison.html" 0 $? "$TMP/compare.out"
contains "replay --report .html: the replay's estimate beside the recording's" "$TMP/comparison.html" \
  '"label":"kf.pose @ compared-kawato_planar_cv.h5"'
contains "replay --report .html: the steps section" "$TMP/comparison.html" '<section id="steps">'

start=$EPOCHREALTIME
"$LODE" plot "$TMP/demo.h5" "$TMP/replay-kawato_planar_cv.h5" -o "$TMP/report.html" >"$TMP/plot.out" 2>&1
check_rc "lode plot" 0 $? "$TMP/plot.out"
seconds=$(awk -v a="$start" -v b="$EPOCHREALTIME" 'BEGIN { printf "%.2f", b - a }')
echo "lode plot took $seconds s on the 3 s demo recording (2400 cycles) and its replay"
# The goal is under 2 s; ten times that is a hang or a regression, not a slow machine.
awk -v s="$seconds" 'BEGIN { exit !(s < 20) }' && ok "lode plot in $seconds s" || bad "lode plot took $seconds s"

# Further files must be replays of the first: the replay beside another run's recording (its
# sensor noise from another seed) is refused, naming the first difference.
sed 's/^    seed: 1$/    seed: 2/' "$SRC/config/kawato_planar.yaml" >"$TMP/other_seed.yaml"
"$LODE" run "$TMP/other_seed.yaml" --duration 3 --record "$TMP/other.h5" --quiet --no-telemetry \
  --no-local-control >"$TMP/other.out" 2>&1
check_rc "record another run (seed 2)" 0 $? "$TMP/other.out"
"$LODE" plot "$TMP/other.h5" "$TMP/replay-kawato_planar_cv.h5" -o "$TMP/mixed.html" >"$TMP/mixed.out" 2>&1
check_rc "lode plot of a recording with another recording's replay is refused" 2 $? "$TMP/mixed.out"
contains "and says which file and where" "$TMP/mixed.out" \
  "replay-kawato_planar_cv.h5 is not a replay of .*other.h5: its stage\.[a-z_]+ differs from the recording's at row [0-9]+"

html=$TMP/report.html
for section in summary signals errors steps psd timing events config; do
  contains "section $section" "$html" "<section id=\"$section\">"
done
contains "the chart library is inlined" "$html" "uPlot"
contains "arrays inlined as base64 blobs" "$html" 'type="application/x-lode-blob" id="b0"'
if grep -qE '<script[^>]+src=|<link[^>]+href=' "$html"; then bad "the page loads nothing from elsewhere"; else ok "the page loads nothing from elsewhere"; fi
for figure in signals-0 errors-0 step-0 psd-0 timing-latency timing-blocks timing-overruns; do
  contains "figure $figure" "$html" "\"id\":\"$figure\""
done
contains "the replay's estimate beside the recording's" "$html" '"label":"kf.pose @ replay-kawato_planar_cv.h5"'
contains "step metrics in the summary" "$html" '"rise_start_s":'
contains "recorded timing" "$html" '"block_exec_time":'
contains "events of the run" "$html" '"kind":"start"'

# In the browser: no console error, every figure drawn, linked zoom down to the samples.
node "$PAGE" --url "file://$html" --ready 'window.lodeReport && window.lodeReport.ready' \
  --eval 'JSON.stringify({figures: lodeReport.figures, drawn: lodeReport.drawn, plots: document.querySelectorAll(".uplot").length, zoom_ms: lodeReport.zoom(0.95, 1.05), back_ms: lodeReport.zoom(0, 3)})' \
  >"$TMP/page.json" 2>"$TMP/page.err"
check_rc "the page opens in headless Chromium without a console error" 0 $? "$TMP/page.json"
cat "$TMP/page.json"
"$PY" - "$TMP/page.json" <<'EOF' && ok "every figure drawn, zoom works" || bad "figures or zoom (see above)"
import json, sys
page = json.load(open(sys.argv[1]))
value = json.loads(page["value"])
assert not page["errors"], page["errors"]
assert value["figures"] == value["drawn"] >= 14, value
assert value["plots"] >= value["figures"], value
assert value["zoom_ms"] >= 0 and value["back_ms"] >= 0, value
EOF

# A recording without a configuration (as `lode record` of DDS topics writes) is plotted from
# its series' names. Made from the demo by h5py: the `config` attribute removed.
"$PY" - "$TMP/demo.h5" "$TMP/noconfig.h5" <<'EOF'
import shutil, sys, h5py
shutil.copy(sys.argv[1], sys.argv[2])
with h5py.File(sys.argv[2], "r+") as f:
    del f.attrs["config"]
EOF
"$LODE" plot "$TMP/noconfig.h5" -o "$TMP/noconfig.html" >"$TMP/noconfig.out" 2>&1
check_rc "plot a recording without a configuration" 0 $? "$TMP/noconfig.out"
contains "roles by name: truth found" "$TMP/noconfig.html" '"role":"truth"'
contains "roles by name: estimate found" "$TMP/noconfig.html" '"detail":"by name","label":"kf.pose"'

# A replay through the recorded configuration reproduces every estimate bit for bit: drawn once,
# with a note, instead of two curves hiding each other.
"$LODE" replay "$TMP/demo.h5" --output "$TMP/same.h5" --quiet >"$TMP/same.out" 2>&1
check_rc "replay through the recorded configuration" 0 $? "$TMP/same.out"
"$LODE" plot "$TMP/demo.h5" "$TMP/same.h5" -o "$TMP/same.html" >"$TMP/plot_same.out" 2>&1
check_rc "plot a recording beside its identical replay" 0 $? "$TMP/plot_same.out"
contains "an identical replay's estimate is noted" "$TMP/plot_same.out" \
  "note: kf.pose @ same.h5 is bit-identical to kf.pose: drawn once"
if grep -q '"label":"kf.pose @ same.h5"' "$TMP/same.html"; then
  bad "an identical replay's estimate is drawn twice"
else
  ok "an identical replay's estimate is drawn once"
fi

"$LODE" plot "$TMP/demo.h5" -o "$TMP/png.html" --png "$TMP/png" --quiet >"$TMP/png.out" 2>&1
check_rc "--png" 0 $? "$TMP/png.out"
for figure in signals-0 step-0 psd-0 timing-blocks; do
  if [ -s "$TMP/png/$figure.png" ] && [ "$(head -c 4 "$TMP/png/$figure.png" | tail -c 3)" = PNG ]; then
    ok "$figure.png written"
  else
    bad "$figure.png missing"
  fi
done

"$LODE" plot "$TMP/missing.h5" >"$TMP/missing.out" 2>&1
check_rc "a missing recording is a usage error" 2 $? "$TMP/missing.out"
exit $fail
