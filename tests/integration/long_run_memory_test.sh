#!/usr/bin/env bash
# Memory of a long run does not grow with its length: `lode run` on the simulated clock for
# STAGE_S seconds of stage time, VmRSS sampled every 0.2 s of wall time. After the first minute
# of stage time (the analysis windows, histograms and buffers are then all allocated) RSS may
# grow by at most 1 MB, whatever the length: at the 200 bytes a cycle that runs used to keep,
# two hours at 800 Hz would add 1.1 GB.
#
#   long_run_memory_test.sh LODE SOURCE_DIR [STAGE_S]   (default 7200 s; 86400 s = a day)
set -u
LODE=$1 SRC=$2 STAGE_S=${3:-7200}
source "$(dirname "$0")/test_lib.sh"
"$LODE" run "$SRC/config/kawato_planar.yaml" --duration "$STAGE_S" --quiet --no-telemetry \
  --summary-json "$TMP/summary.json" >"$TMP/out.log" 2>&1 &
pid=$!
PIDS+=("$pid")
samples=$TMP/rss.txt
start=$(date +%s.%N)
while kill -0 "$pid" 2>/dev/null; do
  rss=$(awk '/^VmRSS:/ {print $2}' "/proc/$pid/status" 2>/dev/null) || true
  [ -n "$rss" ] && echo "$(date +%s.%N) $rss" >>"$samples"
  sleep 0.2
done
wait "$pid"
check_rc "lode run for $STAGE_S s of stage time" 0 $? "$TMP/out.log"
# The stage time of each sample, from the wall time and the run's own simulated/wall ratio.
$PY - "$samples" "$TMP/summary.json" "$start" <<'PYEOF' || fail=1
import json, sys
samples = [tuple(map(float, l.split())) for l in open(sys.argv[1]) if l.strip()]
summary = json.load(open(sys.argv[2]))
start = float(sys.argv[3])
timing = summary["timing"]
stage_s = timing["scheduled_s"]
wall = samples[-1][0] - start if samples else 0.0
speed = stage_s / wall if wall > 0 else 0.0
after_minute = [(t, kb) for t, kb in samples if (t - start) * speed >= 60.0]
if len(after_minute) < 5:
    print(f"FAIL: only {len(after_minute)} RSS samples after the first minute of stage time"); sys.exit(1)
base = after_minute[0][1]
peak = max(kb for _, kb in after_minute)
growth_mb = (peak - base) / 1024.0
print(f"stage time {stage_s:.0f} s in {wall:.1f} s wall ({speed:.0f}x); RSS at 1 min {base / 1024:.1f} MB, "
      f"peak after {peak / 1024:.1f} MB, growth {growth_mb:.2f} MB over {len(after_minute)} samples")
if growth_mb > 1.0:
    print("FAIL: RSS grew more than 1 MB after the first minute"); sys.exit(1)
print("ok: RSS flat after the first minute")
PYEOF
[ "$fail" = 0 ] && echo "1 passed, 0 failed" || echo "0 passed, 1 failed"
exit $fail
