#!/usr/bin/env bash
# Real-clock hot swaps: run config/kawato_planar_swap.yaml at 5 kHz on the real
# clock and swap kf Kalman <-> hybrid H2/Hinf over the local command socket every ~0.1 s;
# the run summary then says how many overruns fell in a swap cycle (or the next).
#
#   tests/bench/swap_realclock.sh [LODE] [CONFIG] [SECONDS]
#
# A measurement, not a test: it prints the summary's timing and hot-swap lines.
set -u
SRC=$(cd "$(dirname "$0")/../.." && pwd)
LODE=${1:-$SRC/build/apps/lode}
CONFIG=${2:-$SRC/config/kawato_planar_swap.yaml}
SECONDS_TO_RUN=${3:-40}
WORK=$(mktemp -d)
export XDG_RUNTIME_DIR=$WORK  # a private command socket
trap 'kill $run 2>/dev/null; rm -rf "$WORK"' EXIT
HYBRID='{q: [1.0e2, 1.0e2, 1.0e5], r: [2.2e-10, 2.2e-10, 9.6e-9], hinf_theta: 1.0e8, d: 0.5, output: predicted}'
KALMAN='{motion: constant_acceleration, q: [1.0e2, 1.0e2, 1.0e5], p0: 1.0e-8, r: [2.2e-10, 2.2e-10, 9.6e-9], output: predicted}'

"$LODE" run "$CONFIG" --clock real --duration "$SECONDS_TO_RUN" --no-telemetry --quiet \
  --summary-json "$WORK/summary.json" > "$WORK/run.txt" 2>&1 &
run=$!
sleep 1.5
ok=0 refused=0  # refused = failed while the run was still alive
while kill -0 $run 2>/dev/null; do
  for target in hybrid kalman; do
    if [ $target = hybrid ]; then plugin=estimator.hybrid_h2hinf params=$HYBRID
    else plugin=estimator.kalman params=$KALMAN; fi
    if "$LODE" swap --local kf $plugin --params "$params" >> "$WORK/swaps.txt" 2>&1; then ok=$((ok + 1))
    elif kill -0 $run 2>/dev/null; then refused=$((refused + 1)); fi
    sleep 0.05
  done
done
wait $run
rc=$?
grep -E "timing:|hot swap:|FAULT|warning" "$WORK/run.txt"
echo "lode run exit $rc; swaps done $ok, failed while it ran $refused"
grep -v "^ok:" "$WORK/swaps.txt" | sort | uniq -c | head -5
exit $rc
