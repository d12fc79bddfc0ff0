#!/usr/bin/env bash
# A late joiner after a client that was killed: `lode run` kawato_planar (real clock), then
# TRIES times a `lode echo kf.pose` killed with SIGKILL 1.5 s after it started, followed by
# a fresh `lode echo kf.pose --count 1`, which gets the killed one's shared-memory port
# number. Prints the fresh one's time from process start to its first sample line.
# usage: tests/bench/late_joiner_after_kill.sh [BUILD_DIR] [TRIES] [TRANSPORT]
set -u
BUILD=$(cd "${1:-build}" && pwd)
TRIES=${2:-5}
TRANSPORT=${3:-loopback}
SRC=$(cd "$(dirname "$0")/../.." && pwd)
source "$SRC/tests/integration/test_lib.sh"
take_private_domain
LODE=$BUILD/apps/lode
export LODE_PLUGIN_PATH=$BUILD/plugins
sed -e "s/^  domain: 0/  domain: $DOMAIN/" -e "s/^  transport: .*/  transport: $TRANSPORT/" \
    "$SRC/config/kawato_planar.yaml" >"$TMP/p.yaml"
"$LODE" run "$TMP/p.yaml" --clock real --duration 600 --quiet >"$TMP/run.log" 2>&1 &
RUN=$!
PIDS+=("$RUN")
"$LODE" echo kf.pose --domain "$DOMAIN" --transport "$TRANSPORT" --count 1 --wait 30 >/dev/null 2>"$TMP/first.err" \
  || { echo "the pipeline did not come up:"; cat "$TMP/first.err" "$TMP/run.log"; exit 1; }
for ((i = 1; i <= TRIES; i++)); do
  "$LODE" echo kf.pose --domain "$DOMAIN" --transport "$TRANSPORT" --duration 30 >/dev/null 2>&1 &
  victim=$!
  sleep 1.5
  kill -KILL "$victim"; wait "$victim" 2>/dev/null
  t0=$(date +%s%N)
  first=$(stdbuf -oL "$LODE" echo kf.pose --domain "$DOMAIN" --transport "$TRANSPORT" --count 1 --wait 10 2>/dev/null |
    { while IFS= read -r line; do case $line in '#'*) ;; *) date +%s%N; break ;; esac; done; cat >/dev/null; })
  if [ -n "$first" ]; then echo "try $i: first sample after $(((first - t0) / 1000000)) ms"; else echo "try $i: no sample"; fi
done
kill -INT "$RUN"; wait "$RUN"
