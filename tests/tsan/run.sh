#!/usr/bin/env bash
# The whole test suite under ThreadSanitizer:
#
#   tests/tsan/run.sh [BUILD_DIR] [ctest arguments...]
#
# configures BUILD_DIR (default build-tsan) with -DLODE_SANITIZE=thread, builds it, runs ctest
# with every report written to BUILD_DIR/tsan-reports/, and prints each report's summary. Exit
# 0 only when ctest passed and no report was written. Reports inside Fast DDS that TSan cannot
# judge (it is not instrumented) are suppressed in suppressions.txt, each with its reason.
set -u
SRC=$(cd "$(dirname "$0")/../.." && pwd)
BUILD=${1:-$SRC/build-tsan}
shift || true
cmake -S "$SRC" -B "$BUILD" -DLODE_SANITIZE=thread -DLODE_BUILD_BENCHMARKS=OFF >/dev/null || exit 2
cmake --build "$BUILD" -j"$(nproc)" || exit 2
REPORTS=$BUILD/tsan-reports
rm -rf "$REPORTS" && mkdir -p "$REPORTS"
export TSAN_OPTIONS="suppressions=$SRC/tests/tsan/suppressions.txt log_path=$REPORTS/tsan second_deadlock_stack=1"
(cd "$BUILD" && ctest -j"$(nproc)" "$@")
rc=$?
n=0
for f in "$REPORTS"/tsan.*; do
  [ -e "$f" ] || continue
  n=$((n + 1))
  echo "== $f"
  grep -E "^SUMMARY" "$f"
done
echo "ThreadSanitizer: $n process(es) reported"
[ $rc -eq 0 ] && [ $n -eq 0 ]
