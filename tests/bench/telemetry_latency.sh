#!/usr/bin/env bash
# Publish-to-receive latency on loopback with the default telemetry settings: `lode run`
# (real clock) publishes kf.pose every cycle; `lode echo --latency` in another process
# reports RT capture -> listener take, both CLOCK_MONOTONIC on one host. Runs at 1 kHz and
# 10 kHz, 10 s each. The RT thread's cost of waking the publisher is in
# lode_telemetry_bench (BM_DoorbellRing).
# usage: tests/bench/telemetry_latency.sh [BUILD_DIR] [DOMAIN]
set -u
BUILD=${1:-build}
DOMAIN=${2:-160}
SRC=$(cd "$(dirname "$0")/../.." && pwd)
LODE=$BUILD/apps/lode
export LODE_PLUGIN_PATH=$BUILD/plugins
TMP=$(mktemp -d)
echo_pid=
trap '[ -n "$echo_pid" ] && kill "$echo_pid" 2>/dev/null; rm -rf "$TMP"' EXIT
for rate in 1000 10000; do
  sed -e "s/^rate_hz: 800/rate_hz: $rate/" -e "s/^  rate_hz: 800 .*/  rate_hz: $rate/" \
      -e "s/^  publish: .*/  publish: [kf.pose]/" -e "s/^  domain: 0/  domain: $DOMAIN/" \
      -e "s/^realtime: .*/realtime: { priority: 80, cpu: 1, lock_memory: true, overrun_policy: catch_up }/" \
      "$SRC/config/kawato_planar.yaml" >"$TMP/p.yaml"
  if grep -q publish_period_ms "$TMP/p.yaml"; then echo "setup: the pipeline sets publish_period_ms"; exit 1; fi
  "$LODE" echo kf.pose --domain "$DOMAIN" --wait 30 --latency --quiet >/dev/null 2>"$TMP/echo.err" &
  echo_pid=$!
  "$LODE" run "$TMP/p.yaml" --clock real --duration 10 --wait-subscribers 1 --quiet >"$TMP/run.out" 2>&1
  wait $echo_pid
  echo_pid=
  echo "$rate Hz, default settings: $(grep latency "$TMP/echo.err") ; $(grep -o 'wake-up latency.*' "$TMP/run.out")"
done
