#!/usr/bin/env bash
# Every `lode` command, taken from `lode --help` so that a new one cannot skip this:
#   - `lode CMD --help` prints that command's usage on stdout, nothing on stderr, exits 0, and
#     does nothing else: it creates no file and opens no socket (so no DDS participant and no
#     local command channel), checked with strace;
#   - `lode CMD --no-such-option` exits 2 and names the option;
# and the values the parser checks: a number that is not one, a value out of range, a
# misspelt option (named, with the nearest known one), an unknown command, --version.
# usage: command_line_test.sh LODE_BINARY REPO_DIR
LODE=$(realpath "$1")
REPO=$2
source "$(dirname "$0")/test_lib.sh"
command -v strace >/dev/null || { echo "FAIL: strace not found (apt-get install strace)"; exit 1; }

commands=$("$LODE" --help | sed -n '/^Subcommands:/,/^$/p' | awk 'NR > 1 && NF { print $1 }')
n=$(echo "$commands" | wc -w)
[ "$n" -ge 12 ] && ok "lode --help lists $n commands" || bad "lode --help lists only $n commands: $commands"

work=$TMP/cwd
mkdir "$work"
for c in $commands; do
  (cd "$work" && strace -f -qq -e trace=socket,creat,openat -o "$TMP/$c.strace" \
     "$LODE" "$c" --help >"$TMP/$c.out" 2>"$TMP/$c.err")
  rc=$?
  check_rc "$c --help: exit 0" 0 $rc "$TMP/$c.err"
  contains "$c --help: its usage on stdout" "$TMP/$c.out" "^Usage: lode $c "
  [ -s "$TMP/$c.err" ] && bad "$c --help wrote to stderr: $(head -3 "$TMP/$c.err")" || ok "$c --help: stderr empty"
  if grep -q "socket(" "$TMP/$c.strace"; then
    bad "$c --help opened a socket: $(grep 'socket(' "$TMP/$c.strace" | head -2)"
  else
    ok "$c --help: no socket"
  fi
  if grep -E 'openat\(.*O_(WRONLY|RDWR|CREAT)|creat\(' "$TMP/$c.strace" | grep -vq '/dev/'; then
    bad "$c --help opened a file for writing: $(grep -E 'O_(WRONLY|RDWR|CREAT)' "$TMP/$c.strace" | head -2)"
  else
    ok "$c --help: nothing written"
  fi
  "$LODE" "$c" --no-such-option >"$TMP/$c.bad" 2>&1
  check_rc "$c --no-such-option: exit 2" 2 $? "$TMP/$c.bad"
  contains "$c --no-such-option: named" "$TMP/$c.bad" "unknown option '--no-such-option'"
done
[ -z "$(ls -A "$work")" ] && ok "no file left in the working folder" || bad "files left: $(ls -A "$work")"

# Values the parser checks before a command runs.
CONFIG=$REPO/config/kawato_planar.yaml
expect() {  # LABEL EXIT REGEX ARGS...
  local label=$1 want=$2 regex=$3
  shift 3
  "$LODE" "$@" >"$TMP/expect.out" 2>&1
  check_rc "$label: exit $want" "$want" $? "$TMP/expect.out"
  contains "$label: message" "$TMP/expect.out" "$regex"
}
expect "bench --cycles abc" 2 "--cycles: 'abc' is not an integer" bench "$CONFIG" --cycles abc
expect "run --duration -1" 2 "--duration: '-1' is outside" run "$CONFIG" --duration -1
expect "run --clock wall" 2 "--clock" run "$CONFIG" --clock wall
expect "run --duraton 1" 2 "unknown option '--duraton' \(did you mean --duration\?\)" run "$CONFIG" --duraton 1
expect "run --quite" 2 "unknown option '--quite' \(did you mean --quiet\?\)" run "$CONFIG" --quite
expect "rtcheck --bogus" 2 "unknown option '--bogus'" rtcheck --bogus
expect "topics --domain 999" 2 "--domain: '999' is outside \[0, 232\]" topics --domain 999
expect "set --transport carrier-pigeon" 2 "--transport" set x.y 1 --transport carrier-pigeon
expect "check without CONFIG" 2 "CONFIG is required" check
expect "an unknown command" 2 "^lode: unknown command 'frobnicate'$" frobnicate
expect "a misspelt command" 2 "^lode: unknown command 'runn' \(did you mean run\?\)$" runn "$CONFIG"
expect "--version" 0 "^lode [0-9]+\.[0-9]+\.[0-9]+, plugin ABI [0-9]+" --version
expect "plugins NAME shows that plugin only" 0 "^filter\.biquad " plugins filter.biquad
[ "$(grep -c '^[a-z]' "$TMP/expect.out")" = 1 ] && ok "plugins NAME: one plugin" || bad "plugins NAME listed $(grep -c '^[a-z]' "$TMP/expect.out") plugins"
expect "plugins NOSUCH" 2 "no plugin named 'no.such'" plugins no.such

[ $fail -eq 0 ] && echo "command_line_test: PASSED" || echo "command_line_test: FAILED"
exit $fail
