#!/usr/bin/env bash
# What `lode scope` costs, measured in one run (by hand, not in ctest: the numbers depend on
# the machine; docs/scope.md quotes them):
#   1. the hot-swap demo on the real clock for SECONDS without a scope: its overruns;
#   2. the same again with `lode scope` and its page attached in headless Chromium, ten
#      signals at 1 kHz ticked in a 10 s window: the overruns, the frames the page draws per
#      second (requestAnimationFrame redraws over 5 s), and the scope server's CPU use
#      (utime + stime from /proc/PID/stat over 10 s while the page is attached).
# The real-time settings are the configuration's own (SCHED_FIFO 80 on CPU 1, memory locked)
# unless --no-rt; a host that cannot grant them makes `lode run` say so in its output.
#
#   tests/scope/scope_measure.sh LODE SRC [SECONDS] [--no-rt] [--screenshot PNG]
set -u
LODE=$1 SRC=$2 SECONDS_RUN=${3:-40}
shift 2; [ $# -gt 0 ] && shift
RT=1 SHOT=
while [ $# -gt 0 ]; do
  case "$1" in --no-rt) RT=0 ;; --screenshot) SHOT=$2; shift ;; esac
  shift
done
source "$SRC/tests/integration/test_lib.sh"
PAGE="$SRC/tests/plot/chromium_page.mjs"
take_private_domain

sed -e "s/^  domain: 0/  domain: $DOMAIN/" "$SRC/config/kawato_planar_swap.yaml" >"$TMP/swap.yaml"
[ $RT = 0 ] && sed -i -e "s/^realtime: .*/realtime: { overrun_policy: skip }/" "$TMP/swap.yaml"
grep '^realtime' "$TMP/swap.yaml"
overruns() { "$PY" -c 'import json,sys; s=json.load(open(sys.argv[1])); t=s["timing"]; print(t["overruns"], t["missed_periods"], t.get("wake_latency", {}).get("p99_us", "?"), "executed", t.get("executed_cycles"))' "$1"; }

# 1. Without the scope.
"$LODE" run "$TMP/swap.yaml" --clock real --duration "$SECONDS_RUN" --summary-json "$TMP/alone.json" >"$TMP/alone.out" 2>&1
echo "without scope: exit $?; overruns, missed periods, wake p99 [us]: $(overruns "$TMP/alone.json")"

# 2. With the scope and its page.
"$LODE" run "$TMP/swap.yaml" --clock real --duration "$SECONDS_RUN" --summary-json "$TMP/scoped.json" >"$TMP/scoped.out" 2>&1 &
RUN=$!; PIDS+=($RUN)
"$LODE" scope --domain "$DOMAIN" --listen 127.0.0.1:0 >"$TMP/scope.out" 2>"$TMP/scope.err" &
SCOPE=$!; PIDS+=($SCOPE)
for _ in $(seq 1 100); do URL=$(grep -o 'http://[^ ]*' "$TMP/scope.out") && break; sleep 0.1; done
shot_args=(); [ -n "$SHOT" ] && shot_args=(--screenshot "$SHOT")
node "$PAGE" --url "$URL" --ready 'window.lodeScope !== undefined' --script "$SRC/tests/scope/scope_page_checks.js" \
  --eval "scopeChecks({signals: 10, window: 10, seconds: 5, hold: 12})" --timeout 120 "${shot_args[@]}" \
  >"$TMP/page.json" 2>"$TMP/page.err" &
NODE=$!; PIDS+=($NODE)
# The page is attached once it has asked for a topic; then 10 s of the server's CPU time.
for _ in $(seq 1 300); do
  "$PY" -c 'import json,sys,urllib.request; c=json.load(urllib.request.urlopen(sys.argv[1]+"api/counters")); sys.exit(0 if c["pages"] and c["topics_watched"] >= 5 else 1)' "$URL" 2>/dev/null && break
  sleep 0.1
done
sleep 12  # past the window filling: the page draws whole 10 s windows from here on
ticks() { awk '{ print $14 + $15 }' "/proc/$SCOPE/stat"; }
t0=$(ticks); s0=$EPOCHREALTIME
sleep 10
t1=$(ticks); s1=$EPOCHREALTIME
cpu=$(awk -v a="$t0" -v b="$t1" -v s="$s0" -v e="$s1" -v hz="$(getconf CLK_TCK)" 'BEGIN { printf "%.1f", 100 * (b - a) / hz / (e - s) }')
wait $NODE
"$PY" - "$TMP/page.json" <<'EOF'
import json, sys
page = json.load(open(sys.argv[1]))
v = json.loads(page["value"]) if page["value"] else {}
print("page errors:", page["errors"] or "none")
print("page: %d signals, %.0f s window, %.1f frames/s over %.1f s, %d points per series drawn" %
      (len(v.get("selected", [])), v.get("window_s", 0), v.get("fps", 0), v.get("seconds", 0), v.get("plotted_points", 0)))
for topic, r in v.get("rates", {}).items():
    print("  %s: %.0f samples/s received (%s Hz topic)" % (topic, r["received_hz"], r["topic_hz"]))
print("  scope drops:", v.get("status", {}).get("scope_dropped"))
EOF
echo "scope server CPU: $cpu % of one core over 10 s with the page attached"
wait $RUN
echo "with scope: exit $?; overruns, missed periods, wake p99 [us]: $(overruns "$TMP/scoped.json")"
grep -iE "warn|cannot|could not" "$TMP/alone.out" | head -3
