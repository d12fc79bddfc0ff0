#!/usr/bin/env bash
# Install lodestone to a temporary prefix, build an out-of-tree plugin against it with
# find_package(lodestone), and load it with the installed `lode`.
set -eu
BUILD=$1
HERE=$2
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
cmake --install "$BUILD" --prefix "$TMP/prefix" >/dev/null
cmake -S "$HERE" -B "$TMP/build" -DCMAKE_PREFIX_PATH="$TMP/prefix" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$TMP/build" >/dev/null
test -f "$TMP/build/lode-filter.external_gain.so"
export LODE_PLUGIN_PATH="$TMP/build"
LODE="$TMP/prefix/bin/lode"
"$LODE" plugins | grep -q "filter.external_gain" || { echo "FAIL: installed lode does not list the plugin"; exit 1; }
"$LODE" plugins | grep -q "estimator.glsdc" || { echo "FAIL: installed lode does not find its own plugins"; exit 1; }
"$LODE" check "$HERE/pipeline.yaml"
"$LODE" describe "$HERE/pipeline.yaml" | grep -q '"gain": 2' || { echo "FAIL: describe"; exit 1; }
"$LODE" run "$HERE/pipeline.yaml" --duration 0.05 --quiet >/dev/null
echo "external_plugin_test: passed"
