#!/usr/bin/env bash
# A crash of the pipeline's process drives the outputs safe. kawato_planar runs
# closed loop through io.vme_pentek against lode-vme-emu with non-zero safe values; a block
# with a bug (tests/core/bad_plugins/crashes_in_step.cpp) kills `lode run` mid-run:
#  1. a write through a null pointer: lode dies of SIGSEGV (exit status 139 as before), says
#     the outputs were driven safe, and the DAC registers hold the safe codes, latched;
#  2. an exception escaping the noexcept step() (std::terminate -> SIGABRT): the same;
#  3. a stack overflow on the RT thread (SIGSEGV with no stack left: the handler runs on the
#     thread's alternate signal stack): the same.
# usage: crash_safe_outputs_test.sh LODE LODE_VME_EMU SRC BAD_PLUGIN_DIR
set -u
LODE=$1 EMU=$2 SRC=$3 BAD_PLUGINS=$4
source "$(dirname "$0")/test_lib.sh"
export LODE_PLUGIN_PATH="${LODE_PLUGIN_PATH:-}:$BAD_PLUGINS"

source "$(dirname "$0")/vme_lib.sh"
# 60 s, so nothing but the crash ends the run; 1.5 N safe forces (code 492), so "safe" cannot
# be mistaken for registers never written.
vme_config "$TMP/vme.yaml" -e "s/^duration_s: .*/duration_s: 60.0/" \
  -e "s/gain: 10.0, unit: N, safe_value: 0.0 }/gain: 10.0, unit: N, safe_value: 1.5 }/"
# The faulty block, one per way of crashing, at cycle 800 (1 s at 800 Hz).
with_crash() {  # with_crash HOW OUT
  $PY - "$TMP/vme.yaml" "$1" >"$2" <<'PY'
import sys
text = open(sys.argv[1]).read()
block = "  buggy:\n    plugin: test.crashes_in_step\n    at_cycle: 800\n    how: %s\n\n" % sys.argv[2]
# The blocks end where the next top-level section starts (envelope:, else monitor:).
after = "\nenvelope:" if "\nenvelope:" in text else "\nmonitor:"
assert after in text
print(text.replace(after, "\n" + block + after[1:], 1), end="")
PY
}
with_crash segv "$TMP/segv.yaml"
with_crash throw "$TMP/throw.yaml"
with_crash overflow "$TMP/overflow.yaml"
"$LODE" check "$TMP/segv.yaml" >"$TMP/check.out" 2>&1
check_rc "the pipeline with the faulty block is valid" 0 $? "$TMP/check.out"

start_emulator || exit 1

crash_run() {  # crash_run NAME EXPECTED_RC SIGNAL_NAME
  (ulimit -c 0; exec "$LODE" run "$TMP/$1.yaml" --no-telemetry --no-local-control --quiet) >"$TMP/$1.out" 2>&1
  check_rc "$1: lode run dies of $3" "$2" $? "$TMP/$1.out"
  contains "$1: it says the outputs were driven safe" "$TMP/$1.out" "lode: $3: .*outputs driven to their safe values"
  sleep 0.2  # the emulator latches the last DAC_LOAD
  dac_registers >"$TMP/dac_$1.txt"
  # 1.5 N at 10 N/V = 0.15 V = code 492 (nearest of 491.52); tz's safe value is 0.
  contains "$1: the DAC outputs hold the safe codes, latched" "$TMP/dac_$1.txt" "^dac 492 492 0 load 0"
}
crash_run segv 139 SIGSEGV
crash_run throw 134 SIGABRT
crash_run overflow 139 SIGSEGV

kill -TERM $EMU_PID
wait $EMU_PID
check_rc "emulator exits on SIGTERM" 0 $? "$TMP/emu.out"
[ $fail -eq 0 ] && echo PASS
exit $fail
