#!/usr/bin/env bash
# How soon a late joiner hears a running pipeline: `lode run` kawato_planar (real clock),
# then TRIES times `lode echo kf.pose --count 1`, each a fresh process that must discover
# the pipeline, get the transient-local metadata (lode/signals) and take one sample. Prints
# each try's time from process start to its first sample line and to its exit, and how
# many first samples came within 300 ms.
# usage: tests/bench/late_joiner.sh [BUILD_DIR] [TRIES]
set -u
BUILD=$(cd "${1:-build}" && pwd)
TRIES=${2:-20}
SRC=$(cd "$(dirname "$0")/../.." && pwd)
source "$SRC/tests/integration/test_lib.sh"
take_private_domain
LODE=$BUILD/apps/lode
export LODE_PLUGIN_PATH=$BUILD/plugins
sed -e "s/^  domain: 0/  domain: $DOMAIN/" "$SRC/config/kawato_planar.yaml" >"$TMP/p.yaml"
"$LODE" run "$TMP/p.yaml" --clock real --duration 600 --quiet >"$TMP/run.log" 2>&1 &
RUN=$!
PIDS+=("$RUN")
"$LODE" echo kf.pose --domain "$DOMAIN" --count 1 --wait 30 >/dev/null 2>"$TMP/first.err" \
  || { echo "the pipeline did not come up:"; cat "$TMP/first.err" "$TMP/run.log"; exit 1; }
within=0
firsts=()
for ((i = 1; i <= TRIES; i++)); do
  t0=$(date +%s%N)
  # Line-buffered, so the first sample line is seen when it is printed, not at exit.
  first=$(stdbuf -oL "$LODE" echo kf.pose --domain "$DOMAIN" --count 1 --wait 10 2>"$TMP/echo.err" |
    { while IFS= read -r line; do case $line in '#'*) ;; *) date +%s%N; break ;; esac; done; cat >/dev/null; })
  rc=${PIPESTATUS[0]}
  t1=$(date +%s%N)
  if [ -n "$first" ]; then ms=$(((first - t0) / 1000000)); else ms=none; fi
  firsts+=("${ms/none/99999}")
  [ "$rc" -eq 0 ] && [ "$ms" != none ] && [ "$ms" -le 300 ] && within=$((within + 1))
  echo "try $i: first sample after ${ms} ms, exit after $(((t1 - t0) / 1000000)) ms (exit $rc)"
done
kill -INT "$RUN"; wait "$RUN"
sorted=$(printf '%s\n' "${firsts[@]}" | sort -n)
echo "late joiner: $within of $TRIES first samples within 300 ms; median $(echo "$sorted" | sed -n "$(((TRIES + 1) / 2))p") ms, max $(echo "$sorted" | tail -1) ms"
[ "$within" -eq "$TRIES" ]
