#!/usr/bin/env bash
# Deliberately broken builds: each mutant in mutants.tsv breaks the code in one place, and the
# test named beside it must then fail. A test that stays green against its mutant cannot
# catch that bug. Not part of ctest (each mutant needs a rebuild); run it after changing a test
# or the code a test guards:
#
#   tests/mutants/run.sh [SCRATCH_DIR] [NAME_REGEX]
#
# It copies the committed tree (HEAD) into SCRATCH_DIR (default /tmp/lode-mutants), builds it
# once, then per mutant: applies the edit, rebuilds, runs the ctest regex, expects a failure,
# restores the file. A mutant whose edit no longer applies (the code moved) is reported as
# STALE, never silently passed. Exit 0 only when every mutant was caught.
set -u
SRC=$(cd "$(dirname "$0")/../.." && pwd)
WORK=${1:-/tmp/lode-mutants}
ONLY=${2:-.}
TREE=$WORK/src BUILD=$WORK/build
mkdir -p "$WORK"
if [ ! -d "$TREE/.git" ] && [ ! -f "$TREE/.git" ]; then
  git -C "$SRC" worktree add --detach "$TREE" HEAD >/dev/null
else
  git -C "$TREE" checkout --detach -q "$(git -C "$SRC" rev-parse HEAD)" && git -C "$TREE" checkout -q -- .
fi
cmake -S "$TREE" -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DLODE_BUILD_BENCHMARKS=OFF >"$WORK/configure.log" 2>&1 \
  || { echo "configure failed: $WORK/configure.log"; exit 2; }
cmake --build "$BUILD" -j"$(nproc)" >"$WORK/build.log" 2>&1 || { echo "build failed: $WORK/build.log"; exit 2; }

caught=0 missed=0 stale=0
printf '%-34s %-8s %s\n' mutant result "test (what failed)"
while IFS=$'\t' read -r name file edit tests; do
  case "$name" in ''|'#'*) continue ;; esac
  [[ "$name" =~ $ONLY ]] || continue
  before=$(sha1sum "$TREE/$file" | cut -d' ' -f1)
  perl -0pi -e "$edit" "$TREE/$file"
  if [ "$(sha1sum "$TREE/$file" | cut -d' ' -f1)" = "$before" ]; then
    printf '%-34s %-8s %s\n' "$name" STALE "the edit no longer applies to $file"
    stale=$((stale + 1)); continue
  fi
  log=$WORK/$name.log
  if ! cmake --build "$BUILD" -j"$(nproc)" >"$log" 2>&1; then
    printf '%-34s %-8s %s\n' "$name" STALE "the mutant does not build ($log)"
    stale=$((stale + 1))
  elif (cd "$BUILD" && ctest -R "$tests" --output-on-failure -j"$(nproc)" >>"$log" 2>&1); then
    printf '%-34s %-8s %s\n' "$name" MISSED "$tests passed against the mutant ($log)"
    missed=$((missed + 1))
  else
    failed=$(sed -n 's/^[[:space:]]*[0-9]* - \(.*\) (Failed.*/\1/p' "$log" | sed 's/  # GetParam.*//' | head -3 | paste -sd, -)
    printf '%-34s %-8s %s\n' "$name" caught "${failed:-$tests}"
    caught=$((caught + 1))
  fi
  git -C "$TREE" checkout -q -- "$file"
done <"$SRC/tests/mutants/mutants.tsv"
cmake --build "$BUILD" -j"$(nproc)" >/dev/null 2>&1  # leave the scratch build unmutated
echo "caught $caught, missed $missed, stale $stale"
[ "$missed" = 0 ] && [ "$stale" = 0 ]
