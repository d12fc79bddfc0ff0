#!/usr/bin/env bash
# Commands that read recordings, under a memory limit: what does not fit in the memory left is
# refused at once, with the file, what it needs and what is left (not an out-of-memory kill,
# nor std::bad_alloc after the run), and what fits runs as ever.
#  - `lode replay` of a 300 s recording (about 195 MB) in a control group limited to 250 MiB:
#    it holds the raw inputs and compares one series at a time (186 MB at its peak), so it
#    runs, bit-identical (holding the whole recording and the replay's file, it used to need
#    about 410 MB and was refused);
#  - the same under 100 MiB: exit 1 and the figures, before anything is replayed;
#  - `lode plot` of it under 250 MiB: it reads only the series it plots (189 MB at its peak,
#    313 MB when it read every series), so it writes its report; under 100 MiB, exit 1 and
#    the figures;
#  - `lode check` of a pipeline whose io.replay block plays it back, under 60 MiB: the
#    recording's reader refuses the raw series it would hold, exit 2;
#  - `lode replay` of a 5 s recording under 200 MiB: bit-identical, exit 0.
# The limit is a control group of this test's own: cgroup v1's memory hierarchy directly, or
# on cgroup v2 a transient scope (systemd-run --scope -p MemoryMax=). Exit 77 (skipped)
# without root or either.
# usage: memory_limit_test.sh LODE SRC
set -u
LODE=$1 SRC=$2
[ "$(id -u)" = 0 ] || { echo "skipped: needs root (a control group with a memory limit)"; exit 77; }
source "$(dirname "$0")/test_lib.sh"
LIMIT=$((200 * 1024 * 1024))

# limited CMD...: CMD in a control group limited to LIMIT bytes; 125 when none can be made.
V1_GROUP=""
v1_memory=$(awk -F: '$2 == "memory" { print $3 }' /proc/self/cgroup)
if [ -n "$v1_memory" ] && [ -d "/sys/fs/cgroup/memory$v1_memory" ]; then
  V1_GROUP="/sys/fs/cgroup/memory$v1_memory/lode_memory_limit_test_$$"
  if mkdir "$V1_GROUP" 2>/dev/null && echo "$LIMIT" >"$V1_GROUP/memory.limit_in_bytes" 2>/dev/null; then
    trap 'cleanup; rmdir "$V1_GROUP" 2>/dev/null' EXIT
  else
    rmdir "$V1_GROUP" 2>/dev/null
    V1_GROUP=""
  fi
fi
limited() {
  if [ -n "$V1_GROUP" ]; then
    echo "$LIMIT" >"$V1_GROUP/memory.limit_in_bytes" || return 125
    bash -c 'echo $$ >"$0/cgroup.procs" && exec "$@"' "$V1_GROUP" "$@"
  else
    systemd-run --quiet --scope -p MemoryMax="$LIMIT" -p MemorySwapMax=0 \
      --setenv=LODE_PLUGIN_PATH="$LODE_PLUGIN_PATH" --setenv=XDG_RUNTIME_DIR="$XDG_RUNTIME_DIR" "$@"
  fi
}
if [ -z "$V1_GROUP" ] && ! limited true 2>/dev/null; then
  echo "skipped: no control group with a memory limit can be made here (cgroup v1 memory, or systemd-run --scope)"
  exit 77
fi

"$LODE" run "$SRC/config/kawato_planar.yaml" --clock sim --duration 300 --no-telemetry --no-local-control --quiet \
  --record "$TMP/long.h5" >"$TMP/long.out" 2>&1
check_rc "a 300 s recording" 0 $? "$TMP/long.out"
"$LODE" run "$SRC/config/kawato_planar.yaml" --clock sim --duration 5 --no-telemetry --no-local-control --quiet \
  --record "$TMP/short.h5" >"$TMP/short.out" 2>&1
check_rc "a 5 s recording" 0 $? "$TMP/short.out"
echo "recordings: $(du -h "$TMP/long.h5" | cut -f1), $(du -h "$TMP/short.h5" | cut -f1)"

LIMIT=$((250 * 1024 * 1024)) limited "$LODE" replay "$TMP/long.h5" --quiet --output "$TMP/long_replay.h5" \
  >"$TMP/replay_long.out" 2>&1
check_rc "replay of the 300 s recording under 250 MiB" 0 $? "$TMP/replay_long.out"
contains "bit-identical" "$TMP/replay_long.out" "^bit-identical: 13 series x 240000 cycles"

start=$(date +%s.%N)
LIMIT=$((100 * 1024 * 1024)) limited "$LODE" replay "$TMP/long.h5" --quiet --output "$TMP/long_replay2.h5" \
  >"$TMP/replay_refused.out" 2>&1
check_rc "replay of the 300 s recording under 100 MiB: refused" 1 $? "$TMP/replay_refused.out"
seconds=$(awk -v s="$start" -v e="$(date +%s.%N)" 'BEGIN { printf "%.2f", e - s }')
contains "it names the file and what it needs" "$TMP/replay_refused.out" \
  "lode: replay: .*long\.h5 \(19[0-9] MB\) needs about [0-9]+ MB of memory"
contains "and what is left" "$TMP/replay_refused.out" "this process has [0-9]+ MB left"
if [ ! -e "$TMP/long_replay2.h5" ]; then ok "nothing replayed (no output file), ${seconds} s"; else bad "an output file was written"; fi
if grep -q "bad_alloc" "$TMP/replay_refused.out"; then bad "std::bad_alloc reported"; fi

LIMIT=$((250 * 1024 * 1024)) limited "$LODE" plot "$TMP/long.h5" -o "$TMP/long.html" >"$TMP/plot_long.out" 2>&1
rc=$?
if grep -q "built without its chart library" "$TMP/plot_long.out"; then
  echo "(lode plot was built without its chart library: its cases are not run)"
else
  check_rc "plot of the 300 s recording under 250 MiB" 0 $rc "$TMP/plot_long.out"
  contains "its report" "$TMP/plot_long.out" "long\.html: 14 figures, 240000 samples per curve"
  LIMIT=$((100 * 1024 * 1024)) limited "$LODE" plot "$TMP/long.h5" -o "$TMP/long2.html" >"$TMP/plot_refused.out" 2>&1
  check_rc "plot of the 300 s recording under 100 MiB: refused" 1 $? "$TMP/plot_refused.out"
  contains "with the figures" "$TMP/plot_refused.out" \
    "lode: plot: .*long\.h5 needs about [0-9]+ MB of memory .*; this process has [0-9]+ MB left"
  if [ ! -e "$TMP/long2.html" ]; then ok "no report written"; else bad "a report was written"; fi
fi

printf 'pipeline: replay_only\nrate_hz: 800\nblocks:\n  stage:\n    plugin: io.replay\n    recording: long.h5\n' \
  >"$TMP/io_replay.yaml"
# The reader holds the board's 4 raw series, about 67 MB of it: under 60 MiB.
LIMIT=$((60 * 1024 * 1024)) limited "$LODE" check "$TMP/io_replay.yaml" >"$TMP/check_long.out" 2>&1
check_rc "io.replay of the 300 s recording under 60 MiB: refused" 2 $? "$TMP/check_long.out"
contains "by the recording's reader, with its figures" "$TMP/check_long.out" \
  "long\.h5': reading its 4 series takes about [0-9]+ MB of memory and this process has [0-9]+ MB left"

limited "$LODE" replay "$TMP/short.h5" --quiet --output "$TMP/short_replay.h5" >"$TMP/replay_short.out" 2>&1
check_rc "replay of the 5 s recording under 200 MiB" 0 $? "$TMP/replay_short.out"
contains "bit-identical" "$TMP/replay_short.out" "^bit-identical: 13 series x 4000 cycles"
exit $fail
