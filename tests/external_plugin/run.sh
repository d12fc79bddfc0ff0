#!/usr/bin/env bash
# Install lodestone to a temporary prefix, build an out-of-tree plugin against it with
# find_package(lodestone), and load it with the installed `lode`.
set -eu
BUILD=$1
HERE=$2
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
export XDG_RUNTIME_DIR=$TMP/run && mkdir -m 700 "$XDG_RUNTIME_DIR"  # our own command sockets
cmake --install "$BUILD" --prefix "$TMP/prefix" >/dev/null
cmake -S "$HERE" -B "$TMP/build" -DCMAKE_PREFIX_PATH="$TMP/prefix" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$TMP/build" >/dev/null
test -f "$TMP/build/lode-filter.external_gain.so"
# Its own test (TESTS): the BlockHarness from the installed SDK, registered with ctest.
ctest --test-dir "$TMP/build" --output-on-failure >"$TMP/ctest.log" 2>&1 \
  || { cat "$TMP/ctest.log"; echo "FAIL: the plugin's own test (TESTS) failed"; exit 1; }
ctest --test-dir "$TMP/build" -N | grep -q "Total Tests: 1" || { echo "FAIL: the plugin's test is not registered"; exit 1; }
# Installed into the same prefix, the installed lode finds it without LODE_PLUGIN_PATH.
cmake --install "$TMP/build" --prefix "$TMP/prefix" >/dev/null
LODE_PLUGIN_PATH= "$TMP/prefix/bin/lode" plugins filter.external_gain | grep -q "Out-of-tree example" \
  || { echo "FAIL: the installed plugin is not found by the installed lode"; exit 1; }
rm "$TMP"/prefix/lib/lodestone/plugins/lode-filter.external_gain.so
export LODE_PLUGIN_PATH="$TMP/build"
LODE="$TMP/prefix/bin/lode"
# The installed man pages (one per command) and bash completion work.
MANPATH="$TMP/prefix/share/man" MANWIDTH=80 man lode-run 2>/dev/null | grep -q -- "--duration" \
  || { echo "FAIL: man lode-run (installed) does not show run's options"; exit 1; }
MANPATH="$TMP/prefix/share/man" man lode 2>/dev/null | grep -q "replay" || { echo "FAIL: man lode lists no commands"; exit 1; }
for c in $("$LODE" --help | sed -n '/^Subcommands:/,/^$/p' | awk 'NR > 1 && NF { print $1 }'); do
  test -f "$TMP/prefix/share/man/man1/lode-$c.1.gz" || { echo "FAIL: no man page for lode $c"; exit 1; }
done
completion=$(bash -c 'source "$1"; COMP_WORDS=(lode run --dur); COMP_CWORD=2; _lode; echo "${COMPREPLY[*]}"' _ \
  "$TMP/prefix/share/bash-completion/completions/lode")
[ "$completion" = "--duration" ] || { echo "FAIL: installed completion of 'lode run --dur' gave '$completion'"; exit 1; }
"$LODE" plugins | grep -q "filter.external_gain" || { echo "FAIL: installed lode does not list the plugin"; exit 1; }
"$LODE" plugins | grep -q "estimator.glsdc" || { echo "FAIL: installed lode does not find its own plugins"; exit 1; }
"$LODE" check "$HERE/pipeline.yaml"
"$LODE" describe "$HERE/pipeline.yaml" | grep -q '"gain": 2' || { echo "FAIL: describe"; exit 1; }
"$LODE" run "$HERE/pipeline.yaml" --duration 0.05 --quiet --record "$TMP/run.h5" >/dev/null
# The plugin really runs in the loop with its parameter: twice.out = 2 * ref.out at every
# cycle, and the reference steps from 0 to 2 within the run (so 0 = 2 * 0 alone proves nothing).
PY=python3; [ -x /usr/bin/python3 ] && PY=/usr/bin/python3  # the Debian interpreter has h5py
"$PY" - "$TMP/run.h5" <<'CHECK' || { echo "FAIL: the plugin's output is not gain * input"; exit 1; }
import sys, h5py, numpy
with h5py.File(sys.argv[1], "r") as f:
    ref = f["signals/ref.out/x"][:]
    out = f["signals/twice.out/x"][:]
assert len(ref) == 50 and len(out) == 50, (len(ref), len(out))
assert ref.max() == 2.0 and ref.min() == 0.0, "the reference did not step"
assert numpy.array_equal(out, 2.0 * ref), f"max |out - 2 ref| = {numpy.abs(out - 2.0 * ref).max()}"
print(f"external plugin: {len(out)} cycles, out = 2 * ref exactly, ref 0 -> 2")
CHECK
echo "external_plugin_test: passed"
