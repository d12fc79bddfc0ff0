#!/usr/bin/env bash
# The `lode` program end to end: exit codes 0 / 1 / 2, located messages, summary JSON.
set -u
LODE=$1
SRC=$2
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
fail=0
check() {  # name expected_rc actual_rc
  if [ "$2" != "$3" ]; then echo "FAIL: $1: exit code $3, expected $2"; fail=1; else echo "ok: $1"; fi
}
contains() {  # name file pattern
  if grep -qE "$3" "$2"; then echo "ok: $1"; else echo "FAIL: $1: no /$3/ in:"; cat "$2"; fail=1; fi
}

"$LODE" check "$SRC/config/kawato_planar.yaml" >"$TMP/check.out" 2>&1; check "check valid" 0 $?
contains "check lists the cycle order" "$TMP/check.out" "stage.read glsdc kf ref ctrl stage.write"

"$LODE" describe "$SRC/config/kawato_planar.yaml" >"$TMP/describe.json" 2>&1; check "describe" 0 $?
contains "describe has derived controller" "$TMP/describe.json" '"derived"'

sed 's/plugin: estimator.glsdc/plugin: estimator.glsdx/' "$SRC/config/kawato_planar.yaml" >"$TMP/bad.yaml"
"$LODE" run "$TMP/bad.yaml" >"$TMP/bad.out" 2>&1; check "run invalid config" 2 $?
contains "invalid config names file:line:column" "$TMP/bad.out" "bad.yaml:[0-9]+:[0-9]+: blocks.glsdc.plugin: no plugin named 'estimator.glsdx'"

"$LODE" run "$SRC/config/kawato_planar.yaml" --duration 1.5 --summary-json "$TMP/summary.json" >"$TMP/run.out" 2>&1
check "run sim" 0 $?
contains "summary printed" "$TMP/run.out" "position noise std"
contains "summary json result" "$TMP/summary.json" '"result": "completed"'
contains "summary json steps" "$TMP/summary.json" '"rise_time_s"'

# A runtime fault: an unstable controller drives the command to infinity; io.sim refuses
# it, drives the outputs safe, and lode exits 1.
sed '0,/- { zeros_s: .*gain: 4\.09e5, discretization: matched }/s//- { num_z: [1.0], den_z: [1.0, -3.0] }/' \
  "$SRC/config/kawato_planar.yaml" >"$TMP/fault.yaml"
grep -q "den_z: \[1.0, -3.0\]" "$TMP/fault.yaml" || { echo "FAIL: test setup (sed)"; exit 1; }
"$LODE" run "$TMP/fault.yaml" --duration 3 --summary-json "$TMP/fault.json" >"$TMP/fault.out" 2>&1
check "runtime fault exit code" 1 $?
contains "fault reported" "$TMP/fault.out" "FAULT: .*driven safe"
contains "fault in summary" "$TMP/fault.json" '"result": "fault"'

# RT-side warnings travel through the RT log ring into the log and the event list.
sed 's/adc_range_v: 10/adc_range_v: 2/' "$SRC/config/kawato_planar.yaml" >"$TMP/clip.yaml"
"$LODE" run "$TMP/clip.yaml" --duration 0.2 --summary-json "$TMP/clip.json" >"$TMP/clip.out" 2>&1
contains "rt_log warning printed" "$TMP/clip.out" "stage cycle 0\] ADC saturated on [0-9]+ channel"
contains "rt_log warning in events" "$TMP/clip.json" '"kind": "warning"'

"$LODE" frobnicate >"$TMP/usage.out" 2>&1; check "unknown command" 2 $?
"$LODE" run "$SRC/config/kawato_planar.yaml" --clock wall >"$TMP/clock.out" 2>&1; check "bad --clock" 2 $?
"$LODE" plugins >"$TMP/plugins.out" 2>&1; check "plugins" 0 $?
contains "plugins lists glsdc" "$TMP/plugins.out" "estimator.glsdc"

if [ $fail -ne 0 ]; then echo "lode_cli_test: FAILED"; exit 1; fi
echo "lode_cli_test: all passed"
