#!/bin/sh
# Inside the systemd guest of tests/qemu/service_qemu_test.sh, as a oneshot unit once the system
# is up: the installed lodestone package's service on a PREEMPT_RT kernel. Every finding is a
# "SVC: " line on the console, which the host checks; then QEMU is ended through isa-debug-exit.
say() { echo "SVC: $*"; }
prefixed() { sed "s/^/SVC: $1| /"; }
W=/dev/shm/lode-vme-kawato
# The DAC registers of the emulated board: DAC_DATA[0..2] at 0x200 and DAC_LOAD at 0x014.
dac() { echo "dac $(od -An -tu4 -j 512 -N 12 "$W" | xargs) load $(od -An -tu4 -j 20 -N 4 "$W" | xargs)"; }
# wait_for SECONDS COMMAND...: until COMMAND succeeds, at most SECONDS.
wait_for() { n=$(( $1 * 5 )); shift; while [ $n -gt 0 ]; do "$@" >/dev/null 2>&1 && return 0; sleep 0.2; n=$((n - 1)); done; return 1; }
emulator_serving() { journalctl -u "lode-vme-emu@$1" -o cat | grep -q serving; }
start_emulator() {
  systemctl start "lode-vme-emu@$1"
  wait_for 60 emulator_serving "$1" && say "EMU_$1=serving" || say "EMU_$1=not serving"
}

say "kernel $(uname -r) realtime=$(cat /sys/kernel/realtime 2>/dev/null) version $(uname -v)"
say "VERSION $(lode --version 2>&1)"
say "USER_LODE $(id lode 2>&1)"

# 1. rtcheck on this kernel.
lode rtcheck >/tmp/rtcheck.txt 2>&1
say "RTCHECK_RC=$?"
prefixed rtcheck </tmp/rtcheck.txt

# 2. The service: READY, the RT thread at SCHED_FIFO with locked memory, as user lode.
start_emulator kawato_vme
t0=$(cut -d' ' -f1 /proc/uptime)
systemctl start lode@kawato_vme
say "START_RC=$? after $(cut -d' ' -f1 /proc/uptime) s (asked at $t0 s)"
say "ACTIVE=$(systemctl is-active lode@kawato_vme)"
pid=$(systemctl show -p MainPID --value lode@kawato_vme)
say "MAIN_PID=$pid USER=$(ps -o user= -p "$pid")"
ps -L -o tid=,cls=,rtprio=,comm= -p "$pid" | prefixed thread
say "$(grep VmLck /proc/"$pid"/status)"
systemctl show -p StatusText --value lode@kawato_vme | prefixed status
sleep 4  # past the YAML's duration_s
say "ACTIVE_AFTER_4S=$(systemctl is-active lode@kawato_vme)"
systemctl show -p StatusText --value lode@kawato_vme | prefixed status_before_stop

# 3. systemctl stop: outputs at their safe values, the summary in the journal.
systemctl stop lode@kawato_vme
say "STOP_RC=$?"
sleep 0.3  # the emulator latches the last DAC_LOAD
say "AFTER_STOP $(dac)"
say "RESULT=$(systemctl show -p Result --value lode@kawato_vme) EXIT_STATUS=$(systemctl show -p ExecMainStatus --value lode@kawato_vme)"
journalctl -u lode@kawato_vme -o cat --no-pager | prefixed journal
# By priority: the start line is info (6), the outcome notice (5).
journalctl -u lode@kawato_vme -p info..info -o cat --no-pager | prefixed journal_info
journalctl -u lode@kawato_vme -p notice..notice -o cat --no-pager | prefixed journal_notice
systemctl stop lode-vme-emu@kawato_vme

# 4. A loop frozen on purpose: no watchdog pings, SIGABRT, the crash guard, a restart.
start_emulator kawato_freeze
systemctl start lode@kawato_freeze
say "FREEZE_START_RC=$? ACTIVE=$(systemctl is-active lode@kawato_freeze)"
sleep 1
# As the service's user: lode refuses to command a socket another user serves, root included.
runuser -u lode -- env XDG_RUNTIME_DIR=/run/lode/kawato_freeze lode set --local "$(cat /guest/freeze_target)" 1 \
  >/tmp/set.txt 2>&1
say "SET_RC=$?"
prefixed set </tmp/set.txt
restarted() { [ "$(systemctl show -p NRestarts --value lode@kawato_freeze)" -ge 1 ]; }
wait_for 60 restarted
say "NRESTARTS=$(systemctl show -p NRestarts --value lode@kawato_freeze)"
# The restarted process is up when systemd logs "Started" a second time (its READY=1). Whether
# it is still active a moment later depends on the emulated board answering in time on
# emulated CPUs, which the service's own behaviour does not decide: that state is shown only.
started_twice() { [ "$(journalctl -u lode@kawato_freeze -o cat | grep -c '^Started lode@kawato_freeze')" -ge 2 ]; }
wait_for 60 started_twice && say "READY_AFTER_RESTART=yes" || say "READY_AFTER_RESTART=no"
say "ACTIVE_AFTER_RESTART=$(systemctl is-active lode@kawato_freeze)"
systemctl stop lode@kawato_freeze
# With the guest's clock: when a restarted loop faults, the gaps show which side stalled.
journalctl -u lode@kawato_freeze -o short-monotonic --no-pager | prefixed freeze_journal
journalctl -u lode@kawato_freeze -p emerg..err -o cat --no-pager | prefixed freeze_journal_err
systemctl stop lode-vme-emu@kawato_freeze
journalctl -u lode-vme-emu@kawato_freeze -o short-monotonic --no-pager | prefixed freeze_emulator

say "DONE"
printf '\001' | dd of=/dev/port bs=1 seek=244 count=1 2>/dev/null
