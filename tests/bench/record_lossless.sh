#!/usr/bin/env bash
# Lossless local recording: `lode record` of every published signal of kawato_planar
# (800 Hz, the real clock, its RT settings) for SECONDS, with the loop beside it on this
# host, RUNS times. Each run: the recorder waits, the pipeline starts once its 7 readers
# (6 signals + state) are matched, and the recording must hold every cycle of every series
# with the recorder's own count of missing samples at 0 and as many samples as the pipeline
# published. The loop catches up on overruns instead of skipping periods (kawato_planar's
# `skip`): a skipped period publishes nothing, and the recorder rightly counts it as a gap,
# which on a loaded host would hide what this measures, the way from the rings to the file.
# usage: tests/bench/record_lossless.sh [BUILD_DIR] [RUNS] [SECONDS]
set -u
BUILD=$(cd "${1:-build}" && pwd)
RUNS=${2:-5}
SECONDS_RUN=${3:-60}
SRC=$(cd "$(dirname "$0")/../.." && pwd)
source "$SRC/tests/integration/test_lib.sh"
take_private_domain
LODE=$BUILD/apps/lode
export LODE_PLUGIN_PATH=$BUILD/plugins
sed -e "s/^  domain: 0/  domain: $DOMAIN/" -e "s/overrun_policy: skip/overrun_policy: catch_up/" \
  "$SRC/config/kawato_planar.yaml" >"$TMP/p.yaml"
grep -q "overrun_policy: catch_up" "$TMP/p.yaml" || { echo "setup: kawato_planar.yaml has no overrun_policy: skip"; exit 1; }
cycles=$((SECONDS_RUN * 800))
# Datagrams the kernel dropped for a full receive buffer, on the whole host (other processes
# count too): where a loss on UDP shows up.
udp_buffer_drops() { awk '/^Udp:/ && $6 ~ /^[0-9]+$/ {print $6}' /proc/net/snmp; }
lossless=0
for ((i = 1; i <= RUNS; i++)); do
  rm -f "$TMP/rec.h5"
  drops_before=$(udp_buffer_drops)
  "$LODE" record "$TMP/rec.h5" --domain "$DOMAIN" --wait 60 >"$TMP/rec.out" 2>&1 &
  REC=$!
  PIDS+=("$REC")
  "$LODE" run "$TMP/p.yaml" --clock real --duration "$SECONDS_RUN" --wait-subscribers 7 --wait 60 --quiet \
    --summary-json "$TMP/run.json" >"$TMP/run.out" 2>&1
  run_rc=$?
  wait "$REC"
  rec_rc=$?
  missing=$(awk '/ missing$/ {m += $(NF-1)} END {print m + 0}' "$TMP/rec.out")
  samples=$(awk '/ missing$/ {s += $(NF-3)} END {print s + 0}' "$TMP/rec.out")
  if $PY "$SRC/tests/integration/check_recording.py" "$TMP/rec.h5" "$cycles" >"$TMP/check.out" 2>&1; then
    complete=complete
  else
    complete="INCOMPLETE: $(tr "\n" " " <"$TMP/check.out")"
  fi
  # Where a loss happened: the pipeline's rings (publisher too slow) or after the write.
  read -r published ring_dropped overruns < <($PY -c "import json; j = json.load(open('$TMP/run.json')); t = j['telemetry']; print(t['published'], t['ring_dropped'], j['timing']['overruns'])" 2>/dev/null || echo "? ? ?")
  sent="published $published, ring drops $ring_dropped, overruns $overruns; host UDP receive-buffer drops $(($(udp_buffer_drops) - drops_before))"
  [ "$published" = "$samples" ] && [ "$ring_dropped" = 0 ] && [ "$run_rc" -eq 0 ] && [ "$rec_rc" -eq 0 ] && [ "$missing" -eq 0 ] && [ "$complete" = complete ] \
    && lossless=$((lossless + 1))
  echo "run $i: $samples samples recorded, $missing missing (record exit $rec_rc, run exit $run_rc; pipeline: $sent), $complete"
done
echo "record lossless: $lossless of $RUNS runs lost nothing ($SECONDS_RUN s at 800 Hz each)"
[ "$lossless" -eq "$RUNS" ]
