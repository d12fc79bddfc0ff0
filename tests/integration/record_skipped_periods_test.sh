#!/usr/bin/env bash
# A live recording of a loop that overran is complete, and says so. kawato_planar runs on the
# real clock with a block that busy-waits 4 ms (3.2 periods at 800 Hz) at cycles 1200 and 2000
# (tests/core/bad_plugins/overruns_at.cpp); `overrun_policy: skip` then skips the periods lost,
# which publish nothing. `lode record` and `lode echo` must not count those periods as lost
# samples: every sample the pipeline sent arrived, so record exits 0, says "0 missing" and how
# many samples were not due, and writes gaps = 0 and skipped = that count into the file.
# usage: record_skipped_periods_test.sh LODE SRC BAD_PLUGIN_DIR
set -u
LODE=$1 SRC=$2 BAD_PLUGINS=$3
source "$(dirname "$0")/test_lib.sh"
export LODE_PLUGIN_PATH="${LODE_PLUGIN_PATH:-}:$BAD_PLUGINS"
take_private_domain

$PY - "$SRC/config/kawato_planar.yaml" "$DOMAIN" >"$TMP/overruns.yaml" <<'PY'
import sys
text = open(sys.argv[1]).read()
block = "  slow:\n    plugin: test.overruns_at\n    cycles: [1200, 2000]\n    busy_us: 4000\n\n"
assert "\nenvelope:" in text and "overrun_policy: skip" in text and "\n  domain: 0" in text
text = text.replace("\nenvelope:", "\n" + block + "envelope:", 1)
print(text.replace("\n  domain: 0", "\n  domain: " + sys.argv[2], 1), end="")
PY

# Both subscribers end when the pipeline posts its stop event.
"$LODE" record "$TMP/rec.h5" --domain "$DOMAIN" --topics kf.pose,ctrl.out --wait 60 >"$TMP/record.out" 2>&1 &
RECORD=$!
PIDS+=("$RECORD")
"$LODE" echo kf.pose --domain "$DOMAIN" --wait 60 --quiet >/dev/null 2>"$TMP/echo.err" &
ECHO=$!
PIDS+=("$ECHO")
sleep 1
"$LODE" run "$TMP/overruns.yaml" --clock real --duration 3.5 --no-local-control --quiet \
  --summary-json "$TMP/run.json" >"$TMP/run.out" 2>&1
check_rc "lode run --clock real with two forced overruns" 0 $? "$TMP/run.out"
missed=$($PY -c 'import json,sys; print(json.load(open(sys.argv[1]))["timing"]["missed_periods"])' "$TMP/run.json" 2>/dev/null)
if [ "${missed:-0}" -ge 6 ]; then ok "the loop skipped $missed periods"; else bad "missed periods: '${missed:-}', expected >= 6"; fi

wait "$RECORD"
check_rc "lode record of the run exits 0: nothing was lost" 0 $? "$TMP/record.out"
wait "$ECHO"
check_rc "lode echo of the run" 0 $? "$TMP/echo.err"
cat "$TMP/record.out" "$TMP/echo.err" | grep -E "missing" | sed 's/^/    /'
contains "record: kf.pose has 0 missing and the skipped periods not due" "$TMP/record.out" \
  "kf/pose +[0-9]+ samples, 0 missing, [0-9]+ not due \(periods the loop skipped after overruns\)$"
contains "echo: 0 missing, the skipped periods never published" "$TMP/echo.err" \
  "^lode echo: [0-9]+ samples, cycles [0-9]+\.\.[0-9]+, 0 missing, [0-9]+ never published \(periods the loop skipped"

# The file: gaps 0, skipped = the periods the cycle numbers jump over, which the run reports.
if $PY - "$TMP/rec.h5" "$missed" <<'PY'; then ok "the file says gaps 0 and skipped = the cycles it has no rows for"; else bad "the file's counters: see above"; fi
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], "r")
ok = True
for name in ("kf.pose", "ctrl.out"):
    g = f["signals"][name]
    cycles = g["cycle"][:]
    absent = int(np.sum(np.diff(cycles) - 1))
    print(name, "rows", len(cycles), "gaps", int(g.attrs["gaps"]), "skipped", int(g.attrs["skipped"]),
          "absent between rows", absent, "loop skipped", sys.argv[2])
    ok = ok and int(g.attrs["gaps"]) == 0 and int(g.attrs["skipped"]) == absent and 0 < absent <= int(sys.argv[2])
sys.exit(0 if ok else 1)
PY
exit $fail
