#!/usr/bin/env bash
# kawato_planar closed loop through io.vme_pentek and the board emulator, with
# separate processes: lode-vme-emu plays the board on a shared file, its plant the io.sim
# block of config/kawato_planar.yaml; `lode run config/kawato_planar_vme.yaml` drives it over
# the register interface. Checks:
#  1. the closed loop gives the same estimates as the io.sim run within quantization (the
#     DAC's 16-bit codes quantize the forces), and at the end the DAC registers hold the safe
#     codes;
#  2. the emulator stops answering (SIGSTOP) mid-run: the run faults with the reason, exit 1,
#     and the DAC registers hold the safe codes with DAC_LOAD rung;
#  3. SIGTERM to lode run mid-run stops it cleanly with the DAC outputs at their safe codes;
#  4. SIGTERM stops the emulator cleanly;
#  5. a register map with every register moved (test/shuffled.regmap), named by a relative
#     `register_map` in a copy of the config, both processes started from another directory:
#     the closed loop gives exactly the output of 1, and the safe codes land where that map
#     puts DAC_DATA; an invalid map is a configuration error (exit 2) naming its file and line.
# usage: vme_closed_loop_test.sh LODE LODE_VME_EMU SRC
set -u
LODE=$1 EMU=$2 SRC=$3
source "$(dirname "$0")/test_lib.sh"

source "$(dirname "$0")/vme_lib.sh"
vme_config "$TMP/vme.yaml"

# start_mid_run CONFIG OUT WHAT [ARGS...]: a 60 s `lode run CONFIG ARGS` in the background
# ($RUN, output in OUT), checked to be still running a second later, before WHAT is done to it.
start_mid_run() {
  local config=$1 out=$2 what=$3
  shift 3
  "$LODE" run "$config" --no-telemetry --no-local-control --quiet "$@" >"$out" 2>&1 &
  RUN=$!
  PIDS+=($RUN)
  sleep 1
  kill -0 $RUN 2>/dev/null || { bad "the 60 s run ended before $what"; cat "$out"; }
}

# 1. Closed loop, compared with io.sim.
start_emulator || exit 1
# Simulated clock (the config says real): cycles back to back, none skipped under load, so the
# comparison with io.sim is cycle for cycle; the emulator's plant advances per trigger anyway.
"$LODE" run "$TMP/vme.yaml" --clock sim --no-telemetry --no-local-control --quiet --record "$TMP/vme.h5" \
  --summary-json "$TMP/vme.json" >"$TMP/vme.out" 2>&1
check_rc "closed loop through the VME emulator" 0 $? "$TMP/vme.out"
dac_registers >"$TMP/dac_end.txt"
contains "after the run the DAC registers hold the safe codes" "$TMP/dac_end.txt" "^dac 0 0 0 load"
"$LODE" run "$SRC/config/kawato_planar.yaml" --no-telemetry --no-local-control --quiet --record "$TMP/sim.h5" \
  >"$TMP/sim.out" 2>&1
check_rc "the same pipeline through io.sim" 0 $? "$TMP/sim.out"
$PY "$(dirname "$0")/compare_with_sim.py" "$TMP/vme.h5" "$TMP/sim.h5" VME || bad "VME and io.sim runs differ beyond quantization"

# 2. The emulator stops answering mid-run.
sed -e "s/^duration_s: .*/duration_s: 60.0/" "$TMP/vme.yaml" >"$TMP/vme_long.yaml"
start_mid_run "$TMP/vme_long.yaml" "$TMP/stall.out" "the emulator was stopped" --summary-json "$TMP/stall.json"
kill -STOP $EMU_PID
wait $RUN
check_rc "a silent board faults the run" 1 $? "$TMP/stall.out"
contains "the fault names the board and why" "$TMP/stall.out" "FAULT: stage.read: .*within conversion_timeout_us"
dac_registers >"$TMP/dac_stall.txt"
contains "outputs driven safe: safe codes written and DAC_LOAD rung" "$TMP/dac_stall.txt" "^dac 0 0 0 load 1"

# 3. SIGTERM to lode run mid-run: it stops cleanly and the DAC outputs go to their safe codes.
# Non-zero safe values here, so "safe" cannot be mistaken for registers never written.
kill -CONT $EMU_PID
sed -e "s/gain: 10.0, unit: N, safe_value: 0.0 }/gain: 10.0, unit: N, safe_value: 1.5 }/" "$TMP/vme_long.yaml" \
  >"$TMP/vme_term.yaml"
start_mid_run "$TMP/vme_term.yaml" "$TMP/term.out" "SIGTERM"
kill -TERM $RUN
wait $RUN
check_rc "lode run stops on SIGTERM" 0 $? "$TMP/term.out"
sleep 0.2  # the emulator latches the last DAC_LOAD
dac_registers >"$TMP/dac_term.txt"
# 1.5 N at 10 N/V = 0.15 V = code 492 (nearest of 491.52); tz stays 0.
contains "after SIGTERM the DAC outputs hold the safe codes, latched" "$TMP/dac_term.txt" "^dac 492 492 0 load 0"

# 4. SIGTERM stops the emulator.
kill -TERM $EMU_PID
wait $EMU_PID
check_rc "emulator exits on SIGTERM" 0 $? "$TMP/emu.out"
contains "emulator reports what it served" "$TMP/emu.out" "stopped after [0-9]+ conversions"
[ ! -e "$WINDOW" ] && ok "the emulator removed the board file it created" \
  || bad "the emulator left its board file $WINDOW behind"

# 5. A shuffled register map, named relative to the config file, both processes started
# elsewhere (/) so a path resolved against the working directory would not be found.
mkdir "$TMP/shuffled"
cp "$SRC/plugins/io/vme_pentek/test/shuffled.regmap" "$TMP/shuffled/board.regmap"
sed -e "s#device: $WINDOW#device: $TMP/window_shuffled#" \
    -e "s/^\(    offset: 0x0.*\)$/\1\n    register_map: board.regmap/" "$TMP/vme.yaml" >"$TMP/shuffled/vme.yaml"
grep -q "register_map: board.regmap" "$TMP/shuffled/vme.yaml" || bad "test bug: no register_map in the shuffled config"
(cd / && exec "$EMU" "$TMP/shuffled/vme.yaml" --sim "$SRC/config/kawato_planar.yaml") >"$TMP/emu_shuffled.out" 2>&1 &
EMU_PID=$!
PIDS+=($EMU_PID)
for _ in $(seq 1 100); do grep -q "serving" "$TMP/emu_shuffled.out" && break; sleep 0.1; done
contains "the emulator serves the shuffled map" "$TMP/emu_shuffled.out" "register map $TMP/shuffled/board.regmap"
(cd / && exec "$LODE" run "$TMP/shuffled/vme.yaml" --clock sim --no-telemetry --no-local-control --quiet \
   --record "$TMP/shuffled.h5") >"$TMP/shuffled.out" 2>&1
check_rc "closed loop through the shuffled register map" 0 $? "$TMP/shuffled.out"
# shuffled.regmap: DAC_DATA at 0x000 stride 8, DAC_LOAD at 0x110.
dac_registers "$TMP/window_shuffled" 0x000 8 0x110 >"$TMP/dac_shuffled.txt"
contains "after the run the shuffled DAC registers hold the safe codes" "$TMP/dac_shuffled.txt" "^dac 0 0 0 load"
$PY - "$TMP/shuffled.h5" "$TMP/vme.h5" <<'PY' || bad "the shuffled-map run differs from the default-map run"
import sys, h5py, numpy as np
a, b = h5py.File(sys.argv[1], "r"), h5py.File(sys.argv[2], "r")
def series(f, sig):
    g = f["signals/" + sig]
    return np.column_stack([g[n][:] for n in g.attrs["names"]])
for sig in ("stage.signals", "ctrl.out", "kf.pose"):
    x, y = series(a, sig), series(b, sig)
    assert x.shape == y.shape, (sig, x.shape, y.shape)
    # The same converters, plant and noise behind other offsets: the same run, bit for bit.
    print("%s: %d cycles, max |shuffled - default| %.3g" % (sig, len(x), np.abs(x - y).max()))
    assert np.array_equal(x, y), sig
PY
kill -TERM $EMU_PID
wait $EMU_PID
check_rc "emulator on the shuffled map exits on SIGTERM" 0 $? "$TMP/emu_shuffled.out"
printf 'window 0x400\nregister STATUS 0x402 ro\n' >"$TMP/shuffled/board.regmap"
"$LODE" run "$TMP/shuffled/vme.yaml" --clock sim --no-telemetry --no-local-control --quiet >"$TMP/badmap.out" 2>&1
check_rc "an invalid register map refuses to start" 2 $? "$TMP/badmap.out"
contains "the error is on the block's register_map key" "$TMP/badmap.out" "vme.yaml:[0-9]+:[0-9]+: blocks.stage.register_map: invalid register map"
contains "the error names the map's file and line" "$TMP/badmap.out" "$TMP/shuffled/board.regmap:2: register STATUS: offset 0x402"
"$EMU" "$TMP/shuffled/vme.yaml" --sim "$SRC/config/kawato_planar.yaml" >"$TMP/emu_badmap.out" 2>&1
check_rc "the emulator refuses the invalid map too" 2 $? "$TMP/emu_badmap.out"
contains "its error names the map's file and line" "$TMP/emu_badmap.out" "board.regmap:2: register STATUS"
"$EMU" "$TMP/vme.yaml" --sim "$SRC/config/kawato_planar.yaml" --block nope >"$TMP/emu_noblock.out" 2>&1
check_rc "the emulator refuses a board pipeline without that io.vme_pentek block" 2 $? "$TMP/emu_noblock.out"
contains "and says so" "$TMP/emu_noblock.out" "has no io.vme_pentek block named 'nope'"
[ $fail -eq 0 ] && echo PASS
exit $fail
