#!/usr/bin/env bash
# The Debian packages, end to end:
#   1. the packages cpack built from this build tree (build_packages.sh, run first by ctest):
#      lodestone, lodestone-dev and their dbgsym;
#   2. lintian reports no error; lodestone's Installed-Size is at most 30 MB; no installed
#      file of either package holds the source or the build folder's path;
#   3. in a clean root file system of the host's Debian release (make_rootfs.sh), apt installs
#      lodestone alone and it works (installed_checks.sh runtime); then lodestone-dev, g++ and
#      cmake, and the out-of-tree plugin tests/external_plugin builds, installs and loads
#      (installed_checks.sh sdk).
# The .deb files apt downloads stay in BUILD/tests/apt-cache for the next run; the root file
# system is made afresh each run and removed at the end.
#
# usage: package_test.sh BUILD_DIR SOURCE_DIR PACKAGE_DIR
# Exit 77 when a tool is missing (mmdebstrap, lintian, dpkg-shlibdeps) or without root.
set -uo pipefail
BUILD=$(realpath "$1") SRC=$(realpath "$2") DEBS=$(realpath "$3")
HERE=$(dirname "$(realpath "$0")")
MAX_INSTALLED_KB=$((30 * 1024))

for tool in lintian mmdebstrap dpkg-deb dpkg-shlibdeps; do
  command -v "$tool" >/dev/null || { echo "SKIP: $tool is missing (setup.sh installs it)"; exit 77; }
done
[ "$(id -u)" -eq 0 ] || { echo "SKIP: making a root file system needs root"; exit 77; }

TMP=$(mktemp -d /tmp/lode-package-test.XXXXXX)
trap 'rm -rf "$TMP"' EXIT
fail=0
ok() { echo "ok: $1"; }
bad() { echo "FAIL: $1"; fail=1; }
stage_start=$SECONDS
took=  # seconds since the previous stage, set by lap
lap() { took="$((SECONDS - stage_start)) s"; stage_start=$SECONDS; }

# --- 1. the packages ----------------------------------------------------------------------
mkdir -p "$TMP/debs" && cp "$DEBS"/*.deb "$DEBS"/*.ddeb "$TMP/debs/" 2>/dev/null
runtime_deb=$(ls "$TMP"/debs/lodestone_*.deb 2>/dev/null)
dev_deb=$(ls "$TMP"/debs/lodestone-dev_*.deb 2>/dev/null)
[ -n "$runtime_deb" ] && [ -n "$dev_deb" ] || { ls -R "$DEBS"; echo "FAIL: no lodestone and lodestone-dev .deb in $DEBS"; exit 1; }
ls "$TMP"/debs/*.ddeb >/dev/null 2>&1 || bad "no debug symbol package (.ddeb)"
lap
ok "packages: $(cd "$TMP/debs" && ls ./*.deb ./*.ddeb 2>/dev/null | tr '\n' ' ')"

# --- 2. lintian, size, build paths ---------------------------------------------------------
# --fail-on error: warnings are reported (and listed in docs/deployment.md), errors fail.
if lintian --fail-on error --no-tag-display-limit "$runtime_deb" "$dev_deb" >"$TMP/lintian.log" 2>&1; then
  ok "lintian: no error ($(grep -c '^W:' "$TMP/lintian.log") warnings)"
else
  bad "lintian reports errors:"
fi
sed 's/^/    /' "$TMP/lintian.log"

installed_kb=$(dpkg-deb --field "$runtime_deb" Installed-Size)
echo "lodestone Installed-Size: ${installed_kb} KiB ($((installed_kb / 1024)) MiB; at most $((MAX_INSTALLED_KB / 1024)) MiB)"
if [ "$installed_kb" -le "$MAX_INSTALLED_KB" ]; then ok "Installed-Size within bounds"
else bad "lodestone's Installed-Size ${installed_kb} KiB exceeds ${MAX_INSTALLED_KB} KiB"; fi

# The paths as an extended regex that also matches them inside man pages, where groff
# writes each '-' as '\-'.
path_regex() { printf '%s' "$1" | sed 's/[].*^$()+?{}|\\[]/\\&/g; s/-/\\\\?-/g'; }
paths="$(path_regex "$SRC")|$(path_regex "$BUILD")"
for deb in "$runtime_deb" "$dev_deb"; do
  name=$(basename "$deb")
  mkdir -p "$TMP/unpacked/$name"
  dpkg-deb -x "$deb" "$TMP/unpacked/$name" || { bad "dpkg-deb -x $name"; continue; }
  files=$(find "$TMP/unpacked/$name" -type f | wc -l)
  [ "$files" -gt 0 ] || { bad "$name unpacks to no file"; continue; }
  # Compressed files (man pages, changelog) are looked into, too.
  hits=$(cd "$TMP/unpacked/$name" && { grep -rlaE -e "$paths" . ;
          find . -name '*.gz' -exec sh -c 'zcat "$1" | grep -qaE -e "$2" && echo "$1"' _ {} "$paths" \; ; } | sort -u)
  if [ -z "$hits" ]; then ok "$name: none of its $files files holds $SRC or $BUILD"
  else bad "$name: files hold the build machine's paths ($SRC or $BUILD):"; echo "$hits" | sed 's/^/    /'; fi
done
[ "$fail" -eq 0 ] || { echo "package_test: FAILED before installing"; exit 1; }

# --- 3. a clean Debian: install, run, build a plugin against the SDK -----------------------
CACHE=$BUILD/tests/apt-cache
mkdir -p "$CACHE/archives"
cached_before=$(find "$CACHE/archives" -maxdepth 1 -name '*.deb' | wc -l)
cp "$HERE/installed_checks.sh" "$TMP/"
cp -r "$SRC/tests/external_plugin" "$TMP/external_plugin"
rm -rf "$TMP/external_plugin/build"
# The hooks run in order inside the new root file system (mmdebstrap mounts /proc, /dev and
# /sys for them and takes them down afterwards); the first that fails fails the run. The .deb
# files of lodestone-dev's dependencies land in the cache like the others.
"$HERE/make_rootfs.sh" "$TMP/rootfs" "$CACHE" --deb "$runtime_deb" -- \
  --customize-hook="copy-in $TMP/installed_checks.sh $TMP/external_plugin $dev_deb /tmp" \
  --customize-hook='chroot "$1" bash /tmp/installed_checks.sh runtime' \
  --customize-hook="chroot \"\$1\" env DEBIAN_FRONTEND=noninteractive apt-get install -y -q \
      --no-install-recommends /tmp/$(basename "$dev_deb") g++ cmake make" \
  --customize-hook='chroot "$1" bash /tmp/installed_checks.sh sdk /tmp/external_plugin' \
  >"$TMP/rootfs.log" 2>&1
rc=$?
lap
grep -E '^(ok|FAIL|    )' "$TMP/rootfs.log"
if [ "$rc" -eq 0 ]; then
  ok "clean $(. /etc/os-release && echo "$PRETTY_NAME"): lodestone installs and runs, lodestone-dev builds a plugin it loads ($took)"
else
  tail -40 "$TMP/rootfs.log"; bad "installing and using the packages in a clean root file system (exit $rc)"
fi
cached_after=$(find "$CACHE/archives" -maxdepth 1 -name '*.deb' | wc -l)
echo "apt cache $CACHE: $cached_before .deb before, $cached_after after ($((cached_after - cached_before)) downloaded)"
[ "$fail" -eq 0 ] && echo "package_test: passed" || echo "package_test: FAILED"
exit "$fail"
