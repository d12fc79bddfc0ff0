#!/usr/bin/env bash
# Late joiners: fresh `lode echo kf.pose --count 1` processes beside a running kawato_planar
# (real clock) each print their first sample within 2 s of starting. Generous on purpose
# (this host is shared): it fails when a late joiner has to wait for a periodic event
# instead of being answered, e.g. Fast DDS's 3 s participant announcement or reliable
# HEARTBEAT period; tests/bench/late_joiner.sh measures the figure (300 ms).
# Before the tries, deterministically: the pipeline's shared-memory ports (and the first
# echo's) make a newcomer that opens one while its health check fails sleep at most 50 ms
# before the next check (Fast DDS's default made it 333 ms, for 2 or 3 late joiners in 20).
# usage: late_joiner_test.sh LODE SRC [TRIES]
set -u
LODE=$1 SRC=$2 TRIES=${3:-6}
source "$(dirname "$0")/test_lib.sh"
take_private_domain

sed -e "s/^  domain: 0/  domain: $DOMAIN/" -e "s/^realtime: .*/realtime: { overrun_policy: catch_up }/" \
    "$SRC/config/kawato_planar.yaml" >"$TMP/p.yaml"
# Ports made from here on are this test's: the domain is private, but a process that used it
# before (and died, or ran an older build) may have left its port files in /dev/shm, which the
# pipeline would take over as they are (their times and settings those of that process).
"$PY" "$(dirname "$0")/shm_port_settings.py" --remove-stale "$DOMAIN" >"$TMP/stale.txt"
STARTED=$(date +%s.%N)
"$LODE" run "$TMP/p.yaml" --clock real --duration 300 --quiet >"$TMP/run.log" 2>&1 &
RUN=$!
PIDS+=("$RUN")
"$LODE" echo kf.pose --domain "$DOMAIN" --count 1 --wait 60 >/dev/null 2>"$TMP/first.err"
check_rc "the pipeline is up (a first echo got a sample)" 0 $? "$TMP/first.err"

"$PY" "$(dirname "$0")/shm_port_settings.py" "$DOMAIN" "$STARTED" >"$TMP/ports.txt"
if [ ! -s "$TMP/ports.txt" ]; then
  bad "no shared-memory port of domain $DOMAIN in /dev/shm"
else
  while read -r port health_ms wake_ms; do
    if [ "$wake_ms" = unknown ]; then
      bad "shared-memory port $port: its health-check settings were not found (not Fast DDS 2.9's layout?)"
    elif [ "$wake_ms" -le 50 ]; then
      ok "shared-memory port $port: a failed health check is retried after $wake_ms ms (timeout $health_ms ms)"
    else
      bad "shared-memory port $port: a failed health check is retried after $wake_ms ms (timeout $health_ms ms), expected at most 50 ms"
    fi
  done <"$TMP/ports.txt"
fi

for ((i = 1; i <= TRIES; i++)); do
  t0=$(date +%s%N)
  # Line-buffered: the first sample line is seen when it is printed, not at exit.
  first=$(stdbuf -oL "$LODE" echo kf.pose --domain "$DOMAIN" --count 1 --wait 10 2>"$TMP/echo$i.err" |
    { while IFS= read -r line; do case $line in '#'*) ;; *) date +%s%N; break ;; esac; done; cat >/dev/null; })
  rc=${PIPESTATUS[0]}
  if [ -z "$first" ]; then
    bad "try $i: no sample (exit $rc)"; sed 's/^/    /' "$TMP/echo$i.err"
    continue
  fi
  ms=$(((first - t0) / 1000000))
  if [ "$rc" -eq 0 ] && [ "$ms" -le 2000 ]; then ok "try $i: first sample after $ms ms"
  else bad "try $i: first sample after $ms ms (exit $rc), expected within 2000 ms"; fi
done

kill -INT "$RUN"; wait "$RUN"; check_rc "run stops cleanly" 0 $? "$TMP/run.log"
exit $fail
