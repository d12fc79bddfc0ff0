#!/usr/bin/env bash
# The lodestone package as a lab PC runs it: a clean Debian 12 root file system with systemd and
# the `lodestone` .deb installed by apt, booted under QEMU on Debian's PREEMPT_RT kernel
# (linux-image-rt-amd64). The guest (tests/qemu/service_guest_tests.sh, a oneshot unit) checks
# `lode rtcheck` on a real PREEMPT_RT kernel, `systemctl start lode@NAME` reaching active with
# READY, the RT thread at SCHED_FIFO with locked memory as user lode, `systemctl stop` leaving
# the VME emulator's DAC registers at the safe codes with the summary in the journal, and a loop
# frozen on purpose killed by the systemd watchdog and restarted. Timing inside an emulated guest
# means nothing: only behaviour is checked.
# usage: service_qemu_test.sh BUILD_DIR SOURCE_DIR FREEZE_PLUGIN.so PACKAGE_DIR
# exit 77 without the tools
set -u
BUILD=$(cd "$1" && pwd) SRC=$(cd "$2" && pwd) FREEZE_PLUGIN=$3 DEBS=$4
source "$SRC/tests/integration/test_lib.sh"
source "$SRC/tests/qemu/guest_kernel.sh"

QEMU=$(command -v qemu-system-x86_64)
if [ -z "$QEMU" ] || ! command -v mmdebstrap >/dev/null; then
  echo "SKIP: needs qemu-system-x86 and mmdebstrap (setup.sh installs them)"
  exit 77
fi

# The packages cpack made of this build tree (build_packages.sh, run first by ctest).
DEB=$(ls "$DEBS"/lodestone_*.deb 2>/dev/null | head -1)
[ -n "$DEB" ] || { bad "a lodestone_*.deb in $DEBS"; exit 1; }
echo "package: $(basename "$DEB")"

# What the guest adds to the installed package: its test unit, two pipelines in /etc/lodestone
# (kawato_planar through io.vme_pentek with non-zero safe values, so "driven safe" cannot be
# mistaken for "never written", and the longest conversion timeout, 1 s: the guest's CPUs are
# emulated; the same with the loop-freezing test filter), the emulator's unit
# and the test plugin. Both keep the YAML's duration_s (3 s): the unit runs them until stopped.
G=$TMP/guest_files
mkdir -p "$G/guest/plugins" "$G/etc/lodestone" "$G/etc/systemd/system/lode@kawato_freeze.service.d"
cp "$SRC/tests/qemu/service_guest_tests.sh" "$G/guest/run.sh"
cp "$FREEZE_PLUGIN" "$G/guest/plugins/"
sed -e "s/unit: N, safe_value: 0.0 }/unit: N, safe_value: 1.5 }/g" \
    -e "s/conversion_timeout_us: [0-9]*/conversion_timeout_us: 1000000/" \
    "$SRC/config/kawato_planar_vme.yaml" >"$G/etc/lodestone/kawato_vme.yaml"
# The freezing one: test.freezes_on_cue between the controller and the board; `lode set
# freeze.freeze 1` stops the loop inside its step().
awk '/^envelope:/ { print "  freeze:"; print "    plugin: test.freezes_on_cue"; print "    inputs: { in: ctrl.out }"; print "" }
     { sub(/inputs: { command: ctrl.out }/, "inputs: { command: freeze.out }"); print }' \
  "$G/etc/lodestone/kawato_vme.yaml" >"$G/etc/lodestone/kawato_freeze.yaml"
grep -q "command: freeze.out" "$G/etc/lodestone/kawato_freeze.yaml" || { bad "made the freezing pipeline"; exit 1; }
echo freeze.freeze >"$G/guest/freeze_target"
cat >"$G/etc/systemd/system/lode@kawato_freeze.service.d/test-plugin.conf" <<'UNIT'
[Service]
Environment=LODE_PLUGIN_PATH=/guest/plugins
UNIT
# The emulator stands in for hardware, which nothing on the host holds up: it has CPU 2 to itself
# (the guest has three). On CPU 1 io.vme_pentek polls the board at SCHED_FIFO 80 until the
# conversion is done, so an emulator there never runs; on CPU 0, with systemd, journald and
# lode's non-RT threads, the emulated CPU left it silent for a whole conversion timeout. CPU 2
# is not isolated, so lode's non-RT threads (which leave the RT CPU) can land there too; at
# SCHED_FIFO 70 the emulator still runs first, as a board would.
cat >"$G/etc/systemd/system/lode-vme-emu@.service" <<'UNIT'
[Unit]
Description=emulated VME board for /etc/lodestone/%i.yaml
[Service]
ExecStart=/usr/bin/lode-vme-emu /etc/lodestone/%i.yaml --sim /usr/share/lodestone/config/kawato_planar.yaml
User=lode
CPUAffinity=2
CPUSchedulingPolicy=fifo
CPUSchedulingPriority=70
UNIT
cat >"$G/etc/systemd/system/guest-test.service" <<'UNIT'
[Unit]
Description=lodestone service tests
After=multi-user.target
[Service]
Type=oneshot
ExecStart=/bin/sh /guest/run.sh
StandardOutput=tty
StandardError=tty
TTYPath=/dev/ttyS0
[Install]
WantedBy=multi-user.target
UNIT

# The root file system: minbase + systemd, and the package by apt so its dependencies resolve
# (tests/package/make_rootfs.sh: the host's archive, downloads kept under the build tree). The
# kernel is Debian's PREEMPT_RT one, linux-image-rt-amd64, installed in the guest's root and
# booted from there: the host needs no second kernel (which would become its boot default).
t0=$(date +%s)
bash "$SRC/tests/package/make_rootfs.sh" "$TMP/root" "$BUILD/tests/apt-cache" --variant minbase \
  --include systemd,systemd-sysv,udev,procps,linux-image-rt-amd64 --deb "$DEB" -- \
  --customize-hook="copy-in $G/guest /" --customize-hook="copy-in $G/etc/lodestone /etc" \
  --customize-hook="copy-in $G/etc/systemd/system /etc/systemd" \
  --customize-hook='chroot "$1" systemctl enable guest-test.service' \
  --customize-hook='chroot "$1" systemctl mask serial-getty@ttyS0.service' \
  --customize-hook='echo guest >"$1"/etc/hostname' >"$TMP/rootfs.out" 2>&1
rootfs_rc=$?
[ $rootfs_rc -eq 77 ] && { echo "SKIP: mmdebstrap missing"; exit 77; }
check_rc "a Debian 12 root file system with systemd and the package ($(( $(date +%s) - t0 )) s)" 0 $rootfs_rc "$TMP/rootfs.out"
[ $fail -eq 0 ] || exit 1
KERNEL=$(ls "$TMP"/root/boot/vmlinuz-*-rt-amd64 2>/dev/null | head -1)
[ -n "$KERNEL" ] || { bad "linux-image-rt-amd64 put a kernel in the guest's /boot"; exit 1; }
cp "$KERNEL" "$TMP/" && KERNEL=$TMP/$(basename "$KERNEL")
# The guest's initramfs, without the kernel's modules (nothing here loads one) and apt's
# downloads and lists (kept in the cache): a third of the size.
(cd "$TMP/root" && find . -path ./var/cache/apt/archives -prune -o -path ./var/lib/apt/lists -prune \
   -o -path ./boot -prune -o -path ./usr/lib/modules -prune -o -print | cpio -o -H newc --quiet) >"$TMP/root.cpio"
rm -rf "$TMP/root"
echo "guest root: $(du -m "$TMP/root.cpio" | cut -f1) MB, kernel $(basename "$KERNEL")"

# Three vCPUs: the system, the RT loop (CPU 1, the pipeline's), the board emulator. TCG: this
# host's KVM does not run these kernels. The root file system is the initramfs itself
# (systemd runs from it; no disk or module needed to mount a root). noirqdebug: see
# can_qemu_test.sh. 15 min at most.
t0=$(date +%s%N)
timeout 900 "$QEMU" -accel tcg -smp 3 -m 2048M -display none -no-reboot -nic none -monitor none \
  -serial "file:$TMP/console.log" -device "$GUEST_EXIT_DEVICE" \
  -kernel "$KERNEL" -initrd "$TMP/root.cpio" \
  -append "console=ttyS0 rdinit=/sbin/init panic=-1 quiet noirqdebug" >"$TMP/qemu.out" 2>&1
qrc=$?
echo "qemu exit $qrc after $(( ($(date +%s%N) - t0) / 1000000 )) ms"
tr -d '\r' <"$TMP/console.log" | sed 's/\x1b\[[0-9;]*m//g' >"$TMP/console.txt"
grep "^SVC: " "$TMP/console.txt" | sed 's/^/    guest| /'
LAST=$BUILD/tests/qemu_service_last
rm -rf "$LAST" && mkdir -p "$LAST" && cp "$TMP/console.txt" "$LAST/" && echo "guest console kept in $LAST"
[ $qrc -eq $GUEST_EXIT_DONE ] || { bad "the guest ran to its end (QEMU exit $qrc, expected $GUEST_EXIT_DONE)"; cat "$TMP/qemu.out"; }
C=$TMP/console.txt
contains "the guest booted the PREEMPT_RT kernel" "$C" "^SVC: kernel .*-rt-amd64 realtime=1 .*PREEMPT_RT"
contains "lode --version in the guest" "$C" "^SVC: VERSION lode "
contains "the package made the user lode in group realtime" "$C" "^SVC: USER_LODE uid=.*\(lode\).*\(realtime\)"
contains "lode rtcheck says PREEMPT_RT" "$C" "^SVC: rtcheck\| .*PASS.*PREEMPT_RT"
contains "systemctl start returned (READY=1 arrived)" "$C" "^SVC: START_RC=0 "
contains "the service is active" "$C" "^SVC: ACTIVE=active$"
contains "it runs as user lode" "$C" "^SVC: MAIN_PID=[0-9]+ USER=lode$"
contains "the RT thread runs SCHED_FIFO at the pipeline's priority 80" "$C" "^SVC: thread\| +[0-9]+ +FF +80 "
contains "memory is locked" "$C" "^SVC: VmLck:[[:space:]]+[1-9][0-9]* kB"
contains "still active after the YAML's duration_s (the unit runs until stopped)" "$C" "^SVC: ACTIVE_AFTER_4S=active$"
contains "systemctl stop returned" "$C" "^SVC: STOP_RC=0$"
# 1.5 N at 10 N/V = 0.15 V = code 492 (nearest of 491.52); tz's safe value stays 0.
contains "after systemctl stop the DAC outputs hold the safe codes, latched" "$C" "^SVC: AFTER_STOP dac 492 492 0 load 0$"
contains "the stop is a success, exit 0" "$C" "^SVC: RESULT=success EXIT_STATUS=0$"
contains "the journal has the run's summary" "$C" "^SVC: journal\| .*cycles"
contains "the start line is filed as info" "$C" "^SVC: journal_info\| lode: started pipeline 'kawato_planar_vme' .*until stopped"
contains "the outcome is filed as notice: stopped, outputs driven safe" "$C" "^SVC: journal_notice\| .*stopped by signal at cycle [0-9]+ \(outputs driven safe\)"
contains "the frozen loop's service started" "$C" "^SVC: FREEZE_START_RC=0 ACTIVE=active$"
contains "the freeze was asked for" "$C" "^SVC: SET_RC=0$"
contains "systemd's watchdog fired" "$C" "^SVC: freeze_journal\| .*[Ww]atchdog timeout"
contains "the stuck loop is reported as an error" "$C" "^SVC: freeze_journal_err\| .*no progress"
contains "the crash guard drove the outputs safe, filed as critical or worse" "$C" "^SVC: freeze_journal_err\| lode: SIGABRT: sent by process 1 .*outputs driven to their safe values"
contains "the unit restarted" "$C" "^SVC: NRESTARTS=[1-9]"
contains "and the restarted process reported READY again" "$C" "^SVC: READY_AFTER_RESTART=yes$"
contains "the guest finished" "$C" "^SVC: DONE$"
[ $fail -eq 0 ] && echo PASS
exit $fail
