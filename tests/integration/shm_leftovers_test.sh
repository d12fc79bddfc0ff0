#!/usr/bin/env bash
# A `lode run` killed with SIGKILL cannot delete its Fast DDS shared memory: its segment (about
# 8.5 MB, every page touched) and its lock file stay in /dev/shm, memory until the host
# reboots. The next lodestone process of the same user that opens DDS with shared memory
# removes them, and leaves a live pipeline's files alone (its samples still arrive).
# usage: shm_leftovers_test.sh LODE SRC
set -u
LODE=$1 SRC=$2
source "$(dirname "$0")/test_lib.sh"
take_private_domain

sed -e "s/^  domain: 0/  domain: $DOMAIN/" -e "s/^realtime: .*/realtime: { overrun_policy: catch_up }/" \
    "$SRC/config/kawato_planar.yaml" >"$TMP/p.yaml"

# The Fast DDS files a process uses: mapped (segments, ports) or open (their lock files).
shm_files() {
  { grep -o '/dev/shm/fastrtps_[^ ]*' "/proc/$1/maps" 2>/dev/null
    for fd in /proc/"$1"/fd/*; do readlink "$fd" 2>/dev/null; done | grep '^/dev/shm/fastrtps_'; } | sort -u
}
# Starts a pipeline (its pid in STARTED_PID) and waits until its segment and the segment's
# lock are in use.
start_pipeline() {  # NAME
  "$LODE" run "$TMP/p.yaml" --clock real --duration 300 --quiet --no-local-control >"$TMP/$1.log" 2>&1 &
  local pid=$!
  PIDS+=("$pid")
  STARTED_PID=$pid
  for _ in $(seq 150); do
    shm_files "$pid" >"$TMP/$1.files"
    grep -qE '/fastrtps_[0-9a-z]{16}$' "$TMP/$1.files" && grep -qE '/fastrtps_[0-9a-z]{16}_el$' "$TMP/$1.files" && break
    sleep 0.2
  done
}

start_pipeline victim; VICTIM=$STARTED_PID
grep -qE '/fastrtps_[0-9a-z]{16}$' "$TMP/victim.files" || { bad "the first pipeline has no shared-memory segment"; exit 1; }
start_pipeline survivor; SURVIVOR=$STARTED_PID
grep -qE "/fastrtps_[0-9a-z]{16}$" "$TMP/survivor.files" || { bad "the second pipeline has no shared-memory segment"; cat "$TMP/survivor.files" "$TMP/survivor.log"; exit 1; }
victim_segment=$(grep -E '/fastrtps_[0-9a-z]{16}$' "$TMP/victim.files" | head -1)
ok "the pipelines use $(wc -l <"$TMP/victim.files") and $(wc -l <"$TMP/survivor.files") shared-memory files; the first's segment: $victim_segment ($(du -k "$victim_segment" | cut -f1) KiB)"

kill -KILL "$VICTIM"; wait "$VICTIM" 2>/dev/null
# Informational: a lodestone process of another test on this host may remove them first.
if [ -e "$victim_segment" ] && [ -e "${victim_segment}_el" ]; then
  ok "killed, the first pipeline left its segment and lock file (what Fast DDS leaves)"
else
  ok "killed, the first pipeline's segment is already gone (another lodestone process on this host removed it)"
fi

# Lock files younger than 2 s are not judged (Fast DDS creates a lock file, then locks it).
sleep 2.5
"$LODE" echo kf.pose --domain "$DOMAIN" --count 1 --wait 30 >"$TMP/echo.out" 2>"$TMP/echo.err"
check_rc "a client beside the second pipeline gets a sample" 0 $? "$TMP/echo.err"

if [ -e "$victim_segment" ] || [ -e "${victim_segment}_el" ]; then
  bad "the killed pipeline's segment is still in /dev/shm after a client started: $(ls -l "$victim_segment"* 2>&1)"
else
  ok "the killed pipeline's segment and lock file were removed when the client started"
fi
missing=0
while read -r file; do
  [ -e "$file" ] || { bad "the live pipeline's $file was removed"; missing=1; }
done <"$TMP/survivor.files"
[ $missing -eq 0 ] && ok "the live pipeline's $(wc -l <"$TMP/survivor.files") files are all there"

kill -INT "$SURVIVOR"; wait "$SURVIVOR"; check_rc "the second pipeline stops cleanly" 0 $? "$TMP/survivor.log"
exit $fail
