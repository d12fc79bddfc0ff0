#!/usr/bin/env bash
# A real-clock recording whose loop overran replays bit for bit. kawato_planar runs on the
# real clock with a block that busy-waits 4 ms (3.2 periods at 800 Hz) at cycles 400 and 900
# (tests/core/bad_plugins/overruns_at.cpp); `overrun_policy: skip` then skips the periods lost,
# so the recording has no rows for them. `lode replay` must run the recorded cycles only, with
# their cycle numbers and times, and match the recording bit for bit and by its digest; it
# says how many periods were skipped. A recording whose recorder lost cycles (its
# dropped_cycles > 0) is still refused: those cycles ran, and their samples are gone.
# usage: replay_skipped_cycles_test.sh LODE SRC BAD_PLUGIN_DIR
set -u
LODE=$1 SRC=$2 BAD_PLUGINS=$3
source "$(dirname "$0")/test_lib.sh"
export LODE_PLUGIN_PATH="${LODE_PLUGIN_PATH:-}:$BAD_PLUGINS"

$PY - "$SRC/config/kawato_planar.yaml" >"$TMP/overruns.yaml" <<'PY'
import sys
text = open(sys.argv[1]).read()
block = "  slow:\n    plugin: test.overruns_at\n    cycles: [400, 900]\n    busy_us: 4000\n\n"
assert "\nenvelope:" in text and "overrun_policy: skip" in text
print(text.replace("\nenvelope:", "\n" + block + "envelope:", 1), end="")
PY
"$LODE" run "$TMP/overruns.yaml" --clock real --duration 1.5 --record "$TMP/r.h5" --no-telemetry \
  --no-local-control --quiet --summary-json "$TMP/run.json" >"$TMP/run.out" 2>&1
check_rc "lode run --clock real with two forced overruns" 0 $? "$TMP/run.out"
missed=$($PY -c 'import json,sys; print(json.load(open(sys.argv[1]))["timing"]["missed_periods"])' "$TMP/run.json" 2>/dev/null)
if [ "${missed:-0}" -ge 6 ]; then ok "the loop skipped $missed periods"; else bad "missed periods: '${missed:-}', expected >= 6"; fi

"$LODE" replay "$TMP/r.h5" --output "$TMP/replay.h5" --report "$TMP/report.json" >"$TMP/replay.out" 2>&1
check_rc "lode replay of the recording with skipped periods" 0 $? "$TMP/replay.out"
contains "bit for bit and by its digest" "$TMP/replay.out" "^bit-identical: [0-9]+ series x [0-9]+ cycles, digest [0-9a-f]{16} \(xxh3-64\)$"
contains "the skipped periods are named" "$TMP/replay.out" "^Note .*: $missed periods the recorded real-time loop skipped after overruns are skipped here too$"
if $PY - "$TMP/r.h5" "$TMP/replay.h5" <<'PY'; then ok "the replay ran the recorded cycle numbers"; else bad "the replay's cycles differ from the recording's"; fi
import sys, h5py, numpy as np
a, b = (h5py.File(p, "r") for p in sys.argv[1:3])
ca, cb = a["signals/kf.pose"]["cycle"][:], b["signals/kf.pose"]["cycle"][:]
source = b.attrs["source"].decode() if isinstance(b.attrs["source"], bytes) else str(b.attrs["source"])
print("the replay's file says it was written by", repr(source))
sys.exit(0 if np.array_equal(ca, cb) and np.any(np.diff(ca) > 1) and source == "lode replay" else 1)
PY

# The estimator statistics are over the replayed cycles, each once, and all finite.
if $PY - "$TMP/report.json" <<'PY'; then ok "the statistics cover every replayed cycle"; else bad "statistics: see above"; fi
import json, math, sys
r = json.load(open(sys.argv[1]))
cycles = r["configurations"][0]["cycles"]
e = r["estimators"][0]
values = [v for el in e["elements"].values() for k, v in el.items() if k != "unit"]
print("replayed", cycles, "cycles; NIS over", e["nis"]["cycles"], "; statistics", values)
sys.exit(0 if e["nis"]["cycles"] == cycles and all(math.isfinite(v) for v in values) else 1)
PY

# The same file, but its recorder says it lost cycles: the gaps may be those, and are refused.
cp "$TMP/r.h5" "$TMP/lost.h5"
$PY -c 'import h5py,sys; f=h5py.File(sys.argv[1],"r+"); f.attrs["dropped_cycles"]=3.0' "$TMP/lost.h5"
"$LODE" replay "$TMP/lost.h5" >"$TMP/lost.out" 2>&1
check_rc "a recording whose recorder lost cycles is refused" 2 $? "$TMP/lost.out"
contains "and says why" "$TMP/lost.out" "has a gap: row [0-9]+ is cycle [0-9]+, expected [0-9]+ \(the recorder lost 3 cycles"
exit $fail
