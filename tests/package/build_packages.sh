#!/usr/bin/env bash
# The Debian packages of this build tree, made once for the tests that use them (the ctest
# fixture lode_packages: package_test, service_qemu_test): cpack -G DEB into OUT_DIR, emptied
# first so no package of an earlier build is taken for this one's.
# usage: build_packages.sh BUILD_DIR OUT_DIR        exit 77 without cpack or dpkg-shlibdeps
set -uo pipefail
BUILD=$(realpath "$1") OUT=$2
for tool in cpack dpkg-deb dpkg-shlibdeps; do
  command -v "$tool" >/dev/null || { echo "SKIP: $tool is missing (setup.sh installs it)"; exit 77; }
done
rm -rf "$OUT" && mkdir -p "$OUT"
start=$SECONDS
# gzip instead of the release's xz: xz-compressing the 300 MB of debug symbols is single-threaded
# and took 260 s of a 300 s package build here; gzip takes 37 s. What the tests check (contents,
# lintian, Installed-Size, installing with apt) does not depend on the compression.
if ! cpack --config "$BUILD/CPackConfig.cmake" -G DEB -B "$OUT" -D CPACK_DEBIAN_COMPRESSION_TYPE=gzip >"$OUT/cpack.log" 2>&1; then
  tail -30 "$OUT/cpack.log"; echo "FAIL: cpack"; exit 1
fi
ls "$OUT"/lodestone_*.deb "$OUT"/lodestone-dev_*.deb >/dev/null 2>&1 || { ls -R "$OUT"; echo "FAIL: cpack made no lodestone and lodestone-dev .deb"; exit 1; }
echo "ok: cpack: $(cd "$OUT" && ls ./*.deb ./*.ddeb 2>/dev/null | tr '\n' ' ')($((SECONDS - start)) s)"
