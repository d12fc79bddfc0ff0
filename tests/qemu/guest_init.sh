#!/bin/busybox sh
# /init of the QEMU guest (tests/qemu/can_qemu_test.sh): bring up vcan0 on a stock Debian
# kernel, run the guest tests, hand their results to the host on the second serial port as a
# tar stream, power off. The first serial port is the console the host reads.
/bin/busybox --install -s /bin
export PATH=/bin:/sbin:/usr/bin
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev
# The initramfs root is already a writable tmpfs: no tmpfs over /tmp, where the build (copied
# in at its own absolute path) may live.
mkdir -p /tmp /dev/shm && mount -t tmpfs shm /dev/shm
echo "GUEST: kernel $(uname -r), $(grep -c ^processor /proc/cpuinfo) CPU, up $(cut -d' ' -f1 /proc/uptime) s"
if modprobe vcan && modprobe can-raw && ip link add dev vcan0 type vcan && ip link set up vcan0; then
  echo "GUEST: vcan0 up"
  sh /guest/guest_tests.sh
  echo "GUEST_TESTS_RC=$?"
else
  echo "GUEST: cannot bring up vcan0"
  echo "GUEST_TESTS_RC=99"
fi
stty -F /dev/ttyS1 raw -echo 2>/dev/null
# Bounded: a UART that stopped interrupting must not keep the guest from its end.
timeout 120 tar cf /dev/ttyS1 -C /out . 2>/dev/null || echo "GUEST: sending the results on ttyS1 failed or timed out"
echo "GUEST_DONE up $(cut -d' ' -f1 /proc/uptime) s"
# End QEMU through its isa-debug-exit port (status 3): no shutdown path to hang in. Power-off
# stays as the fallback, for a QEMU without the device.
printf '\001' | dd of=/dev/port bs=1 seek=244 count=1 2>/dev/null
echo o > /proc/sysrq-trigger
sleep 5
