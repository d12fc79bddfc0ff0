#!/bin/bash
# The deterministic side of the framework overhead: instructions per kawato_planar cycle of each
# way (by hand, direct, scheduler, scheduler + digest), counted by callgrind, which a loaded host
# cannot disturb. lode_framework_overhead_bench's "kawato_planar/instructions" runs each way's
# cycles inside its own function (after checking that all ways give the same outputs and a
# second of warm-up); callgrind counts only inside those functions, and callgrind_annotate gives
# each one's inclusive count.
#
#   tests/bench/framework_overhead_instructions.sh [build-dir]     (default: build)
#
# Exit 77 when valgrind is missing.
set -euo pipefail
build=${1:-build}
bench="$build/tests/lode_framework_overhead_bench"
[ -x "$bench" ] || { echo "no $bench: build the target lode_framework_overhead_bench first" >&2; exit 1; }
command -v valgrind >/dev/null && command -v callgrind_annotate >/dev/null ||
  { echo "valgrind (callgrind, callgrind_annotate) is not installed" >&2; exit 77; }

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
ways=(by_hand direct scheduler scheduler_digest)
toggles=()
for w in "${ways[@]}"; do toggles+=("--toggle-collect=*instructions_${w}(*"); done
if ! valgrind --tool=callgrind --callgrind-out-file="$work/callgrind.out" "${toggles[@]}" \
    "$bench" --benchmark_filter=kawato_planar/instructions --benchmark_format=json >"$work/bench.json" 2>"$work/valgrind.log"; then
  cat "$work/valgrind.log" >&2
  exit 1
fi
if grep -q '"error_occurred": true' "$work/bench.json"; then
  grep '"error_message"' "$work/bench.json" >&2
  exit 1
fi
cycles=$(sed -n 's/.*"cycles_per_way": *\([0-9.e+]*\).*/\1/p' "$work/bench.json" | head -1)
[ -n "$cycles" ] || { echo "the benchmark did not report cycles_per_way" >&2; exit 1; }
callgrind_annotate --inclusive=yes --threshold=100 "$work/callgrind.out" >"$work/annotate.txt"

declare -A per_cycle
for w in "${ways[@]}"; do
  ir=$(grep -E "::instructions_${w}\(" "$work/annotate.txt" | head -1 | awk '{gsub(",", "", $1); print $1}')
  [ -n "$ir" ] || { echo "callgrind counted nothing in instructions_${w}" >&2; exit 1; }
  per_cycle[$w]=$(awk -v ir="$ir" -v n="$cycles" 'BEGIN { printf "%.0f", ir / n }')
done
printf '%-18s %12s %10s\n' way instr/cycle "vs by hand"
for w in "${ways[@]}"; do
  awk -v w="$w" -v x="${per_cycle[$w]}" -v b="${per_cycle[by_hand]}" \
    'BEGIN { printf "%-18s %12d %+9.1f %%\n", w, x, 100 * (x / b - 1) }'
done
