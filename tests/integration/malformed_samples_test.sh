#!/usr/bin/env bash
# Malformed DDS samples (an XCDR2 encapsulation, a truncated body, a length of 2^31, a
# string without its terminator, a boolean that is 2) written by a foreign participant under
# lodestone's type names, to a running pipeline's command topic and to a `lode echo`'s
# signal and metadata topics. Both processes must survive them, keep working (the pipeline
# answers a valid get and set afterwards, echo goes on printing the pipeline's samples) and
# count them: the pipeline in its summary and an event, echo on exit.
# usage: malformed_samples_test.sh LODE SRC MALFORMED_SENDER
set -u
LODE=$1 SRC=$2 SENDER=$3
source "$(dirname "$0")/test_lib.sh"
take_private_domain

# kawato_planar on the real clock at a low telemetry rate, commands open to this host, and
# reliable signal topics: every malformed sample the sender writes reaches echo's reader
# (best effort would lose those written before the reader has matched the sender).
sed -e "s/^realtime: .*/realtime: { overrun_policy: catch_up }/" \
    -e "s/^  rate_hz: 800 .*/  rate_hz: 100/" \
    -e "s/^  domain: 0/  domain: $DOMAIN\n  reliability: reliable/" "$SRC/config/kawato_planar.yaml" >"$TMP/p.yaml"
grep -q "^  reliability: reliable" "$TMP/p.yaml" || { echo "FAIL: test setup (sed)"; exit 1; }
PIPE=kawato_planar
"$LODE" run "$TMP/p.yaml" --clock real --duration 120 --summary-json "$TMP/run.json" >"$TMP/run.out" 2>&1 &
PIDS+=($!); RUN=$!
"$LODE" echo kf.pose --domain "$DOMAIN" --wait 60 --duration 120 >"$TMP/echo.out" 2>"$TMP/echo.err" &
PIDS+=($!); ECHO=$!

samples() { grep -vc '^#' "$TMP/echo.out"; }
# wait_for_samples N: until echo has printed more than N samples (up to 60 s).
wait_for_samples() {
  for _ in $(seq 1 300); do [ "$(samples)" -gt "$1" ] && return 0; sleep 0.2; done
  return 1
}
wait_for_samples 10 && ok "echo prints the pipeline's samples" || { bad "echo printed no samples"; cat "$TMP/echo.err"; exit 1; }

"$SENDER" "$DOMAIN" command "lode/$PIPE/command" >"$TMP/s1.out" 2>&1
check_rc "4 malformed commands written and acknowledged" 0 $? "$TMP/s1.out"
"$SENDER" "$DOMAIN" sample "lode/$PIPE/kf/pose" >"$TMP/s2.out" 2>&1
check_rc "3 malformed signal samples written" 0 $? "$TMP/s2.out"
"$SENDER" "$DOMAIN" info "lode/signals" >"$TMP/s3.out" 2>&1
check_rc "1 malformed SignalInfo written" 0 $? "$TMP/s3.out"

kill -0 $RUN 2>/dev/null && ok "lode run survived the malformed commands" \
  || { bad "lode run died"; tail -5 "$TMP/run.out"; }
kill -0 $ECHO 2>/dev/null && ok "lode echo survived the malformed samples" \
  || { bad "lode echo died"; tail -5 "$TMP/echo.err"; }

# The pipeline still obeys: a valid get, and a set of the same value (nothing changes).
L="$LODE"; D=(--dds --domain "$DOMAIN" --wait 20 --timeout 10)
"$L" set --list "${D[@]}" >"$TMP/list.out" 2>&1; check_rc "list runtime parameters afterwards" 0 $? "$TMP/list.out"
param=$(awk 'NF && $1 ~ /^[a-z_0-9]+\.[a-z_0-9]+$/ {print $1; exit}' "$TMP/list.out")
value=$("$L" set "$param" "${D[@]}" 2>"$TMP/get.err" | sed -n 's/^ok: .* = \([^ ]*\).*/\1/p')
[ -n "$param" ] && [ -n "$value" ] && ok "get $param afterwards ($value)" || { bad "get '$param' afterwards"; cat "$TMP/get.err" "$TMP/list.out" | tail -20; }
"$L" set "$param" "$value" "${D[@]}" >"$TMP/set.out" 2>&1; check_rc "set $param afterwards" 0 $? "$TMP/set.out"

# echo goes on: more samples after the malformed ones.
now=$(samples)
wait_for_samples $((now + 20)) && ok "echo still prints samples ($now, then more)" || bad "echo stopped printing after $now samples"

"$L" echo events --pipeline $PIPE --domain "$DOMAIN" --wait 10 --duration 3 >"$TMP/ev.out" 2>&1
# One event per look of the command thread: the last one has the total.
contains "the malformed commands are an event" "$TMP/ev.out" "\[command_malformed\] [1-3] malformed command sample.*\(3 since start\)"

kill -TERM $RUN; wait $RUN; check_rc "run stopped by SIGTERM" 0 $? "$TMP/run.out"
wait $ECHO; check_rc "echo ends with the pipeline" 0 $? "$TMP/echo.err"
# Exactly the three Fast CDR rejects: the unterminated string decodes (as the string without
# it) and is a valid status command from then on.
$PY -c "import json;t=json.load(open('$TMP/run.json'))['telemetry'];assert t['commands_malformed']==3,t" \
  && ok "summary counts 3 malformed commands" || bad "summary telemetry: $($PY -c "import json;print(json.load(open('$TMP/run.json')).get('telemetry'))" 2>&1)"
contains "run's summary warns of them" "$TMP/run.out" "WARNING: 3 malformed command samples dropped"
contains "echo says on exit what it dropped (3 samples + 1 SignalInfo)" "$TMP/echo.err" "^lode echo: 4 malformed samples dropped"
contains "echo's own summary is unchanged" "$TMP/echo.err" "^lode echo: [0-9]+ samples, cycles"
exit $fail
