#!/usr/bin/env bash
# The local command channel end to end, no Fast DDS: a runner of config/maglev6_hybrid.yaml on
# the real clock serves $XDG_RUNTIME_DIR/lode/maglev6_hybrid.sock; `lode set` / `lode swap`
# (separate processes) and raw clients (python) command it.
#   Part A: tests/integration/local_control_server (ControlService + LocalControlServer).
#   Part B: `lode run` itself (--no-telemetry, with telemetry, --no-local-control).
# usage: local_control_test.sh LODE SOURCE_DIR LOCAL_CONTROL_SERVER
set -u
LODE=$1
SRC=$2
SERVER=$3
PY=/usr/bin/python3
source "$(dirname "$0")/private_domain.sh"
TMP=$(mktemp -d)
RUNNER_PID=
cleanup() {
  [ -n "$RUNNER_PID" ] && kill -KILL "$RUNNER_PID" 2>/dev/null
  rm -rf "$TMP"
}
trap cleanup EXIT
# Our own runtime dir: parallel tests (and a developer's own runs) never collide.
export XDG_RUNTIME_DIR=$TMP/run
mkdir -m 700 "$XDG_RUNTIME_DIR"
SOCK=$XDG_RUNTIME_DIR/lode/maglev6_hybrid.sock
CONFIG=$SRC/config/maglev6_hybrid.yaml
fail=0
check() {  # name expected_rc actual_rc
  if [ "$2" != "$3" ]; then echo "FAIL: $1: exit code $3, expected $2"; fail=1; else echo "ok: $1"; fi
}
check_nonzero() {  # name actual_rc
  if [ "$2" = 0 ]; then echo "FAIL: $1: exit code 0, expected non-zero"; fail=1; else echo "ok: $1 (exit $2)"; fi
}
show() { sed 's/^/    | /' "$1"; }  # the replies, for whoever reads the log
contains() {  # name file pattern
  if grep -qE -- "$3" "$2"; then echo "ok: $1"; else echo "FAIL: $1: no /$3/ in:"; cat "$2"; fail=1; fi
}

wait_for_socket() {  # log: waits until the runner answers on the socket (loading takes seconds)
  for _ in $(seq 1 600); do
    if [ -S "$SOCK" ] && "$LODE" set --local --pipeline maglev6_hybrid --list >/dev/null 2>&1; then return 0; fi
    if ! kill -0 "$RUNNER_PID" 2>/dev/null; then echo "FAIL: runner exited early:"; cat "$1"; return 1; fi
    sleep 0.1
  done
  echo "FAIL: no live socket at $SOCK after 60 s:"; cat "$1"; return 1
}

# One runner, every check. $1 = label, rest = the runner's command line.
exercise() {
  local label=$1; shift
  local log=$TMP/$label.runner.log
  "$@" >"$log" 2>&1 &
  RUNNER_PID=$!
  wait_for_socket "$log" || { fail=1; return; }
  echo "--- $label: runner pid $RUNNER_PID serves $SOCK"

  [ "$(stat -c %a "$XDG_RUNTIME_DIR/lode")" = 700 ] && [ "$(stat -c %a "$SOCK")" = 600 ] \
    && echo "ok: $label: directory 0700, socket 0600" \
    || { echo "FAIL: $label: modes $(stat -c %a "$XDG_RUNTIME_DIR/lode") $(stat -c %a "$SOCK")"; fail=1; }

  # Bash completion of `lode set` offers the live parameters of this runner (local socket).
  local completion
  completion=$(bash -c 'source <("$1" --bash-completion); COMP_WORDS=("$1" set observer.); COMP_CWORD=2; _lode
                        echo "${COMPREPLY[*]}"' _ "$LODE")
  [ "$completion" = "observer.d" ] && echo "ok: $label: completion of 'lode set observer.' is observer.d" \
    || { echo "FAIL: $label: completion of 'lode set observer.' gave '$completion'"; fail=1; }

  "$LODE" set --list >"$TMP/list.out" 2>&1; check "$label: set --list (the one local pipeline)" 0 $?
  contains "$label: list names observer.d with its range" "$TMP/list.out" '^observer\.d \[0, 1\]'
  contains "$label: list reply line" "$TMP/list.out" '^ok: [0-9]+ runtime parameters'

  "$LODE" set observer.d 0.2 >"$TMP/set.out" 2>&1; check "$label: set observer.d 0.2" 0 $?
  show "$TMP/set.out"
  contains "$label: reply gives old and new value" "$TMP/set.out" '^ok: observer\.d: 1 -> 0\.2 at cycle [0-9]+'
  "$LODE" set maglev6_hybrid/observer.d >"$TMP/get.out" 2>&1; check "$label: read back with PIPELINE/ prefix" 0 $?
  contains "$label: value in force" "$TMP/get.out" '^ok: observer\.d = 0\.2'

  "$LODE" set observer.d 7 >"$TMP/range.out" 2>&1; check_nonzero "$label: out-of-range value refused" $?
  show "$TMP/range.out"
  contains "$label: refusal says why" "$TMP/range.out" "^error: set observer\.d: value 7 is outside \[0, 1\]; unchanged"
  "$LODE" set observer.d >"$TMP/get2.out" 2>&1
  contains "$label: refused value left 0.2 in force" "$TMP/get2.out" '^ok: observer\.d = 0\.2'

  "$LODE" swap observer estimator.no_such_plugin --timeout 20 >"$TMP/swap.out" 2>&1
  check_nonzero "$label: swap to a missing plugin refused over the socket" $?
  show "$TMP/swap.out"
  contains "$label: swap reply printed" "$TMP/swap.out" '^error: '

  "$LODE" set --local --pipeline nosuch observer.d 0.3 >"$TMP/nosuch.out" 2>&1; check_nonzero "$label: --local to a pipeline not running" $?
  contains "$label: says no local pipeline" "$TMP/nosuch.out" "no local pipeline at .*/nosuch\.sock"
  "$LODE" set --local --dds observer.d 0.3 >"$TMP/both.out" 2>&1; check "$label: --local with --dds is a usage error" 2 $?

  # Raw clients: malformed lines get an ok=false reply naming the problem; the connection
  # stays usable. Then two clients at once, interleaving requests on kept-open connections.
  "$PY" - "$SOCK" >"$TMP/raw.out" 2>&1 <<'EOF'
import json, socket, sys, threading
path = sys.argv[1]
def client():
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    s.settimeout(10)
    s.connect(path)
    return s, s.makefile("r")
s, f = client()
s.sendall(b'set observer.d 0.3\n{"id": 77, "kind": "set", "block": ["observer"]}\n{"id": 78, "kind": "get", "block": "observer", "name": "d"}\n')
for _ in range(3):
    r = json.loads(f.readline())
    print("raw reply", r["id"], r["ok"], r["message"])
s.close()
results = []
def hammer(tag):
    c, cf = client()
    ok = 0
    for k in range(50):
        c.sendall((json.dumps({"id": tag * 1000 + k, "kind": "get", "block": "observer", "name": "d"}) + "\n").encode())
        r = json.loads(cf.readline())
        ok += r["ok"] and r["id"] == tag * 1000 + k and r["value"] == "0.2"
    results.append(ok)
    c.close()
threads = [threading.Thread(target=hammer, args=(t,)) for t in (1, 2)]
[t.start() for t in threads]
[t.join() for t in threads]
print("concurrent ok", sum(results), "of 100")
EOF
  check "$label: raw python clients" 0 $?
  show "$TMP/raw.out"
  contains "$label: non-JSON line refused" "$TMP/raw.out" "^raw reply 0 False malformed request: column 1: expected '\{'"
  contains "$label: nested value refused, id kept" "$TMP/raw.out" '^raw reply 77 False malformed request: .*"block": nested objects and arrays are not accepted'
  contains "$label: connection still serves" "$TMP/raw.out" '^raw reply 78 True observer\.d = 0\.2'
  contains "$label: two concurrent raw clients" "$TMP/raw.out" '^concurrent ok 100 of 100'
  # Two `lode set` processes at once.
  "$LODE" set observer.d 0.2 >"$TMP/c1.out" 2>&1 & c1=$!
  "$LODE" set observer.d 0.2 >"$TMP/c2.out" 2>&1 & c2=$!
  wait $c1; r1=$?; wait $c2; r2=$?
  check "$label: two concurrent lode set (1)" 0 $r1
  check "$label: two concurrent lode set (2)" 0 $r2

  # A second run of the same pipeline is refused and leaves the first one alone.
  "$SERVER" "$CONFIG" --hold --duration 5 >"$TMP/second.out" 2>&1; check "$label: second run refused" 1 $?
  show "$TMP/second.out"
  contains "$label: second run names the first" "$TMP/second.out" "pipeline maglev6_hybrid is already running locally \(pid $RUNNER_PID,"
  if [ "$label" = lode_run ]; then
    "$LODE" run "$CONFIG" --clock real --duration 5 --no-telemetry --quiet >"$TMP/second_run.out" 2>&1
    check "$label: second lode run of the same pipeline refused" 1 $?
    contains "$label: lode run names the first run" "$TMP/second_run.out" \
      "pipeline maglev6_hybrid is already running locally \(pid $RUNNER_PID,.*nothing was started"
  fi
  "$LODE" set observer.d >/dev/null 2>&1; check "$label: first run still serves" 0 $?

  kill -INT "$RUNNER_PID"; wait "$RUNNER_PID"; local rc=$?; RUNNER_PID=
  check "$label: runner stops cleanly on SIGINT" 0 $rc
  if [ -e "$SOCK" ]; then echo "FAIL: $label: socket file left behind"; fail=1; else echo "ok: $label: socket removed on stop"; fi
  "$LODE" set --local observer.d >"$TMP/gone.out" 2>&1; check_nonzero "$label: nothing to command after stop" $?
  contains "$label: says no pipeline runs" "$TMP/gone.out" "no pipeline runs on this host with a local command socket"
}

# --- Part A: the test-only runner ---------------------------------------------------------
exercise server "$SERVER" "$CONFIG" --clock real --duration 60
contains "server: it served the requests above" "$TMP/server.runner.log" "^served: connections [0-9]+ requests [0-9]+ malformed 2"
contains "server: parameter change in the event log names the local client" "$TMP/server.runner.log" \
  "event \[parameter\] observer\.d: 1 -> 0\.2 at cycle [0-9]+ \(by lode-set-[0-9]+@.* via local pid [0-9]+ uid [0-9]+\)"

# A crashed run leaves its socket: clients say it is stale, the next run replaces it.
"$SERVER" "$CONFIG" --hold --duration 30 >"$TMP/crash.log" 2>&1 &
RUNNER_PID=$!
for _ in $(seq 1 600); do [ -S "$SOCK" ] && break; sleep 0.1; done
kill -KILL "$RUNNER_PID"; wait "$RUNNER_PID" 2>/dev/null; RUNNER_PID=
[ -S "$SOCK" ] && echo "ok: crash leaves the socket file" || { echo "FAIL: no socket after the crash"; fail=1; }
"$LODE" set --local --pipeline maglev6_hybrid observer.d >"$TMP/stale.out" 2>&1; check_nonzero "stale socket: command fails" $?
contains "stale socket: says so" "$TMP/stale.out" "is stale: nothing listens there"
"$SERVER" "$CONFIG" --hold --duration 30 >"$TMP/restart.log" 2>&1 &
RUNNER_PID=$!
for _ in $(seq 1 600); do "$LODE" set --local observer.d >/dev/null 2>&1 && break; sleep 0.1; done
"$LODE" set --local observer.d >"$TMP/restart.out" 2>&1; check "stale socket replaced by the next run" 0 $?
contains "restart: replaced" "$TMP/restart.log" "replaced a stale socket"
kill -INT "$RUNNER_PID"; wait "$RUNNER_PID"; RUNNER_PID=

# --- Part B: `lode run` itself ----------------------------------------------------------------
# (This part once ran only when `lode`'s usage listed --no-local-control; since the usage
# became per command it was skipped without anyone noticing. It always runs now.)
{
  exercise lode_run "$LODE" run "$CONFIG" --clock real --duration 20 --no-telemetry --quiet --summary-json "$TMP/run.json"
  contains "lode run: summary counts the local requests" "$TMP/run.json" '"local_control": \{'
  contains "lode run: summary names the socket" "$TMP/run.json" "\"socket\": \"$SOCK\""
  # A set refused before it reached the RT thread (out of range) is an event at the cycle then
  # running, not at cycle 0 of a run that had long started.
  if "$PY" - "$TMP/run.json" <<'EOF'; then echo "ok: lode run: a refused set is an event at its cycle"; else echo "FAIL: lode run: refused-set event"; fail=1; fi
import json, sys
events = [e for e in json.load(open(sys.argv[1]))["events"] if e["kind"] == "command_failed" and "outside" in e["text"]]
print("   ", [(e["cycle"], e["text"][:60]) for e in events])
sys.exit(0 if events and all(e["cycle"] > 0 for e in events) else 1)
EOF
  # With telemetry on, both channels reach the same ControlService: set over DDS (--dds), read
  # back over the socket, on a DDS domain of its own.
  take_private_domain
  "$LODE" run "$CONFIG" --clock real --duration 60 --domain "$DOMAIN" --quiet >"$TMP/both.runner.log" 2>&1 &
  RUNNER_PID=$!
  wait_for_socket "$TMP/both.runner.log" || fail=1
  "$LODE" set --dds --domain "$DOMAIN" --transport loopback --timeout 10 observer.d 0.3 >"$TMP/dds_set.out" 2>&1
  check "telemetry on: set over DDS (--dds)" 0 $?
  show "$TMP/dds_set.out"
  "$LODE" set observer.d >"$TMP/dds_get.out" 2>&1; check "telemetry on: read back locally" 0 $?
  contains "telemetry on: the socket sees the DDS change" "$TMP/dds_get.out" '^ok: observer\.d = 0\.3'
  kill -INT "$RUNNER_PID"; wait "$RUNNER_PID"; check "telemetry on: run stops cleanly" 0 $?; RUNNER_PID=
  [ -e "$SOCK" ] && { echo "FAIL: telemetry on: socket left behind"; fail=1; }
  # --local --wait: a command given while the pipeline still loads waits for its socket.
  "$LODE" run "$CONFIG" --clock real --duration 3 --no-telemetry --quiet >"$TMP/late.log" 2>&1 &
  RUNNER_PID=$!
  "$LODE" set --local --wait 30 observer.d >"$TMP/late.out" 2>&1
  check "--local --wait: a command waits for a pipeline still starting" 0 $?
  wait "$RUNNER_PID"; RUNNER_PID=
  "$LODE" set --local --wait 0.5 observer.d >"$TMP/none.out" 2>&1
  check "--local --wait: none came up within the wait" 1 $?
  # Without --local, --wait looks on DDS and on this host together: a pipeline still starting
  # without telemetry is commanded through its socket as soon as it is up (this waited the whole
  # --wait for DDS, and said no pipeline was publishing, before it looked at the socket again).
  "$LODE" run "$CONFIG" --clock real --duration 30 --no-telemetry --quiet >"$TMP/start.log" 2>&1 &
  RUNNER_PID=$!
  started=$EPOCHREALTIME
  "$LODE" set --list --wait 20 >"$TMP/start.out" 2>&1
  check "--wait: a command given as the pipeline starts" 0 $?
  took=$(awk -v a="$started" -v b="$EPOCHREALTIME" 'BEGIN { printf "%.1f", b - a }')
  [ -n "$took" ] && awk -v t="$took" 'BEGIN { exit !(t < 10) }' && echo "ok: --wait: answered after $took s, not after the whole 20 s wait" \
    || { echo "FAIL: --wait: answered after $took s (the whole wait: the socket was not looked at)"; fail=1; }
  if grep -q "no pipeline is publishing" "$TMP/start.out"; then
    echo "FAIL: --wait: says no pipeline is publishing, then answers:"; cat "$TMP/start.out"; fail=1
  else
    echo "ok: --wait: no false error"
  fi
  kill -INT "$RUNNER_PID"; wait "$RUNNER_PID"; RUNNER_PID=
  # A swap whose newcomer runs as a shadow for 7 s (longer than the 5 s default --timeout):
  # `lode swap` waits for it, and meanwhile the pipeline answers other commands at once (a set
  # used to wait behind the swap and time out); a second swap is refused while the shadow runs.
  "$LODE" run "$CONFIG" --clock real --duration 30 --no-telemetry --quiet >"$TMP/shadow.log" 2>&1 &
  RUNNER_PID=$!
  wait_for_socket "$TMP/shadow.log" || fail=1
  HYBRID='{d: 0.9, q: [1.0e3, 1.0e3, 1.0e5, 1.0e9, 1.0e9, 1.0e9], r: 1.0e-6, hinf_theta: [8.0e5, 8.0e5, 8.0e5, 5.0e5, 5.0e5, 5.0e5], hinf_error_weight: [1, 0, 0], output: filtered}'
  "$LODE" swap observer estimator.hybrid_h2hinf --params "$HYBRID" --shadow-cycles 5600 >"$TMP/shadow_swap.out" 2>&1 &
  swapper=$!
  sleep 1.5
  started=$EPOCHREALTIME
  "$LODE" set observer.d >"$TMP/shadow_get.out" 2>&1
  check "shadow swap: a get while the shadow runs" 0 $?
  took=$(awk -v a="$started" -v b="$EPOCHREALTIME" 'BEGIN { printf "%.1f", b - a }')
  awk -v t="$took" 'BEGIN { exit !(t < 3) }' && echo "ok: shadow swap: the get was answered after $took s" \
    || { echo "FAIL: shadow swap: the get waited $took s behind the swap"; fail=1; }
  "$LODE" swap observer estimator.hybrid_h2hinf --params "$HYBRID" >"$TMP/shadow_second.out" 2>&1
  check "shadow swap: a second swap meanwhile is refused" 1 $?
  contains "shadow swap: ... saying why" "$TMP/shadow_second.out" "^error: swap: the newcomer for observer still runs as a shadow"
  wait "$swapper"; check "shadow swap: lode swap waits out the shadow period" 0 $?
  show "$TMP/shadow_swap.out"
  contains "shadow swap: ... and reports the swap" "$TMP/shadow_swap.out" "^ok: swapped observer: estimator.hybrid_h2hinf -> estimator.hybrid_h2hinf at cycle"
  kill -INT "$RUNNER_PID"; wait "$RUNNER_PID"; RUNNER_PID=
  # --no-local-control: no socket at all.
  "$LODE" run "$CONFIG" --clock real --duration 1.5 --no-telemetry --no-local-control --quiet >"$TMP/nolocal.log" 2>&1 &
  RUNNER_PID=$!
  sleep 1
  if [ -e "$SOCK" ]; then echo "FAIL: --no-local-control still made $SOCK"; fail=1; else echo "ok: --no-local-control makes no socket"; fi
  wait "$RUNNER_PID"; check "--no-local-control run completes" 0 $?; RUNNER_PID=
}

if [ $fail -ne 0 ]; then echo "local_control_test: FAILED"; exit 1; fi
echo "local_control_test: all passed"
