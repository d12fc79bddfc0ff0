#!/usr/bin/env bash
# The `lode` program end to end: exit codes 0 / 1 / 2, located messages, summary JSON.
set -u
LODE=$1
SRC=$2
source "$(dirname "$0")/test_lib.sh"  # TMP, our own command sockets, check_rc, contains

"$LODE" check "$SRC/config/kawato_planar.yaml" >"$TMP/check.out" 2>&1; check_rc "check valid" 0 $?
contains "check lists the cycle order" "$TMP/check.out" "stage.read glsdc kf ref ctrl stage.write"
if grep -q "warning" "$TMP/check.out"; then bad "the demo's reference stays inside its envelope"; else ok "no warning on the demo"; fi
# A reference the envelope does not let the stage follow: valid, but certain to fault at 2 s.
sed 's/value: \[100.0e-6, 0.0, 1.0e-3\]/value: [0.1, 0.0, 1.0e-3]/' "$SRC/config/kawato_planar.yaml" >"$TMP/far.yaml"
"$LODE" check "$TMP/far.yaml" >"$TMP/far.out" 2>&1; check_rc "check a reference beyond the envelope" 0 $? "$TMP/far.out"
contains "check warns that the reference leaves the envelope" "$TMP/far.out" \
  "far.yaml: warning: ref.out.x reaches 0.1 m at t = 2 s; the envelope keeps stage.truth.x within \[-0.08, 0.08\] m"
contains "... for the estimate too" "$TMP/far.out" "the envelope keeps kf.pose.x within \[-0.08, 0.08\] m"

"$LODE" describe "$SRC/config/kawato_planar.yaml" >"$TMP/describe.json" 2>&1; check_rc "describe" 0 $?
contains "describe has derived controller" "$TMP/describe.json" '"derived"'

sed 's/plugin: estimator.glsdc/plugin: estimator.glsdx/' "$SRC/config/kawato_planar.yaml" >"$TMP/bad.yaml"
"$LODE" run "$TMP/bad.yaml" >"$TMP/bad.out" 2>&1; check_rc "run invalid config" 2 $?
contains "invalid config names file:line:column" "$TMP/bad.out" "bad.yaml:[0-9]+:[0-9]+: blocks.glsdc.plugin: no plugin named 'estimator.glsdx' \(did you mean 'estimator.glsdc'\?\)"
# ... and only that: the Kalman filter reading glsdc.pose, and the controller reading the
# filter, would refuse their configuration for want of it; those echoes are not reported.
contains "one mistake, one problem" "$TMP/bad.out" "^lode: 1 problem in .*bad.yaml; nothing was started$"

"$LODE" run "$SRC/config/kawato_planar.yaml" --duration 1.5 --summary-json "$TMP/summary.json" >"$TMP/run.out" 2>&1
check_rc "run sim" 0 $?
contains "summary printed" "$TMP/run.out" "position noise std"
contains "summary json result" "$TMP/summary.json" '"result": "completed"'
contains "summary json steps" "$TMP/summary.json" '"rise_time_s"'

# A step that never rises or settles (a platen a thousand times too heavy, 0.5 s after the step)
# is said in words, not printed as "nan ms".
sed "s/mass_kg: 6.20$/mass_kg: 6200/" "$SRC/config/kawato_planar.yaml" >"$TMP/heavy.yaml"
grep -q "mass_kg: 6200$" "$TMP/heavy.yaml" || { echo "FAIL: the test could not make the platen heavy"; fail=1; }
"$LODE" run "$TMP/heavy.yaml" --duration 1.5 --no-telemetry >"$TMP/heavy.out" 2>&1; check_rc "run a step that never rises" 0 $?
contains "the step that never rose says so" "$TMP/heavy.out" \
  "step x +at 1\.000 s of \+100\.0 um: rise never \(did not reach 90 %\), .*settling \(\+-2\.00 um\) never,"
if grep -qi "nan" "$TMP/heavy.out"; then echo "FAIL: nan in the summary:"; grep -i nan "$TMP/heavy.out"; fail=1; else echo "ok: no nan in the summary"; fi

# lode record: a folder that does not exist is said so, before anything starts; with nothing to
# record, no empty file is left behind.
"$LODE" record "$TMP/nodir/x.h5" --duration 1 >"$TMP/nodir.out" 2>&1; check_rc "record into a missing folder" 2 $?
contains "record names the missing folder" "$TMP/nodir.out" "lode record: recording '.*/nodir/x.h5': cannot create the file: the folder .*/nodir does not exist$"
"$LODE" run "$SRC/config/kawato_planar.yaml" --record "$TMP/nodir/x.h5" --no-telemetry --quiet >"$TMP/run_nodir.out" 2>&1
check_rc "run --record into a missing folder" 1 $?
contains "run --record names the missing folder" "$TMP/run_nodir.out" "cannot create the file: the folder .*/nodir does not exist; nothing was started$"
take_private_domain
"$LODE" record "$TMP/none.h5" --duration 1 --wait 1 --domain "$DOMAIN" >"$TMP/none.out" 2>&1
check_rc "record with no pipeline on the domain" 1 $?
contains "record says nothing was written" "$TMP/none.out" "nothing to record: .*none.h5 not written"
[ ! -e "$TMP/none.h5" ] && ok "no empty recording left behind" || bad "an empty $TMP/none.h5 was left behind"
# No pipeline to command is a fault (1), as for echo and record; naming none among several is
# the usage error (2).
"$LODE" set ref.offset.x 1 --dds --wait 1 --domain "$DOMAIN" >"$TMP/set_none.out" 2>&1
check_rc "set with no pipeline on the domain" 1 $? "$TMP/set_none.out"
contains "set says no pipeline is publishing" "$TMP/set_none.out" "^lode: no pipeline is publishing on this domain"

# The summary of the full demo is the README's table (the default duration, seed 1, the
# simulated clock: deterministic). kawato_planar_test checks these figures against the
# design's model; here the CLI's own summary must carry them, to the digits printed.
"$LODE" run "$SRC/config/kawato_planar.yaml" --quiet --no-telemetry --summary-json "$TMP/demo.json" >/dev/null 2>&1
check_rc "run the demo" 0 $?
"$PY" - "$TMP/demo.json" <<'CHECK' && echo "ok: the demo's summary is the README's table" || { echo "FAIL: demo summary vs README"; fail=1; }
import json, sys
s = json.load(open(sys.argv[1]))
def near(label, value, printed, half_unit):
    assert abs(value - printed) <= half_unit, f"{label}: {value} vs README {printed}"
truth = s["position_noise"]["truth"]
near("hold noise x um", truth["x"]["std"] * 1e6, 0.36, 0.005)
near("hold noise y um", truth["y"]["std"] * 1e6, 0.47, 0.005)
glsdc = s["recorded"]["glsdc.pose"]["hold_noise"]
near("GLSDC std x um", glsdc["x"]["std"] * 1e6, 1.64, 0.005)
near("GLSDC std y um", glsdc["y"]["std"] * 1e6, 1.63, 0.005)
steps = {st["axis"]: st for st in s["steps"]}
for axis, rise_ms, overshoot, settle_ms in (("x", 24.5, 19.3, 163), ("theta_z", 15.8, 11.6, 128)):
    near(axis + " rise ms", steps[axis]["rise_time_s"] * 1e3, rise_ms, 0.05)
    near(axis + " overshoot %", steps[axis]["overshoot_pct"], overshoot, 0.05)
    near(axis + " settling ms", steps[axis]["settling_time_s"] * 1e3, settle_ms, 0.5)
CHECK

# A shadow's estimate is compared with the truth; its disagreement (shadow minus primary) is
# not an estimate, and is not.
"$LODE" run "$SRC/config/kawato_planar_swap.yaml" --duration 1 --quiet --no-telemetry --summary-json "$TMP/swap.json" >"$TMP/swap_run.out" 2>&1
check_rc "run kawato_planar_swap" 0 $? "$TMP/swap_run.out"
"$PY" - "$TMP/swap.json" <<'CHECK' && ok "a shadow's disagreement is not compared with the truth" || bad "shadow outputs in the summary"
import json, sys
recorded = json.load(open(sys.argv[1]))["recorded"]
print("   ", {name: sorted(r) for name, r in recorded.items()})
sys.exit(0 if "error_vs_truth" in recorded["kf_hybrid.pose"] and "error_vs_truth" not in recorded["kf_hybrid.disagreement"] else 1)
CHECK

# A runtime fault: an unstable controller drives the command to infinity; io.sim refuses
# it, drives the outputs safe, and lode exits 1.
sed '0,/- { zeros_s: .*gain: 4\.09e5, discretization: matched }/s//- { num_z: [1.0], den_z: [1.0, -3.0] }/' \
  "$SRC/config/kawato_planar.yaml" >"$TMP/fault.yaml"
grep -q "den_z: \[1.0, -3.0\]" "$TMP/fault.yaml" || { echo "FAIL: test setup (sed)"; exit 1; }
"$LODE" run "$TMP/fault.yaml" --duration 3 --summary-json "$TMP/fault.json" >"$TMP/fault.out" 2>&1
check_rc "runtime fault exit code" 1 $?
contains "fault reported" "$TMP/fault.out" "FAULT: .*driven safe"
contains "fault in summary" "$TMP/fault.json" '"result": "fault"'

# RT-side warnings travel through the RT log ring into the log and the event list.
sed 's/adc_range_v: 10/adc_range_v: 2/' "$SRC/config/kawato_planar.yaml" >"$TMP/clip.yaml"
"$LODE" run "$TMP/clip.yaml" --duration 0.2 --summary-json "$TMP/clip.json" >"$TMP/clip.out" 2>&1
contains "rt_log warning printed" "$TMP/clip.out" "stage cycle 0\] ADC saturated on [0-9]+ channel"
contains "rt_log warning in events" "$TMP/clip.json" '"kind": "warning"'

"$LODE" frobnicate >"$TMP/usage.out" 2>&1; check_rc "unknown command" 2 $?
"$LODE" run "$SRC/config/kawato_planar.yaml" --clock wall >"$TMP/clock.out" 2>&1; check_rc "bad --clock" 2 $?
"$LODE" plugins >"$TMP/plugins.out" 2>&1; check_rc "plugins" 0 $?
contains "plugins lists glsdc" "$TMP/plugins.out" "estimator.glsdc"

# A full disk loses nothing silently: what a command writes (its summary, its report, what it
# prints) either arrives whole or the command says so and exits 1. /dev/full fails every
# write with ENOSPC. A reader that leaves early (head) is not a failure.
if [ -w /dev/full ]; then
  CFG="$SRC/config/kawato_planar.yaml"
  "$LODE" run "$CFG" --duration 0.2 --quiet --no-telemetry --no-local-control --summary-json /dev/full \
    >"$TMP/full_summary.out" 2>&1; check_rc "--summary-json on a full disk" 1 $? "$TMP/full_summary.out"
  contains "--summary-json says why" "$TMP/full_summary.out" "cannot write /dev/full .*No space left on device"
  "$LODE" describe "$CFG" >/dev/full 2>"$TMP/full_describe.err"; check_rc "describe > full disk" 1 $? "$TMP/full_describe.err"
  contains "describe says its output was cut" "$TMP/full_describe.err" "output could not be written in full"
  "$LODE" check "$CFG" >/dev/full 2>"$TMP/full_check.err"; check_rc "check > full disk" 1 $? "$TMP/full_check.err"
  contains "check says why" "$TMP/full_check.err" "No space left on device"
  "$LODE" describe "$CFG" 2>"$TMP/head.err" | head -c 10 >/dev/null
  check_rc "describe | head: a reader that leaves is no error" 0 "${PIPESTATUS[0]}" "$TMP/head.err"
else
  bad "/dev/full is not writable: the full-disk checks did not run"
fi

if [ $fail -ne 0 ]; then echo "lode_cli_test: FAILED"; exit 1; fi
echo "lode_cli_test: all passed"
