#!/usr/bin/env bash
# Two pipelines of one name on one DDS domain (two rigs, or two users, started the same
# configuration): their topics are the same topics, so a command would reach both. While the
# second runs, the first refuses commands and says why; when it leaves, commands are accepted
# again; both changes are "namesake" events, which lode run prints as they happen; and
# `lode echo` warns that the samples it prints come from both. Two runtime directories stand
# for two hosts (on one host and one runtime directory the local control socket already
# refuses the second run).
# usage: namesake_test.sh LODE SRC
set -u
LODE=$1 SRC=$2
source "$(dirname "$0")/test_lib.sh"
take_private_domain
sed -e "s/^  domain: 0/  domain: $DOMAIN/" "$SRC/config/kawato_planar.yaml" >"$TMP/p.yaml"
mkdir -m 700 "$TMP/other_host"

# set_until REGEX VALUE: `lode set ref.offset.x VALUE --dds` until its reply matches, 20 s at most.
set_until() {
  local deadline=$((SECONDS + 20))
  while [ $SECONDS -lt $deadline ]; do
    "$LODE" set ref.offset.x "$2" --dds --domain "$DOMAIN" >"$TMP/set.out" 2>&1
    grep -qE -e "$1" "$TMP/set.out" && return 0
    sleep 0.5
  done
  return 1
}

"$LODE" run "$TMP/p.yaml" --clock real --duration 120 --quiet --summary-json "$TMP/first.json" >"$TMP/first.out" 2>&1 &
first=$!
PIDS+=("$first")
"$LODE" echo kf.pose --domain "$DOMAIN" --count 1 --wait 30 >/dev/null 2>"$TMP/up.err"
check_rc "the first pipeline is up" 0 $? "$TMP/up.err"
set_until "^ok: ref.offset.x" 1e-6 && ok "alone, it takes a command" || bad "alone: $(cat "$TMP/set.out")"
"$LODE" echo kf.pose --domain "$DOMAIN" --count 100 --wait 10 >/dev/null 2>"$TMP/alone.err"
grep -q "pipelines named" "$TMP/alone.err" && bad "alone, lode echo warned: $(cat "$TMP/alone.err")" ||
  ok "alone, lode echo does not warn"

XDG_RUNTIME_DIR=$TMP/other_host "$LODE" run "$TMP/p.yaml" --clock real --duration 120 --quiet >"$TMP/second.out" 2>&1 &
second=$!
PIDS+=("$second")
if set_until "refused: another pipeline named 'kawato_planar' is live on DDS domain $DOMAIN" 2e-6; then
  ok "with a namesake live, the command is refused and the reply says why"
else
  bad "with a namesake live: $(cat "$TMP/set.out")"
fi

"$LODE" echo kf.pose --domain "$DOMAIN" --count 100 --wait 10 >/dev/null 2>"$TMP/echo.err"
contains "lode echo warns that two pipelines of that name are live" "$TMP/echo.err" \
  "warning: 2 pipelines named 'kawato_planar' are live on this domain"

kill -TERM "$second"
wait "$second"
check_rc "the second pipeline stops" 0 $? "$TMP/second.out"
set_until "^ok: ref.offset.x" 3e-6 && ok "once it has left, commands are taken again" ||
  bad "after the namesake left: $(cat "$TMP/set.out")"

kill -TERM "$first"
wait "$first"
check_rc "the first pipeline stops cleanly" 0 $? "$TMP/first.out"
contains "lode run printed it on stderr (with --quiet too)" "$TMP/first.out" \
  "lode: namesake: another pipeline named 'kawato_planar' is live on DDS domain $DOMAIN"
$PY - "$TMP/first.json" >"$TMP/warnings.txt" <<'PY'
import json, sys
for e in json.load(open(sys.argv[1]))["events"]:
    if e["kind"] == "namesake":
        print(e["text"])
PY
contains "a namesake event named the other pipeline" "$TMP/warnings.txt" \
  "another pipeline named 'kawato_planar' is live on DDS domain $DOMAIN: lode-run/kawato_planar@"
contains "a namesake event said when it left" "$TMP/warnings.txt" \
  "no other pipeline named 'kawato_planar' is live on DDS domain $DOMAIN any more"

[ $fail -eq 0 ] && echo PASS
exit $fail
