#!/usr/bin/env bash
# docs/pipelines.md's table of top-level keys is exactly what the loader accepts: a pipeline
# with an unknown top-level key makes `lode check` list the allowed ones, and the table must
# have one row per allowed key and no other.
set -eu
LODE=$1
DOC=$2
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
printf 'pipeline: probe\nrate_hz: 100\nzz_not_a_key: 1\nblocks: {}\n' >"$TMP/probe.yaml"
message=$("$LODE" check "$TMP/probe.yaml" 2>&1 || true)
allowed=$(printf '%s\n' "$message" | sed -n "s/.*unknown top-level key 'zz_not_a_key' (allowed: \(.*\))$/\1/p" | tr -d ' ' | tr ',' '\n' | sort)
[ -n "$allowed" ] || { echo "FAIL: lode check did not list the allowed top-level keys:"; echo "$message"; exit 1; }
documented=$(sed -n '/^## Top-level keys/,/^## /p' "$DOC" | sed -n 's/^| `\([a-z_]*\)` |.*/\1/p' | sort)
if [ "$allowed" != "$documented" ]; then
  echo "FAIL: docs/pipelines.md's top-level keys differ from what the loader accepts"
  diff <(echo "$allowed") <(echo "$documented") | sed 's/^</  accepted, not documented:/; s/^>/  documented, not accepted:/' | grep -v '^[0-9]'
  exit 1
fi
echo "docs/pipelines.md documents the $(echo "$allowed" | wc -l) top-level keys the loader accepts"
