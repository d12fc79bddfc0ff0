# Sourced by the QEMU guest tests: which kernel a guest boots, named, never "the newest in /boot".
#
#   guest_kernel amd64      the kernel Debian's linux-image-amd64 selects (the stock one)
#   guest_kernel rt-amd64   the kernel linux-image-rt-amd64 selects (PREEMPT_RT)
#
# Prints the vmlinuz path, or nothing when that meta package or its image is not installed. With
# both flavours in /boot, the newest file by version is the RT one ("-rt-amd64" sorts last), so a
# test that took the newest booted a kernel it was not written for.
guest_kernel() {
  local flavour=$1 image
  image=$(dpkg-query -W -f='${Depends}' "linux-image-$flavour" 2>/dev/null | grep -o "linux-image-[^ ,]*-$flavour" | head -1)
  [ -n "$image" ] && [ -f "/boot/vmlinuz-${image#linux-image-}" ] && echo "/boot/vmlinuz-${image#linux-image-}"
}

# QEMU's isa-debug-exit device: a guest that writes byte V to port 0xf4 ends QEMU at once with
# exit status 2V+1. Guests end this way instead of powering off, which an RT kernel's shutdown can
# hang in (after "Disabling IRQ #3"); the host tells "the guest reached its end" (status 3, V=1)
# from a crash or a timeout.
GUEST_EXIT_DEVICE="isa-debug-exit,iobase=0xf4,iosize=0x04"
GUEST_EXIT_DONE=3
