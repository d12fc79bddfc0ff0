#!/usr/bin/env bash
# lodestone: install every dependency (Debian 12 packages), build, then run the demo or the tests.
#
#   ./setup.sh demo    install, build, run config/kawato_planar.yaml (simulated clock)
#   ./setup.sh test    install, build, run every test (ctest)
#   ./setup.sh package install, build, make the Debian packages (cpack), print their paths
#
# Run as root on a fresh Debian 12 (or with sudo available). Safe to re-run.
set -euo pipefail
cd "$(dirname "$0")"
mode=${1:-demo}
case "$mode" in demo|test|build|package) ;; *) echo "usage: $0 demo|test|build|package" >&2; exit 2 ;; esac

PACKAGES=(build-essential g++ cmake make pkg-config
  libeigen3-dev libyaml-cpp-dev libspdlog-dev libfmt-dev libutfcpp-dev
  libgtest-dev libgmock-dev libbenchmark-dev rt-tests libslicot-dev
  libcli11-dev nlohmann-json3-dev strace help2man man-db    # command line, local JSON commands, man pages; strace for the CLI test
  libfastrtps-dev libfastcdr-dev fastddsgen fastdds-tools  # telemetry over Fast DDS 2.9
  libxxhash-dev                                             # the output digest (XXH3-64) and the key of lode/signals (XXH64)
  cyclonedds-dev cyclonedds-tools                           # the interop test: a Cyclone DDS program (idlc) on lode's topics
  libhdf5-dev hdf5-tools python3-h5py python3-numpy        # recordings (HDF5) and their check
  openssl                                                   # DDS Security lab certificates
  clang libclang-rt-14-dev                                  # libFuzzer for the decoder fuzz tests
  qemu-system-x86 linux-image-amd64 busybox-static kmod cpio can-utils  # QEMU guest with a real vcan0 for the CAN test
  libcpp-httplib-dev                                        # lode scope's HTTP server
  libsystemd-dev                                            # lode run under systemd: sd_notify (READY, watchdog)
  chromium                                                  # lode plot --png, and the report test's browser
  mmdebstrap lintian)                                       # the package tests: a clean Debian root file system, lintian on the .debs
# Node.js and npm install the plot report's chart library (apps/lode/plot/package-lock.json);
# a machine that already has them (e.g. from another Node.js distribution) keeps its own.
command -v npm >/dev/null 2>&1 || PACKAGES+=(nodejs npm)

as_root() { if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi; }
missing=()
for p in "${PACKAGES[@]}"; do dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p"); done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  as_root apt-get update -qq
  # INITRD=No: the kernel packages are only booted by the QEMU guest tests, each with an
  # initramfs of its own, so skip building one for the host (saves minutes on a fresh machine).
  DEBIAN_FRONTEND=noninteractive INITRD=No as_root apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# uPlot, exactly as the lock file pins it (compiled into `lode`: nothing is fetched at run time).
(cd apps/lode/plot && npm ci --no-audit --no-fund)

jobs=$(nproc)
cmake -S . -B build -DCMAKE_BUILD_TYPE=RelWithDebInfo
cmake --build build -j"$jobs"

case "$mode" in
  demo) ./build/apps/lode run config/kawato_planar.yaml ;;
  test) cd build && ctest --output-on-failure -j"$jobs" ;;
  build) ;;
  package)
    cmake --build build --target package
    echo "setup: Debian packages (docs/deployment.md):"
    ls -1 "$PWD"/build/packages/*.deb "$PWD"/build/packages/*.ddeb ;;
esac
