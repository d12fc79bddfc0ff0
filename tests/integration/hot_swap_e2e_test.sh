#!/usr/bin/env bash
# Hot swap, promotion and the health fallback end to end, with separate processes:
# `lode run config/kawato_planar_swap.yaml` on the real clock with telemetry on its own DDS
# domain; `lode swap` over the local socket (Kalman -> hybrid), `lode swap --promote`, then
# `lode set stage.inject_nan_channel 0` (a Hall channel turns NaN). Checks the replies, that the
# health trip and the fallback are in the recording's events (HDF5) and were published on the
# events topic (`lode echo events`), and the run summary's swap count.
# usage: hot_swap_e2e_test.sh LODE SRC
set -u
LODE=$1 SRC=$2
source "$(dirname "$0")/test_lib.sh"
take_private_domain

# Own domain; no SCHED_FIFO (CI shares two cores); long enough for the commands below.
sed -e "s/^  domain: 0/  domain: $DOMAIN/" -e "s/^realtime: .*/realtime: { overrun_policy: skip }/" \
  "$SRC/config/kawato_planar_swap.yaml" >"$TMP/swap.yaml"
HYBRID='{q: [1.0e2, 1.0e2, 1.0e5], r: [2.2e-10, 2.2e-10, 9.6e-9], hinf_theta: 1.0e8, d: 0.5, output: predicted}'

# No --pipeline: echo follows every pipeline it hears and ends when they have stopped.
"$LODE" echo events --domain "$DOMAIN" --wait 60 --duration 90 >"$TMP/events.out" 2>&1 &
PIDS+=($!); ECHO=$!
"$LODE" run "$TMP/swap.yaml" --clock real --duration 12 --record "$TMP/rec.h5" \
  --summary-json "$TMP/run.json" >"$TMP/run.out" 2>&1 &
PIDS+=($!); RUN=$!

# Wait for the local socket, then let the run get going (events are transient-local: the
# echo gets them whenever it matches).
for _ in $(seq 1 300); do
  "$LODE" set --local --list stage >/dev/null 2>&1 && break
  sleep 0.2
done
sleep 1

"$LODE" swap --local kf estimator.hybrid_h2hinf --params "$HYBRID" >"$TMP/swap.out" 2>&1
check_rc "swap kf -> hybrid over the local socket" 0 $? "$TMP/swap.out"
contains "swap reply: state handed over, jump and RT cost" "$TMP/swap.out" \
  "^ok: swapped kf: estimator.kalman -> estimator.hybrid_h2hinf at cycle [0-9]+ \(state handed over: 9 of 9 elements.*jump of kf.pose: x .*RT cost [0-9]+ ns"

"$LODE" swap --local --promote kf_hybrid >"$TMP/promote.out" 2>&1
check_rc "promote kf_hybrid" 0 $? "$TMP/promote.out"
contains "promote reply" "$TMP/promote.out" "^ok: promoted kf_hybrid at cycle [0-9]+"

"$LODE" swap --local kf estimator.no_such_plugin >"$TMP/refused.out" 2>&1
check_rc "a missing plugin is refused" 1 $? "$TMP/refused.out"
contains "refusal says why and that the incumbent runs on" "$TMP/refused.out" "no plugin named 'estimator.no_such_plugin'.*unchanged|keeps running"

"$LODE" set --local stage.inject_nan_channel 0 >"$TMP/nan.out" 2>&1
check_rc "inject NaN on a Hall channel" 0 $? "$TMP/nan.out"

# The fallback takes over in the cycle of the trip; the NaN stays, so kf_coast runs on
# prediction alone, and the envelope (glsdc.pose: max_invalid_s 0.05) ends that after 50 ms
# with the outputs driven safe: a stage must not coast away (unbounded, it did).
wait $RUN; check_rc "the run faults once the fallback has coasted its envelope's 0.05 s" 1 $? "$TMP/run.out"
contains "the fault names the envelope" "$TMP/run.out" "envelope: glsdc.pose has been invalid \(non-finite\) for [0-9.]+ ms, longer than its max_invalid_s of 50 ms"
# The run has ended; its stop event ends the echo within a second (not at --duration 90).
for _ in $(seq 1 100); do kill -0 $ECHO 2>/dev/null || break; sleep 0.1; done
if kill -0 $ECHO 2>/dev/null; then echo "FAIL: lode echo events did not end with the pipeline"; fail=1; kill $ECHO; fi
wait $ECHO

contains "published: the swap" "$TMP/events.out" "\[swap\] swapped kf: estimator.kalman -> estimator.hybrid_h2hinf"
contains "published: the promotion" "$TMP/events.out" "\[swap\] promoted kf_hybrid"
contains "published: the health trip and the fallback" "$TMP/events.out" \
  "\[health\] health monitor: kf tripped at cycle [0-9]+ \(non-finite .*fallback kf_coast took over in the same cycle"

$PY - "$TMP/rec.h5" "$TMP/run.json" <<'PY' || bad "recording and summary"
import sys, json, h5py
f = h5py.File(sys.argv[1], "r")
ev = f["events"]
kinds = [k.decode() if isinstance(k, bytes) else str(k) for k in ev["kind"][:]]
texts = [t.decode() if isinstance(t, bytes) else str(t) for t in ev["text"][:]]
health = [t for k, t in zip(kinds, texts) if k == "health"]
assert health and "fallback kf_coast took over in the same cycle" in health[0], (kinds, texts)
assert sum(k == "swap" for k in kinds) >= 2, kinds
s = json.load(open(sys.argv[2]))
assert s["hot_swap"]["swaps"] >= 2, s["hot_swap"]
print("recorded events:", ", ".join(sorted(set(kinds))), "; summary hot_swap:", s["hot_swap"])
PY
[ $fail -eq 0 ] && echo PASS
exit $fail
