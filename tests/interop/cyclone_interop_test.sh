#!/usr/bin/env bash
# lodestone's topics from Cyclone DDS: a running pipeline (Fast DDS, transport loopback) and
# cyclone_peer (Cyclone DDS 0.10, types from the same lode_msgs.idl, configured by the sample
# CYCLONEDDS_URI of docs/telemetry.md, taken from the page itself) on a private domain:
#   - every sample of one signal and of the state that both saw is the same, by cycle, in
#     cyclone_peer's output and in `lode echo`'s, and all arrived as plain CDR (XCDR1);
#   - the metadata (lode/signals) reaches it, keyed by XXH64 of the topic name;
#   - its `set` is applied (the reply, `lode set`'s get, the parameter event naming it) and
#     its `get` answers the new value;
#   - when the pipeline stops, it sees every metadata instance disposed.
# usage: cyclone_interop_test.sh LODE SRC CYCLONE_PEER (empty: Cyclone DDS missing, exit 77)
set -u
LODE=$1 SRC=$2 PEER=${3:-}
if [ -z "$PEER" ] || [ ! -x "$PEER" ]; then
  echo "SKIP: cyclone_peer was not built: Cyclone DDS is missing (apt-get install cyclonedds-dev cyclonedds-tools)"
  exit 77
fi
source "$SRC/tests/integration/test_lib.sh"
take_private_domain

# wait_for FILE REGEX SECONDS PID: until FILE has a line matching REGEX, PID exits, or time is up.
wait_for() {
  local deadline=$((SECONDS + $3))
  while [ $SECONDS -lt $deadline ]; do
    grep -qE -e "$2" "$1" 2>/dev/null && return 0
    kill -0 "$4" 2>/dev/null || { grep -qE -e "$2" "$1" 2>/dev/null; return; }
    sleep 0.2
  done
  return 1
}
# wait_exit PID SECONDS: its exit code, or 124 (and killed) when it outlives SECONDS.
wait_exit() {
  local deadline=$((SECONDS + $2))
  while kill -0 "$1" 2>/dev/null && [ $SECONDS -lt $deadline ]; do sleep 0.2; done
  kill -0 "$1" 2>/dev/null && { kill "$1"; wait "$1" 2>/dev/null; return 124; }
  wait "$1"
}

# The Cyclone DDS configuration users are given is the one tested.
$PY - "$SRC/docs/telemetry.md" >"$TMP/cyclonedds.xml" <<'PY' || { echo "FAIL: no cyclonedds.xml block in docs/telemetry.md"; exit 1; }
import re, sys
page = open(sys.argv[1], encoding="utf-8").read()
m = re.search(r"<!-- cyclonedds\.xml -->\n```xml\n(.*?)\n```", page, re.S)
sys.exit(1) if not m else print(m.group(1))
PY
export CYCLONEDDS_URI="file://$TMP/cyclonedds.xml"

# kawato_planar on the real clock without real-time privileges (catch_up: every cycle runs),
# commands allowed from this host to the Cyclone program and to our checks, by name.
sed -e "s/^realtime: .*/realtime: { overrun_policy: catch_up }/" \
    -e "s/^  domain: 0/  domain: $DOMAIN/" \
    -e "s/^    allow_hosts: \[127.0.0.1\].*$/&\n    allow_participants: [cyclone-peer, lode-check]/" \
    "$SRC/config/kawato_planar.yaml" >"$TMP/p.yaml"
grep -q "allow_participants: \[cyclone-peer" "$TMP/p.yaml" || { echo "FAIL: test set-up (sed)"; exit 1; }
D=(--domain "$DOMAIN")

"$LODE" run "$TMP/p.yaml" --clock real --duration 120 --quiet >"$TMP/run.out" 2>&1 &
PIDS+=($!); RUN=$!
"$LODE" set --list --wait 30 "${D[@]}" --name lode-check >/dev/null 2>&1; check_rc "pipeline up" 0 $?

# lode's own readers first, so that they hear every cycle cyclone_peer hears.
"$LODE" echo kf.pose "${D[@]}" --wait 30 >"$TMP/echo_signal.out" 2>"$TMP/echo_signal.err" &
PIDS+=($!); ECHO_SIGNAL=$!
"$LODE" echo state "${D[@]}" --wait 30 >"$TMP/echo_state.out" 2>"$TMP/echo_state.err" &
PIDS+=($!); ECHO_STATE=$!
wait_for "$TMP/echo_signal.out" "^[0-9]" 60 $ECHO_SIGNAL && wait_for "$TMP/echo_state.out" "^[0-9]" 60 $ECHO_STATE \
  || bad "lode echo received nothing"

mkdir "$TMP/peer"
"$PEER" "$DOMAIN" kawato_planar lode/kawato_planar/kf/pose 800 "$TMP/peer" ref offset.x 2e-05 \
  >"$TMP/peer.out" 2>"$TMP/peer.err" &
PIDS+=($!); PEER_PID=$!
wait_for "$TMP/peer.out" "^awaiting-dispose" 150 $PEER_PID \
  || { bad "cyclone_peer did not get through reading and commanding"; sed 's/^/    /' "$TMP/peer.err" "$TMP/peer.out" | tail -20; }

contains "cyclone_peer: signal and state samples, all plain CDR" "$TMP/peer.out" \
  "^collected [0-9]+ signal and [0-9]+ state samples, encapsulation CDR_LE"
contains "cyclone_peer: kf.pose metadata, keyed by XXH64 of the name" "$TMP/peer.out" \
  "^info [0-9a-f]{16} lode/kawato_planar/kf/pose signal best_effort key=xxh64 x\[m\] y\[m\] theta_z\[rad\]$"
contains "cyclone_peer: state metadata" "$TMP/peer.out" "^info [0-9a-f]{16} lode/kawato_planar/state state best_effort key=xxh64 "
if grep -q "key=WRONG" "$TMP/peer.out"; then bad "a topic_id is not XXH64 of its topic"; else ok "every topic_id is XXH64 of its topic"; fi
contains "cyclone_peer: set applied" "$TMP/peer.out" "^reply set ok ref\.offset\.x: 0 -> 2e-05 at cycle [0-9]+"
contains "cyclone_peer: get answers the new value" "$TMP/peer.out" "^reply get ok value=2e-05$"

# The pipeline says the same, to lode's own tools.
"$LODE" set ref.offset.x --dds "${D[@]}" --name lode-check --wait 10 --timeout 10 >"$TMP/get.out" 2>&1
contains "lode set (get over DDS) sees the value set from Cyclone" "$TMP/get.out" "^ok: ref\.offset\.x = 2e-05"
"$LODE" echo events --pipeline kawato_planar "${D[@]}" --wait 10 --duration 5 >"$TMP/events.out" 2>&1
contains "parameter event names the Cyclone participant" "$TMP/events.out" \
  "\[parameter\] ref\.offset\.x: 0 -> 2e-05 at cycle [0-9]+ \(by cyclone-peer\)"

# Stop the pipeline: its metadata must be disposed, and lode echo ends on its stop event.
kill -INT $RUN
wait_exit $RUN 60; check_rc "lode run stopped cleanly" 0 $? "$TMP/run.out"
wait_exit $PEER_PID 90; check_rc "cyclone_peer" 0 $? "$TMP/peer.err"
n=$(grep -c "^info " "$TMP/peer.out")
contains "every metadata instance ($n) disposed, seen by Cyclone" "$TMP/peer.out" "^disposed $n of $n metadata instances$"
[ "$n" -eq 7 ] && ok "7 topics (6 signals and the state)" || bad "$n metadata instances, expected 7"
wait_exit $ECHO_SIGNAL 30; check_rc "lode echo kf.pose" 0 $? "$TMP/echo_signal.err"
wait_exit $ECHO_STATE 30; check_rc "lode echo state" 0 $? "$TMP/echo_state.err"

# Same cycle, same line: cycle, time and every value to the last bit (%.17g).
for what in signal state; do
  $PY - "$TMP/peer/$what.txt" "$TMP/echo_$what.out" "$what" <<'PY' && ok "$what: Cyclone's samples equal lode echo's" || bad "$what: Cyclone and lode echo differ"
import sys
peer_file, echo_file, what = sys.argv[1:]
def lines(path):
    return {l.split()[0]: l.strip() for l in open(path) if l[:1].isdigit()}
peer, echo = lines(peer_file), lines(echo_file)
common = sorted(set(peer) & set(echo), key=int)
least = 400 if what == "signal" else 50
print(f"    {what}: Cyclone {len(peer)} samples, lode echo {len(echo)}, {len(common)} cycles in both")
assert len(common) >= least, f"only {len(common)} cycles in both (want {least})"
differ = [c for c in common if peer[c] != echo[c]]
assert not differ, f"{len(differ)} differ, first cycle {differ[0]}:\n  cyclone {peer[differ[0]]}\n  echo    {echo[differ[0]]}"
PY
done

[ $fail -eq 0 ] && echo "PASS" || echo "FAIL"
exit $fail
