#!/usr/bin/env bash
# `lode scope` end to end: `lode run` of the hot-swap demo on the real clock, publishing
# telemetry and taking commands on a private DDS domain; `lode scope` on a free loopback port;
# the page opened in headless Chromium (chromium_page.mjs) and driven as a person would
# (scope_page_checks.js): ten signals ticked, samples counted against the topics' rate, a
# parameter typed and set, an estimator swapped, a level trigger fired, no console error.
# Then the access rules over plain HTTP: a scope started with --require-token refuses every
# request (page, stream, command) without its token, and a tokenless loopback scope refuses
# a foreign Host header and a command that is not JSON.
# usage: scope_test.sh LODE SRC
set -u
LODE=$1 SRC=$2
source "$SRC/tests/integration/test_lib.sh"  # TMP, XDG_RUNTIME_DIR, PIDS killed at exit, ok/bad/check_rc/contains
PAGE="$SRC/tests/plot/chromium_page.mjs"
export LODE_CHROMIUM=${LODE_CHROMIUM:-/usr/bin/chromium}
for tool in node "$LODE_CHROMIUM"; do
  command -v "$tool" >/dev/null || { echo "SKIP: $tool not installed"; exit 77; }
done
take_private_domain

# Own domain; no SCHED_FIFO (CI shares two cores); long enough for every check below.
sed -e "s/^  domain: 0/  domain: $DOMAIN/" -e "s/^realtime: .*/realtime: { overrun_policy: skip }/" \
  "$SRC/config/kawato_planar_swap.yaml" >"$TMP/swap.yaml"
HYBRID='{q: [1.0e2, 1.0e2, 1.0e5], r: [2.2e-10, 2.2e-10, 9.6e-9], hinf_theta: 1.0e8, d: 0.5, output: predicted}'
"$LODE" run "$TMP/swap.yaml" --clock real --duration 150 >"$TMP/run.out" 2>&1 &
PIDS+=($!)

# start_scope NAME ARGS...: starts `lode scope` on a free loopback port; sets URL to what it printed.
start_scope() {
  local name=$1; shift
  "$LODE" scope --domain "$DOMAIN" --listen 127.0.0.1:0 "$@" >"$TMP/$name.out" 2>"$TMP/$name.err" &
  PIDS+=($!)
  URL=
  for _ in $(seq 1 100); do
    URL=$(grep -o 'http://[^ ]*' "$TMP/$name.out" 2>/dev/null) && [ -n "$URL" ] && return 0
    sleep 0.1
  done
  bad "lode scope $* printed no address"; cat "$TMP/$name.err"; exit 1
}

start_scope scope
ok "lode scope serves $URL"

# Another client of one of the topics the page ticks, beside it: what the scope shows of a run
# of cycles is compared with what this got of the same cycles (the pipeline skips periods
# when it overruns, so the cycles alone do not say how many samples there were).
"$LODE" echo kf.pose --domain "$DOMAIN" --wait 60 --duration 120 >"$TMP/echo_pose.out" 2>"$TMP/echo_pose.err" &
ECHO_POSE=$!
PIDS+=($ECHO_POSE)

# The page, driven in Chromium. The checks wait for the signals (DDS discovery) themselves.
node "$PAGE" --url "$URL" --ready 'window.lodeScope !== undefined' --script "$SRC/tests/scope/scope_page_checks.js" \
  --eval "scopeChecks({signals: 10, seconds: 4, parameter: 'kf_hybrid.d', value: '0.4',
          swap: {block: 'kf', plugin: 'estimator.hybrid_h2hinf', params: '$HYBRID'}, promote: 'kf_coast',
          trigger: true})" \
  --timeout 150 --screenshot "$TMP/scope.png" >"$TMP/page.json" 2>"$TMP/page.err"
check_rc "the page runs in headless Chromium without a console error" 0 $? "$TMP/page.json"
kill -TERM $ECHO_POSE 2>/dev/null; wait $ECHO_POSE 2>/dev/null
"$PY" - "$TMP/page.json" "$TMP/echo_pose.out" <<'EOF' || bad "the scope showed fewer kf.pose samples than lode echo got of the same cycles"
import json, sys
v = json.loads(json.load(open(sys.argv[1]))["value"])
topic = next(t for t in v["rates"] if t.endswith("kf/pose"))
r = v["rates"][topic]
first, last = r["cycles"]
echoed = sum(1 for line in open(sys.argv[2]) if line.strip() and not line.startswith("#")
             and first < float(line.split()[0]) <= last)
print(f"  {topic}: cycles ({first:.0f}, {last:.0f}]: the scope {r['samples']} samples, lode echo {echoed}")
# Both read the same writer on this host; a sample either one lost is all that may differ.
assert echoed > 100 and r["samples"] >= 0.97 * echoed, (r["samples"], echoed)
print("ok: the scope showed every sample lode echo got of those cycles")
EOF
"$PY" - "$TMP/page.json" <<'EOF' || bad "what the page showed (above)"
import json, sys
page = json.load(open(sys.argv[1]))
assert not page["errors"], page["errors"]
v = json.loads(page["value"])
print(json.dumps({k: v[k] for k in ("fps", "rates", "late", "status", "set_reply", "trigger_state")}, indent=1))
problems = []
def check(what, condition):
    print(("ok: " if condition else "FAIL: ") + what)
    if not condition: problems.append(what)
check("ten signals ticked", len(v["selected"]) == 10)
for topic, r in v["rates"].items():
    # Live at the topic's rate, not a trickle. The pipeline publishes less when it misses
    # periods (overrun_policy skip), which a CI machine running other tests beside this one
    # makes it do (seen: 0.39 of the rate while a build ran): what the scope got of what was
    # published is checked below (same count on every topic, no drop). The figures on a
    # quiet machine come from tests/scope/scope_measure.sh, not from this test.
    check(f"{topic}: {r['received_hz']:.0f} samples/s received for {r['topic_hz']} Hz",
          0.25 * r["topic_hz"] <= r["received_hz"] <= 1.05 * r["topic_hz"])
rates = [r["received_hz"] for r in v["rates"].values()]
check("every topic at the same rate (none lost in the scope)", max(rates) - min(rates) <= 0.03 * max(rates))
check("the plot is redrawn while samples arrive (%.0f frames/s; scope_measure.sh measures the rate)" % v["fps"], v["fps"] >= 1)
check("the plot shows the window's samples", v["plotted_points"] > 1000)
check("the status strip shows the pipeline's timing", v["status"]["rate"] == "5000 Hz" and v["status"]["connection"] == "live")
check("no sample lost by the scope", v["status"]["scope_dropped"] == "0")
check("the shadows' NIS and disagreement shown", any("kf_hybrid" in s and "nis" in s and "disagreement" in s for s in v["shadows"]))
check("set: the reply shown in the page", v["set_ok"] and v["set_reply"].startswith("kf_hybrid.d: 0.5 -> 0.4 at cycle"))
check("set: the parameter event arrived and is listed", "kf_hybrid.d: 0.5 -> 0.4" in v["parameter_event"]
      and "lode-scope-" in v["parameter_event"] and v["event_list_shows_it"])
check("swap: ok", v["swap_reply"]["ok"] and v["swap_reply"]["message"].startswith("swapped kf: estimator.kalman -> estimator.hybrid_h2hinf"))
check("swap: the reply listed", "→ ok: swapped kf" in v["reply_list_shows_it"])
check("swap: the event arrived", v["swap_event"].startswith("swapped kf: estimator.kalman -> estimator.hybrid_h2hinf"))
check("promote: ok", v["promote_reply"]["ok"] and v["promote_reply"]["message"].startswith("promoted kf_coast at cycle"))
check("promote: the event arrived", v["promote_event"].startswith("promoted kf_coast at cycle"))
check("the level trigger fired", v["trigger_state"].startswith("triggered at"))
sys.exit(1 if problems else 0)
EOF

# http_status METHOD URL [HEADER=VALUE...] [--body TEXT]: the HTTP status code of one request.
http_status() {
  "$PY" - "$@" <<'EOF'
import http.client, sys, urllib.parse
method, url, *rest = sys.argv[1:]
body = None
headers = {}
while rest:
    item = rest.pop(0)
    if item == "--body": body = rest.pop(0)
    else: k, _, val = item.partition("="); headers[k] = val
u = urllib.parse.urlsplit(url)
c = http.client.HTTPConnection(u.hostname, u.port, timeout=10)
c.request(method, u.path + ("?" + u.query if u.query else ""), body=body, headers=headers)
r = c.getresponse()
# The stream never ends: the status line is enough.
print(r.status)
EOF
}
expect_status() {  # LABEL EXPECTED METHOD URL ...
  local label=$1 expected=$2; shift 2
  local got; got=$(http_status "$@")
  [ "$got" = "$expected" ] && ok "$label ($got)" || bad "$label: HTTP $got, expected $expected"
}

start_scope token --require-token
TOKEN=${URL##*token=}
BASE=${URL%%\?*}
[ ${#TOKEN} -eq 32 ] && ok "a 128-bit token printed" || bad "token: '$TOKEN'"
JSON=Content-Type=application/json
SET='{"kind": "set", "target": "kf_hybrid.d", "value": "0.3"}'
expect_status "with the token: the page" 200 GET "${BASE}?token=$TOKEN"
expect_status "with the token in a header: the signals" 200 GET "${BASE}api/signals" "X-Lode-Token=$TOKEN"
expect_status "with the token: the stream" 200 GET "${BASE}api/stream?token=$TOKEN"
expect_status "without the token: the page refused" 403 GET "$BASE"
expect_status "without the token: uPlot refused" 403 GET "${BASE}uplot.js"
expect_status "without the token: the stream refused" 403 GET "${BASE}api/stream"
expect_status "without the token: the parameters refused" 403 GET "${BASE}api/parameters"
expect_status "without the token: a command refused" 403 POST "${BASE}api/command" "$JSON" --body "$SET"
# The token with its last digit changed: one in sixteen tokens already ends in 0.
LAST=${TOKEN: -1}; [ "$LAST" = 0 ] && OTHER=1 || OTHER=0
expect_status "a wrong token refused" 403 GET "${BASE}api/signals?token=${TOKEN%?}$OTHER"
PORT=${BASE##*:}; PORT=${PORT%/}
expect_status "a cookie with the wrong token refused" 403 GET "${BASE}api/signals" "Cookie=lode_scope_token_$PORT=x"
expect_status "the cookie the page set is enough" 200 GET "${BASE}api/signals" "Cookie=lode_scope_token_$PORT=$TOKEN"
# Tokenless loopback: still no cross-site form post, no rebound name.
expect_status "loopback without token: a foreign Host refused" 403 GET "$(grep -o 'http://[^ ]*' "$TMP/scope.out")api/signals" Host=evil.example:80
expect_status "loopback without token: a command that is not JSON refused" 415 POST \
  "$(grep -o 'http://[^ ]*' "$TMP/scope.out")api/command" Content-Type=text/plain --body "$SET"
"$LODE" scope --listen 127.0.0.1:99999 >"$TMP/badlisten.out" 2>&1
check_rc "a malformed --listen is a usage error" 2 $? "$TMP/badlisten.out"

[ -n "${LODE_SCOPE_SCREENSHOT:-}" ] && cp "$TMP/scope.png" "$LODE_SCOPE_SCREENSHOT"
[ $fail -eq 0 ] && echo PASS
exit $fail
