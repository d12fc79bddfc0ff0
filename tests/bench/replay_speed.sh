#!/usr/bin/env bash
# How fast `lode replay` runs a recording: records DURATION seconds of kawato_planar (simulated
# clock) once, replays it RUNS times, and prints each run's speed as `lode replay` reports it
# (recorded cycles / wall time of the replayed cycles and of writing and closing the replay's
# file) and as the whole command (starting lode, reading the recording once, the run, reading
# the replay's file back for the bit-for-bit check), then the medians.
# usage: tests/bench/replay_speed.sh [BUILD_DIR] [DURATION_S] [RUNS]
set -u
BUILD=${1:-build}
DURATION=${2:-30}
RUNS=${3:-5}
SRC=$(cd "$(dirname "$0")/../.." && pwd)
LODE=$BUILD/apps/lode
export LODE_PLUGIN_PATH=$BUILD/plugins
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
export XDG_RUNTIME_DIR=$TMP/run && mkdir -m 700 "$XDG_RUNTIME_DIR"
"$LODE" run "$SRC/config/kawato_planar.yaml" --duration "$DURATION" --no-telemetry --no-local-control --quiet \
  --record "$TMP/rec.h5" > "$TMP/run.txt" 2>&1 || { cat "$TMP/run.txt"; echo "lode run --record failed"; exit 1; }
echo "recorded ${DURATION} s of kawato_planar: $(du -h "$TMP/rec.h5" | cut -f1)"
runs=() commands=()
for i in $(seq "$RUNS"); do
  start=$(date +%s.%N)
  "$LODE" replay "$TMP/rec.h5" --quiet > "$TMP/replay.txt" 2>&1 || { cat "$TMP/replay.txt"; echo "replay $i failed"; exit 1; }
  end=$(date +%s.%N)
  grep -q "^bit-identical" "$TMP/replay.txt" || { cat "$TMP/replay.txt"; echo "replay $i not bit-identical"; exit 1; }
  run=$(sed -n 's/.*cycles in [0-9.]* s wall, \([0-9.]*\)x real time.*/\1/p' "$TMP/replay.txt" | head -1)
  command=$(awk -v d="$DURATION" -v s="$start" -v e="$end" 'BEGIN { printf "%.0f", d / (e - s) }')
  echo "replay $i: ${run}x real time (replayed cycles), ${command}x (whole command)"
  runs+=("$run") commands+=("$command")
done
median() { printf '%s\n' "$@" | sort -n | awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }
echo "median of $RUNS: $(median "${runs[@]}")x real time (replayed cycles), $(median "${commands[@]}")x (whole command)"
