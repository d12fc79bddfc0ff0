#!/usr/bin/env bash
# `lode replay` end to end:
#  1. record a kawato_planar run, replay it through the recorded configuration: bit-identical, exit 0;
#  2. corrupt one recorded raw ADC value (h5py): the replay is no longer bit-identical, exit 1;
#     move one recorded estimate by 3e-12 relative: the report gives that largest difference;
#  3. replay through three other estimator sets (config/replay/): the report has 4 estimator
#     rows with finite statistics; replay speed is printed and asserted loosely (>= 10x).
# usage: replay_test.sh LODE SOURCE_DIR
set -u
LODE=$1
SRC=$2
PY=/usr/bin/python3
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
export XDG_RUNTIME_DIR=$WORK/run && mkdir -m 700 "$XDG_RUNTIME_DIR"  # our own command sockets
fail() { echo "FAIL: $*"; exit 1; }

cd "$WORK" || exit 1
"$LODE" run "$SRC/config/kawato_planar.yaml" --no-telemetry --quiet --record rec.h5 > run.txt 2>&1 \
  || { cat run.txt; fail "lode run --record"; }

# The recording says what produced it.
$PY - rec.h5 <<'PY' || fail "recording attributes"
import sys, json, h5py
f = h5py.File(sys.argv[1], "r")
a = f.attrs
for k in ("config", "output_digest", "cycles", "first_cycle", "lode_plugins"):
    assert k in a, "missing attribute " + k
assert int(a["cycles"]) == 2400 and int(a["first_cycle"]) == 0, (a["cycles"], a["first_cycle"])
plugins = json.loads(a["lode_plugins"])
assert plugins["io.sim"].endswith("lode-io.sim.so"), plugins
assert f["signals/stage.signals"].attrs["kind"] == "raw"
assert f["signals/kf.pose"].attrs["kind"] == "signal"
print("recording attributes ok: digest", a["output_digest"])
PY

# 1. Same configuration: bit for bit.
"$LODE" replay rec.h5 --quiet > same.txt 2>&1
rc=$?
cat same.txt
[ $rc -eq 0 ] || fail "replay of the recorded configuration exited $rc"
grep -q "^bit-identical: [0-9]* series x 2400 cycles, digest [0-9a-f]\{16\}" same.txt || fail "no bit-identical line"
[ -f rec.replay.h5 ] || fail "rec.replay.h5 not written"
digest=$($PY -c 'import h5py,sys; print(h5py.File(sys.argv[1],"r").attrs["output_digest"])' rec.h5)
grep -q "digest $digest" same.txt || fail "digest differs from the recorded $digest"

# Speed: reported always, asserted loosely (two shared, noisy cores).
speed=$(sed -n 's/.*cycles in [0-9.]* s wall, \([0-9.]*\)x real time.*/\1/p' same.txt | head -1)
echo "replay speed: ${speed}x real time (issue target: >= 50x)"
$PY -c "import sys; sys.exit(0 if float('$speed') >= 10 else 1)" || fail "replay only ${speed}x real time"

# 2. One corrupted raw value: the check must fail and name where.
cp rec.h5 bad.h5
$PY - bad.h5 <<'PY' || fail "corrupting the recording"
import sys, h5py
f = h5py.File(sys.argv[1], "r+")
g = f["signals/stage.signals"]
name = g.attrs["names"][0]
d = g[name]
d[1000] = d[1000] + 1e-3   # one ADC sample, 1 mV (one cycle at 1.25 s)
print("corrupted", name, "row 1000")
PY
"$LODE" replay bad.h5 --quiet > bad.txt 2>&1
rc=$?
cat bad.txt
[ $rc -eq 1 ] || fail "replay of a corrupted recording exited $rc, expected 1"
grep -q "NOT bit-identical with .*: first difference in series .*cycle 1000" bad.txt || fail "first difference not named at cycle 1000"

# 2b. One recorded estimate moved by 3e-12 of its largest magnitude (what a reordered sum in an
# estimator does): the check fails and says how large the difference is, where and when, so
# that a last-bit change is told apart from a real one.
cp rec.h5 nudged.h5
element=$($PY - nudged.h5 <<'PY'
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], "r+")
g = f["signals/kf.pose"]
name = g.attrs["names"][0]
d = g[name]
d[700] = d[700] + 3e-12 * np.abs(d[()]).max()
print(name)
PY
) || fail "nudging a recorded estimate"
"$LODE" replay nudged.h5 --quiet > nudged.txt 2>&1
rc=$?
cat nudged.txt
[ $rc -eq 1 ] || fail "replay of a recording with a nudged estimate exited $rc, expected 1"
grep -q "^  largest relative difference 3e-12 in kf.pose.$element at cycle 700$" nudged.txt \
  || fail "no 'largest relative difference 3e-12 in kf.pose.$element at cycle 700' line"
[ "$(grep -c "largest relative difference" nudged.txt)" -eq 1 ] || fail "a series other than kf.pose reported as different"

# 3. Three other estimator sets and a comparison report.
"$LODE" replay rec.h5 --config "$SRC/config/replay/kawato_planar_hybrid.yaml" \
  --config "$SRC/config/replay/kawato_planar_cv.yaml" --config "$SRC/config/replay/kawato_planar_glsdc3.yaml" \
  --report report.json > sets.txt 2>&1
rc=$?
cat sets.txt
[ $rc -eq 0 ] || fail "replay through three estimator sets exited $rc"
for stem in kawato_planar_hybrid kawato_planar_cv kawato_planar_glsdc3; do
  [ -f "rec.replay-$stem.h5" ] || fail "rec.replay-$stem.h5 not written"
done
grep -c "^| .* | kf.pose (" sets.txt | grep -qx 4 || fail "markdown table does not have 4 estimator rows"
$PY - report.json <<'PY' || fail "report.json"
import sys, json, math
r = json.load(open(sys.argv[1]))
rows = r["estimators"]
assert len(rows) == 4, len(rows)
assert r["bit_identical"] is True
plugins = [e["plugin"] for e in rows]
assert plugins == ["estimator.kalman", "estimator.hybrid_h2hinf", "estimator.kalman", "estimator.kalman"], plugins
for e in rows:
    assert e["reference"] == "stage.truth", e["reference"]
    for name, s in e["elements"].items():
        for k in ("bias", "rms", "max_abs", "noise_std"):
            assert s[k] is not None and math.isfinite(s[k]), (e["config"], name, k, s[k])
        assert s["rms"] < 1e-4, (e["config"], name, s["rms"])  # an estimate, not garbage
    assert e["median_step_us"] is not None and e["median_step_us"] > 0
    n = e["nis"]
    assert n["channels"] == 3 and n["cycles"] > 2000, n
    assert math.isfinite(n["mean"]) and 0 <= n["fraction_in_95"] <= 1, n
    lo, hi = n["interval_95"]
    assert abs(lo - 0.2158) < 1e-3 and abs(hi - 9.3484) < 1e-3, (lo, hi)   # chi-square(3) 2.5 / 97.5 %
    print("%-45s %-26s rms x %.3g m  NIS %.2f (3)  in95 %.2f  step %.2f us" % (
        e["config"], e["plugin"], e["elements"]["x"]["rms"], n["mean"], n["fraction_in_95"], e["median_step_us"]))
speeds = [c["speed_vs_realtime"] for c in r["configurations"]]
print("speeds vs real time:", ["%.0fx" % s for s in speeds])
PY

# A configuration error in a --config keeps its own file and line.
sed 's/    iterations: 3/    iterations: -3/' "$SRC/config/replay/kawato_planar_glsdc3.yaml" > badcfg.yaml
line=$(grep -n "iterations: -3" badcfg.yaml | cut -d: -f1)
"$LODE" replay rec.h5 --config badcfg.yaml --quiet > badcfg.txt 2>&1
rc=$?
cat badcfg.txt
[ $rc -eq 2 ] || fail "config error exited $rc, expected 2"
grep -q "badcfg.yaml replaying rec.h5:$line:[0-9]*: blocks.glsdc.iterations" badcfg.txt || fail "error not located at line $line"
# ... and stops the command before anything is replayed, even after a good configuration.
rm -f rec.replay.h5
"$LODE" replay rec.h5 --config "$SRC/config/replay/kawato_planar_cv.yaml" --config badcfg.yaml --quiet > badlast.txt 2>&1
rc=$?
[ $rc -eq 2 ] || fail "a bad last --config exited $rc, expected 2"
[ ! -e rec.replay.h5 ] || fail "a replay ran before the bad last --config was refused"

# A configuration at another rate would step the recorded samples with another period: refused.
sed 's/^rate_hz: 800$/rate_hz: 1600/' "$SRC/config/replay/kawato_planar_cv.yaml" > rate1600.yaml
grep -q "^rate_hz: 1600$" rate1600.yaml || fail "the test could not change the rate"
"$LODE" replay rec.h5 --config rate1600.yaml --quiet > rate.txt 2>&1
rc=$?
cat rate.txt
[ $rc -eq 2 ] || fail "another rate exited $rc, expected 2"
grep -q "rate1600.yaml: rate_hz 1600 differs from the recording's 800 Hz" rate.txt || fail "another rate not explained"

echo "PASS"
