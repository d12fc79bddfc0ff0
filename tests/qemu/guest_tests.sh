# Runs inside the QEMU guest (sourced paths are filled in by can_qemu_test.sh): io.socketcan_daq
# on a real CAN socket (vcan0) through the kernel's CAN stack.
#  1. the plugin's unit tests with LODE_CAN_INTERFACE=vcan0: PDO exchange at 1 kHz for 10 s
#     with no lost frame, then the faults (node silent, heartbeat lost, bus-off, malformed PDO
#     length, EMCY), each detected within its timeout with the outputs driven safe;
#  2. kawato_planar closed loop: `lode run` through io.socketcan_daq against lode-can-emu, its
#     plant the io.sim block of kawato_planar.yaml (the host compares with io.sim);
#  3. the emulator process stopped (SIGSTOP) mid-run: the run faults, outputs safe;
#  4. SIGTERM to `lode run` mid-run: the module holds the (non-zero) safe values;
#  5. SIGKILL to `lode run` mid-run (it cannot drive anything): the module's SYNC watchdog
#     drives its outputs to the (non-zero) safe values on its own.
# Every result goes to /out, which the host receives; lines with _RC= go to the console.
. /guest/paths.sh
OUT=/out
mkdir -p $OUT
rc=0

echo "== 1. io.socketcan_daq unit tests on vcan0"
# The plugins sit in the build tree's plugins/ beside apps/ (no compiled-in folder is searched).
LODE_PLUGIN_PATH=$(dirname $LODE)/../plugins LODE_CAN_INTERFACE=vcan0 $DAQ_TEST > $OUT/gtest.txt 2>&1
r=$?; echo "GTEST_RC=$r"; [ $r -eq 0 ] || rc=1
grep -E "^\[ +(OK|FAILED|SKIPPED|PASSED) |vcan0:|silent node|heartbeat lost:|Failure|Expected|Which is|actual" $OUT/gtest.txt

start_emulator() {  # start_emulator NAME CONFIG [ARGS...]
  name=$1; cfg=$2; shift 2
  # SYNC watchdog 1 s: the emulated guest may stall for a tenth of a second under host load.
  $EMU $cfg --sim /cfg/kawato_planar.yaml --sync-watchdog-ms 1000 "$@" > $OUT/$name.emu.txt 2>&1 &
  EMU_PID=$!
  i=0
  while [ $i -lt 100 ] && ! grep -q serving $OUT/$name.emu.txt; do sleep 0.1; i=$((i + 1)); done
}
wait_first_sync() {  # the pipeline has started (lode run takes seconds to start in the guest)
  i=0
  while [ $i -lt 300 ] && ! grep -q "first SYNC" $OUT/$1.emu.txt; do sleep 0.1; i=$((i + 1)); done
  sleep 0.5
}
stop_emulator() {
  kill -CONT $EMU_PID 2>/dev/null; kill -TERM $EMU_PID; wait $EMU_PID
  echo "EMU_RC=$?"
}
RUN_ARGS="--no-telemetry --no-local-control --quiet"

echo "== 2. kawato_planar closed loop through CAN"
# Simulated clock: cycles back to back (the module paced by SYNC), none skipped, so the host
# compares with io.sim cycle for cycle.
start_emulator loop /cfg/can.yaml
$LODE run /cfg/can.yaml --clock sim $RUN_ARGS --record $OUT/can.h5 > $OUT/loop.txt 2>&1
r=$?; echo "LOOP_RC=$r"; [ $r -eq 0 ] || { rc=1; tail -20 $OUT/loop.txt; }
stop_emulator
tail -2 $OUT/loop.emu.txt
# The config's real clock: 800 Hz on CLOCK_MONOTONIC in the emulated guest; overruns reported.
start_emulator real /cfg/can.yaml
$LODE run /cfg/can.yaml --no-telemetry --no-local-control --summary-json $OUT/real.json > $OUT/real.txt 2>&1
r=$?; echo "LOOP_REAL_RC=$r"; [ $r -eq 0 ] || { rc=1; tail -20 $OUT/real.txt; }
grep -E "overruns|timing|stage.read" $OUT/real.txt | tail -3
stop_emulator
tail -2 $OUT/real.emu.txt

# start_mid_run NAME CONFIG: the emulator, then `lode run` in the background ($RUN), returning
# once the pipeline runs; the caller interrupts one side, then calls end_mid_run NAME TAG.
start_mid_run() {
  start_emulator $1 $2
  $LODE run $2 $RUN_ARGS > $OUT/$1.txt 2>&1 &
  RUN=$!
  wait_first_sync $1
}
end_mid_run() {
  wait $RUN
  echo "$2_RC=$?"
  sleep 0.2  # the module takes the last frames
}

echo "== 3. the module stops answering mid-run"
start_mid_run stall /cfg/can_long.yaml
kill -STOP $EMU_PID
end_mid_run stall STALL
grep "FAULT" $OUT/stall.txt | head -3
stop_emulator
tail -1 $OUT/stall.emu.txt

echo "== 4. SIGTERM to lode run mid-run"
start_mid_run term /cfg/can_term.yaml
kill -TERM $RUN
end_mid_run term TERM
stop_emulator
tail -1 $OUT/term.emu.txt

echo "== 5. SIGKILL to lode run mid-run"
start_mid_run kill /cfg/can_term.yaml
kill -KILL $RUN
end_mid_run kill KILL
i=0
while [ $i -lt 50 ] && ! grep -q "SYNC watchdog" $OUT/kill.emu.txt; do sleep 0.1; i=$((i + 1)); done
stop_emulator
grep "SYNC watchdog" $OUT/kill.emu.txt
tail -1 $OUT/kill.emu.txt
exit $rc
