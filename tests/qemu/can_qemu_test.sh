#!/usr/bin/env bash
# io.socketcan_daq on a real CAN socket. The host kernel has no CAN, so this boots the
# machine's stock Debian kernel under QEMU (TCG: this host's KVM cannot run it)
# with an initramfs made here: busybox, the kernel's can/can-raw/can-dev/vcan modules, and this
# build's lode, lode-can-emu, plugins and io.socketcan_daq unit tests with the shared libraries
# they load. The guest brings up vcan0 and runs tests/qemu/guest_tests.sh; its results come
# back as a tar stream on the second serial port. Checks here: every guest step's exit code,
# and that the closed loop through CAN gives the io.sim run's results within quantization.
# usage: can_qemu_test.sh BUILD_DIR SOURCE_DIR        exit 77 (skipped) without qemu/kernel
set -u
BUILD=$(cd "$1" && pwd) SRC=$(cd "$2" && pwd)
source "$SRC/tests/integration/test_lib.sh"

source "$SRC/tests/qemu/guest_kernel.sh"
# The stock kernel (LODE_CAN_GUEST_KERNEL=rt-amd64 boots the PREEMPT_RT one instead, to check
# that these tests and the guest's end hold there too).
KERNEL=$(guest_kernel "${LODE_CAN_GUEST_KERNEL:-amd64}")
KVER=${KERNEL#/boot/vmlinuz-}
QEMU=$(command -v qemu-system-x86_64)
BUSYBOX=/bin/busybox
if [ -z "$KERNEL" ] || [ -z "$QEMU" ] || [ ! -x "$BUSYBOX" ] || readelf -l "$BUSYBOX" | grep -q "program interpreter"; then
  echo "SKIP: needs qemu-system-x86, linux-image-amd64, busybox-static (setup.sh installs them)"
  exit 77
fi
MODDIR=/lib/modules/$KVER
for m in net/can/can.ko net/can/can-raw.ko drivers/net/can/dev/can-dev.ko drivers/net/can/vcan.ko; do
  [ -f "$MODDIR/kernel/$m" ] || { echo "SKIP: $MODDIR/kernel/$m missing"; exit 77; }
done

LODE=$BUILD/apps/lode EMU=$BUILD/apps/lode-can-emu
DAQ_TEST=$BUILD/plugins/io/socketcan_daq/io_socketcan_daq_test
ROOT=$TMP/root
mkdir -p "$ROOT"/{bin,sbin,proc,sys,dev,tmp,out,cfg,guest,lib64}

# An ELF at its own absolute path (the plugin search path and the rpaths stay valid), without
# debug sections (the initramfs stays small), and every shared library it loads.
copy_elf() {
  local f=$1
  [ -e "$ROOT$f" ] && return
  mkdir -p "$ROOT$(dirname "$f")"
  objcopy --strip-debug "$f" "$ROOT$f" 2>/dev/null || cp -L "$f" "$ROOT$f"
  ldd "$f" 2>/dev/null | awk '/=> \//{print $3} /^\s*\/lib/{print $1}' | while read -r lib; do
    [ -e "$ROOT$lib" ] && continue
    mkdir -p "$ROOT$(dirname "$lib")"
    cp -L "$lib" "$ROOT$lib"
  done
}
cp "$BUSYBOX" "$ROOT/bin/busybox"
for m in net/can/can.ko net/can/can-raw.ko drivers/net/can/dev/can-dev.ko drivers/net/can/vcan.ko; do
  mkdir -p "$ROOT$MODDIR/kernel/$(dirname $m)"
  cp "$MODDIR/kernel/$m" "$ROOT$MODDIR/kernel/$m"
done
cp "$MODDIR"/modules.order "$MODDIR"/modules.builtin* "$ROOT$MODDIR/"
depmod -b "$ROOT" "$KVER"
copy_elf "$LODE"; copy_elf "$EMU"; copy_elf "$DAQ_TEST"
for so in "$BUILD"/plugins/lode-*.so; do copy_elf "$so"; done
cp -L /lib64/ld-linux-x86-64.so.2 "$ROOT/lib64/"

# The pipelines: kawato_planar through CAN with the timeouts of a shared, emulated machine
# (the guest's CPU is emulated, tens of times slower than the host's); a 60 s variant to stop
# mid-run; one with non-zero safe values so "driven safe" cannot be mistaken for "never written".
cp "$SRC/config/kawato_planar.yaml" "$ROOT/cfg/kawato_planar.yaml"
sed -e "s/pdo_timeout_us: [0-9]*/pdo_timeout_us: 50000/" -e "s/heartbeat_timeout_ms: [0-9]*/heartbeat_timeout_ms: 1000/" \
    -e "s/cpu: 1, //" "$SRC/config/kawato_planar_can.yaml" > "$ROOT/cfg/can.yaml"
sed -e "s/^duration_s: .*/duration_s: 60.0/" "$ROOT/cfg/can.yaml" > "$ROOT/cfg/can_long.yaml"
sed -e "s/unit: N, safe_value: 0.0 }/unit: N, safe_value: 1.5 }/g" "$ROOT/cfg/can_long.yaml" > "$ROOT/cfg/can_term.yaml"
cp "$SRC/tests/qemu/guest_init.sh" "$ROOT/init"
cp "$SRC/tests/qemu/guest_tests.sh" "$ROOT/guest/guest_tests.sh"
chmod +x "$ROOT/init"
printf 'LODE=%s\nEMU=%s\nDAQ_TEST=%s\n' "$LODE" "$EMU" "$DAQ_TEST" > "$ROOT/guest/paths.sh"
(cd "$ROOT" && find . | cpio -o -H newc --quiet) > "$TMP/initramfs.cpio"
echo "initramfs: $(du -m "$TMP/initramfs.cpio" | cut -f1) MB, kernel $KVER"

# Two vCPUs (the RT thread and the module emulator each get one); no network; 10 min at most.
# noirqdebug: under emulation the UARTs' interrupts, threaded on a PREEMPT_RT kernel, can reach
# the handler after the transmitter was already refilled; the kernel then counts them as
# spurious ("nobody cared"), disables IRQ 3 ("Disabling IRQ #3"), and ttyS1 stops mid-transfer.
t0=$(date +%s%N)
timeout 600 "$QEMU" -accel tcg -smp 2 -m 1024M -display none -no-reboot -nic none -monitor none \
  -serial "file:$TMP/console.log" -serial "file:$TMP/out.tar" -device "$GUEST_EXIT_DEVICE" \
  -kernel "$KERNEL" -initrd "$TMP/initramfs.cpio" \
  -append "console=ttyS0 panic=-1 rdinit=/init quiet loglevel=3 noirqdebug" >"$TMP/qemu.out" 2>&1
qrc=$?
t1=$(date +%s%N)
tr -d '\r' < "$TMP/console.log" > "$TMP/console.txt"
sed 's/^/    guest| /' "$TMP/console.txt"
echo "qemu exit $qrc after $(( (t1 - t0) / 1000000 )) ms"
[ $qrc -eq $GUEST_EXIT_DONE ] || { bad "the guest ran to its end and QEMU exited (exit $qrc, expected $GUEST_EXIT_DONE)"; cat "$TMP/qemu.out"; }
contains "the guest brought up vcan0" "$TMP/console.txt" "GUEST: vcan0 up"
contains "the guest finished" "$TMP/console.txt" "GUEST_DONE"
contains "io.socketcan_daq unit tests pass on vcan0" "$TMP/console.txt" "^GTEST_RC=0"
contains "1 kHz for 10 s on vcan0, no frame lost" "$TMP/console.txt" "OK \] SocketCanDaqOnInterface.ThousandHertzForTenSecondsWithNoLostFrame"
contains "kawato_planar closed loop through CAN ran" "$TMP/console.txt" "^LOOP_RC=0"
contains "the same on the real clock (800 Hz)" "$TMP/console.txt" "^LOOP_REAL_RC=0"
contains "a silent module faults the run" "$TMP/console.txt" "^STALL_RC=1"
contains "the fault names the module and why" "$TMP/console.txt" "FAULT: stage.read: TPDO missing"
contains "SIGTERM stops lode run cleanly" "$TMP/console.txt" "^TERM_RC=0"

mkdir -p "$TMP/out"
tar xf "$TMP/out.tar" -C "$TMP/out" 2>/dev/null || bad "the guest's results arrived (tar)"
# Kept for a look after the run (the unit tests' whole output, the emulator's and lode's logs).
LAST=$BUILD/tests/qemu_can_last
rm -rf "$LAST" && mkdir -p "$LAST" && cp -r "$TMP/out/." "$TMP/console.txt" "$LAST/" && echo "guest results kept in $LAST"
# The module's outputs after each stop: safe values (counts), as lode-can-emu held them.
contains "after the silent module came back, it holds the safe outputs" "$TMP/out/stall.emu.txt" \
  "outputs held: fx=0 .* fy=0 .* tz=0 "
# 1.5 N at 3.0517578125 mN per count = 491.52 -> 492 counts; tz's safe value stays 0.
contains "after SIGTERM the module holds the non-zero safe outputs" "$TMP/out/term.emu.txt" \
  "outputs held: fx=492 .* fy=492 .* tz=0 "
contains "SIGKILL: lode run died of it" "$TMP/console.txt" "^KILL_RC=137"
contains "after SIGKILL the module's SYNC watchdog drove its outputs safe" "$TMP/out/kill.emu.txt" "SYNC watchdog: no SYNC"
contains "after SIGKILL the module holds the non-zero safe outputs" "$TMP/out/kill.emu.txt" \
  "outputs held: fx=492 .* fy=492 .* tz=0 "

# The io.sim run of the same pipeline, here on the host (deterministic: same seed).
"$LODE" run "$SRC/config/kawato_planar.yaml" --no-telemetry --no-local-control --quiet --record "$TMP/sim.h5" \
  >"$TMP/sim.out" 2>&1
check_rc "the same pipeline through io.sim" 0 $? "$TMP/sim.out"
if [ -f "$TMP/out/can.h5" ]; then
$PY "$SRC/tests/integration/compare_with_sim.py" "$TMP/out/can.h5" "$TMP/sim.h5" CAN || bad "CAN and io.sim runs differ beyond quantization"
else
  bad "the closed-loop recording came back from the guest"
fi
[ $fail -eq 0 ] && echo PASS
exit $fail
