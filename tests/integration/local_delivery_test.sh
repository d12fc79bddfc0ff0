#!/usr/bin/env bash
# A pipeline's samples to a client on the same host (the default `loopback` transport):
#  - run by the same user, they come through shared memory alone: 2 s of `lode echo` at 1 kHz
#    cost the host a few hundred UDP datagrams (discovery, heartbeats), not one more per
#    sample as when every sample also went out as a datagram on 127.0.0.1;
#  - run by another user (the packaged service runs as `lode`, an engineer watches it as
#    themselves), they come over UDP: the pipeline and the client discover each other and the
#    samples arrive, both ways round, and a client that read through shared memory goes on
#    over UDP when a pipeline of that name turns up run by another user.
# Runs in a network namespace of its own (so the UDP counters are this test's alone) and needs
# root for it and for running a process as another user (nobody); exit 77 (skipped) without.
# usage: local_delivery_test.sh LODE SRC
set -u
LODE=$1 SRC=$2
if [ "$(id -u)" != 0 ] || ! command -v unshare >/dev/null || ! command -v setpriv >/dev/null; then
  echo "skipped: needs root, unshare and setpriv (a network namespace, a second user)"
  exit 77
fi
if [ -z "${LODE_TEST_IN_NETNS:-}" ]; then
  exec unshare -n env LODE_TEST_IN_NETNS=1 bash "$0" "$@"
fi
source "$(dirname "$0")/test_lib.sh"
# The namespace's loopback interface starts down.
$PY - <<'PYEOF'
import fcntl, socket, struct
SIOCGIFFLAGS, SIOCSIFFLAGS, IFF_UP = 0x8913, 0x8914, 0x1
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
flags = struct.unpack("16sH", fcntl.ioctl(s, SIOCGIFFLAGS, struct.pack("16sH", b"lo", 0)))[1]
fcntl.ioctl(s, SIOCSIFFLAGS, struct.pack("16sH", b"lo", flags | IFF_UP))
PYEOF
take_private_domain
sed -e "s/^  domain: 0/  domain: $DOMAIN/" -e "s/^rate_hz: 800/rate_hz: 1000/" -e "s/^  rate_hz: 800 .*/  rate_hz: 1000/" \
  "$SRC/config/kawato_planar.yaml" >"$TMP/p.yaml"
chmod 755 "$TMP"
chmod 644 "$TMP/p.yaml"

udp_sent() { awk '/^Udp: [0-9]/ { print $5 }' /proc/net/snmp; }

# --- the same user: shared memory alone -----------------------------------------------------
"$LODE" run "$TMP/p.yaml" --clock real --duration 60 --quiet >"$TMP/same.out" 2>&1 &
PIDS+=($!)
"$LODE" echo kf.pose --domain "$DOMAIN" --count 1 --wait 30 >/dev/null 2>"$TMP/up.err"
check_rc "the pipeline is up" 0 $? "$TMP/up.err"
# Counted over 2 s once the echo is under way: its discovery (64 peer ports, a few
# announcements each) is over by then, and at 1 kHz a datagram per sample would be 2000.
"$LODE" echo kf.pose --domain "$DOMAIN" --count 5000 --wait 30 --quiet 2>"$TMP/echo.err" &
echo_pid=$!
sleep 2
before=$(udp_sent)
sleep 2
datagrams=$(($(udp_sent) - before))
wait $echo_pid
check_rc "lode echo takes 5000 samples" 0 $? "$TMP/echo.err"
if [ "$datagrams" -lt 800 ]; then
  ok "2 s of samples cost the host $datagrams UDP datagrams (shared memory carried them)"
else
  bad "2 s of samples cost the host $datagrams UDP datagrams: they went out over UDP as well as shared memory"
fi
kill -TERM "${PIDS[-1]}"; wait "${PIDS[-1]}" 2>/dev/null

# --- another user -------------------------------------------------------------------------
NOBODY=(setpriv --reuid=65534 --regid=65534 --clear-groups env HOME="$TMP/nobody" XDG_RUNTIME_DIR="$TMP/nobody/run")
mkdir -p "$TMP/nobody/run" && chmod 700 "$TMP/nobody/run" && chown -R 65534:65534 "$TMP/nobody"
if ! "${NOBODY[@]}" test -x "$LODE" -a -r "$TMP/p.yaml" -a -r "$LODE_PLUGIN_PATH"; then
  echo "not run: user nobody cannot reach $LODE (a build under a private home?)"
  exit $fail
fi
# echo_as WHO LABEL: lode echo as WHO ("" or nobody) of a pipeline run by the other one.
echo_as() {
  local out=$TMP/echo_$1.err
  if [ "$1" = nobody ]; then
    "${NOBODY[@]}" "$LODE" echo kf.pose --domain "$DOMAIN" --count 300 --wait 30 --quiet 2>"$out"
  else
    "$LODE" echo kf.pose --domain "$DOMAIN" --count 300 --wait 30 --quiet 2>"$out"
  fi
  check_rc "$2" 0 $? "$out"
  contains "$2: 300 samples" "$out" "300 samples"
}
"${NOBODY[@]}" LODE_PLUGIN_PATH="$LODE_PLUGIN_PATH" "$LODE" run "$TMP/p.yaml" --clock real --duration 60 --quiet \
  >"$TMP/nobody/run.out" 2>&1 &
PIDS+=($!)
echo_as root "the pipeline run by nobody, lode echo by root"
kill -TERM "${PIDS[-1]}"; wait "${PIDS[-1]}" 2>/dev/null
"$LODE" run "$TMP/p.yaml" --clock real --duration 60 --quiet >"$TMP/root.out" 2>&1 &
PIDS+=($!)
echo_as nobody "the pipeline run by root, lode echo by nobody"

# A client reading through shared memory when a pipeline of that name turns up run by another
# user (a restart, or a namesake as here): it goes on over UDP, and so takes that pipeline's
# samples too, from a second publisher. Shared memory alone, it would never see them.
"$LODE" echo kf.pose --domain "$DOMAIN" --count 4000 --wait 30 --quiet 2>"$TMP/both.err" &
echo_pid=$!
sleep 1
"${NOBODY[@]}" "$LODE" run "$TMP/p.yaml" --clock real --duration 60 --quiet >"$TMP/nobody/run2.out" 2>&1 &
PIDS+=($!)
wait $echo_pid
check_rc "lode echo takes 4000 samples with another user's namesake turning up" 0 $? "$TMP/both.err"
if grep -qE "from [2-9] publishers" "$TMP/both.err"; then
  ok "the other user's pipeline reached it too: $(grep -oE 'from [0-9]+ publishers' "$TMP/both.err")"
else
  bad "only the first pipeline's samples arrived: $(grep -E "samples," "$TMP/both.err")"
fi
for p in "${PIDS[@]: -2}"; do kill -TERM "$p" 2>/dev/null; wait "$p" 2>/dev/null; done
exit $fail
