#!/usr/bin/env bash
# `lode rtcheck --latency` against cyclictest, back to back on this machine, with the same CPU,
# SCHED_FIFO priority and interval (the pipeline's realtime section and period), each for
# SECONDS: prints both sets of percentiles and the ratios lode/cyclictest (goal: p50 and p99
# within 1.2x). Repeats ROUNDS times, alternating which runs first (the machine's load drifts).
#
#   tests/bench/rtcheck_vs_cyclictest.sh [LODE] [CONFIG] [SECONDS] [ROUNDS]
#
# A measurement, not a test. cyclictest (Debian rt-tests) keeps a 1 us histogram; its
# percentiles are the upper edge of the bin they fall in, as lode's are (lode's bins are
# narrower: within 3 %). Needs root or the rtprio/memlock limits `lode rtcheck` checks.
set -u
SRC=$(cd "$(dirname "$0")/../.." && pwd)
LODE=${1:-$SRC/build/apps/lode}
CONFIG=${2:-$SRC/config/kawato_planar.yaml}
SECONDS_TO_RUN=${3:-10}
ROUNDS=${4:-1}
export LODE_PLUGIN_PATH=${LODE_PLUGIN_PATH:-$(dirname "$(dirname "$LODE")")/plugins}
command -v cyclictest >/dev/null || { echo "cyclictest not found (apt-get install rt-tests)"; exit 77; }
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

# The CPU, priority and interval lode measures with: the pipeline's, as rtcheck reads them.
"$LODE" rtcheck "$CONFIG" --json > "$WORK/target.json"
[ $? -le 1 ] || { echo "lode rtcheck $CONFIG failed"; exit 1; }
read -r cpu prio interval < <(python3 -c '
import json, sys
t = json.load(open(sys.argv[1]))["target"]
print(t["cpu"], t["priority"], round(t["period_us"]))' "$WORK/target.json")
affinity=(); [ "$cpu" -ge 0 ] && affinity=(-a "$cpu")

run_lode() {  # round
  "$LODE" rtcheck "$CONFIG" --json --latency "${SECONDS_TO_RUN}s" > "$WORK/lode$1.json"
  [ $? -le 1 ] || { echo "lode rtcheck failed"; exit 1; }
}
run_cyclictest() {  # round
  cyclictest -m -p "$prio" "${affinity[@]}" -i "$interval" -D "$SECONDS_TO_RUN" -h 100000 -q \
    --histfile="$WORK/cyclictest$1.hist" > "$WORK/cyclictest$1.txt" 2>&1 ||
    { echo "cyclictest failed:"; cat "$WORK/cyclictest$1.txt"; exit 1; }
  echo "cyclictest -m -p $prio ${affinity[*]} -i $interval -D $SECONDS_TO_RUN -h 100000 -q" > "$WORK/cyclictest$1.cmd"
}

for round in $(seq 1 "$ROUNDS"); do
  if [ $((round % 2)) = 1 ]; then run_lode "$round"; run_cyclictest "$round"
  else run_cyclictest "$round"; run_lode "$round"; fi
done

python3 - "$WORK" "$ROUNDS" <<'PY'
import json, statistics, sys
work, rounds = sys.argv[1], int(sys.argv[2])
QS = [("min", None), ("p50", 0.5), ("p90", 0.9), ("p99", 0.99), ("p99.9", 0.999), ("max", None)]

def cyclictest_stats(path):
    """Percentiles from cyclictest's histogram: bin k counts wake-ups k..k+1 us late."""
    bins, overflows, mx = [], 0, None
    for line in open(path):
        if line.startswith("# Max Latencies:"):
            mx = int(line.split(":")[1].split()[0])
        elif line.startswith("# Histogram Overflows:"):
            overflows = int(line.split(":")[1].split()[0])
        elif line.strip() and not line.startswith("#"):
            k, n = line.split()[:2]
            if int(n):
                bins.append((int(k), int(n)))
    total = sum(n for _, n in bins) + overflows
    out = {"count": total, "min": bins[0][0] if bins else 0, "max": mx}
    for name, q in QS:
        if q is None:
            continue
        seen, target = 0, q * total
        out[name] = mx
        for k, n in bins:
            seen += n
            if seen >= target:
                out[name] = k + 1  # the bin's upper edge, as lode reports its percentiles
                break
    return out

rows = []
for r in range(1, rounds + 1):
    l = json.load(open(f"{work}/lode{r}.json"))["latency"]
    lode = {"count": l["count"], "min": l["min_us"], "p50": l["p50_us"], "p90": l["p90_us"],
            "p99": l["p99_us"], "p99.9": l["p999_us"], "max": l["max_us"]}
    cyc = cyclictest_stats(f"{work}/cyclictest{r}.hist")
    rows.append((lode, cyc))
    print(f"round {r}: lode rtcheck CPU {l['cpu']} SCHED_FIFO {l['priority']} (fifo={l['sched_fifo']}, "
          f"pinned={l['pinned']}) every {l['period_us']:.0f} us; "
          + open(f"{work}/cyclictest{r}.cmd").read().strip())
    print(f"  {'':12}" + "".join(f"{n:>9}" for n in ["count"] + [q for q, _ in QS]))
    print(f"  {'lode':12}" + f"{lode['count']:>9}" + "".join(f"{lode[q]:>9.1f}" for q, _ in QS))
    print(f"  {'cyclictest':12}" + f"{cyc['count']:>9}" + "".join(f"{cyc[q]:>9.1f}" for q, _ in QS))
    print(f"  {'ratio':12}{'':>9}" + "".join(
        f"{lode[q] / cyc[q]:>9.2f}" if cyc[q] else f"{'-':>9}" for q, _ in QS))
if rounds > 1:
    print("medians over", rounds, "rounds:")
    for q in ("p50", "p99"):
        lm = statistics.median(l[q] for l, _ in rows)
        cm = statistics.median(c[q] for _, c in rows)
        print(f"  {q}: lode {lm:.1f} us, cyclictest {cm:.1f} us, ratio {lm / cm:.2f}")
PY
