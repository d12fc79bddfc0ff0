#!/usr/bin/env bash
# `lode scope` with more than it serves, over plain HTTP (no browser, no pipeline needed):
#   1. as many pages' streams as it serves (32) are open: the next stream is refused with 503
#      at once, and the page, its assets and the API still answer beside them (before, the
#      ninth page took the last thread of a pool of 8 and every later request hung);
#   2. a page closed frees its place: a new stream is served again;
#   3. a command body of 2 MiB is refused with 413 before it is held (before, 300 MB were read
#      into memory).
# usage: scope_limits_test.sh LODE SRC
set -u
LODE=$1 SRC=$2
source "$SRC/tests/integration/test_lib.sh"  # TMP, XDG_RUNTIME_DIR, PIDS killed at exit, ok/bad
take_private_domain

"$LODE" scope --domain "$DOMAIN" --listen 127.0.0.1:0 --duration 120 >"$TMP/scope.out" 2>"$TMP/scope.err" &
PIDS+=($!)
URL=
for _ in $(seq 1 100); do
  URL=$(grep -o 'http://[^ ]*' "$TMP/scope.out" 2>/dev/null) && [ -n "$URL" ] && break
  sleep 0.1
done
[ -n "$URL" ] || { bad "lode scope printed no address"; cat "$TMP/scope.err"; exit 1; }

"$PY" - "$URL" <<'PY'
import http.client, socket, sys, time, urllib.parse
url = urllib.parse.urlparse(sys.argv[1])
HOST, PORT = url.hostname, url.port
PAGES = 32  # Server::kMaxPages
failed = False

def check(label, condition, detail=""):
    global failed
    print(("ok: " if condition else "FAIL: ") + label + ("" if condition else f" ({detail})"), flush=True)
    failed |= not condition

def open_stream():
    """A page's stream: the connection and the status line of its answer."""
    s = socket.create_connection((HOST, PORT), timeout=10)
    s.sendall(f"GET /api/stream HTTP/1.1\r\nHost: 127.0.0.1:{PORT}\r\n\r\n".encode())
    head = b""
    while b"\r\n\r\n" not in head:
        chunk = s.recv(4096)
        if not chunk:
            break
        head += chunk
    return s, head.split(b"\r\n", 1)[0].decode(errors="replace"), head

def request(method, path, body=None, headers=None):
    c = http.client.HTTPConnection(HOST, PORT, timeout=10)
    c.request(method, path, body=body, headers=headers or {})
    r = c.getresponse()
    data = r.read()
    c.close()
    return r.status, data

streams = []
for i in range(PAGES):
    try:
        s, status, _ = open_stream()
    except OSError as e:  # a pool too small for the pages: the stream waits for a thread
        s, status = None, repr(e)
    if s is not None:
        streams.append(s)
    if " 200 " not in status + " ":
        check(f"stream {i + 1} of {PAGES} served", False, status)
        break
else:
    check(f"{PAGES} streams served", True)

try:
    extra, status, head = open_stream()
    check("the next stream refused with 503", status.startswith("HTTP/1.1 503"), status)
    check("the refusal says why", b"pages are open already" in head + extra.recv(4096), head[:200])
    extra.close()
except OSError as e:
    check("the next stream refused with 503", False, repr(e))

for path in ["/", "/scope.js", "/api/signals", "/api/counters"]:
    try:
        status, data = request("GET", path)
        check(f"GET {path} answered beside {PAGES} open pages", status == 200, status)
    except OSError as e:
        check(f"GET {path} answered beside {PAGES} open pages", False, repr(e))

# 2. One page closed: its place is free once the scope has noticed (its next write fails).
streams.pop().close()
served = False
deadline = time.time() + 30
while time.time() < deadline and not served:
    s, status, _ = open_stream()
    if status.startswith("HTTP/1.1 200"):
        served = True
        streams.append(s)
    else:
        s.close()
        time.sleep(0.5)
check("a closed page's place is served again", served)

# 3. A command larger than a command can be.
try:
    status, _ = request("POST", "/api/command", body=b"{" + b" " * (2 << 20) + b"}",
                        headers={"Content-Type": "application/json"})
    check("a 2 MiB command refused with 413", status == 413, status)
except OSError as e:
    check("a 2 MiB command refused with 413", False, repr(e))

for s in streams:
    s.close()
sys.exit(1 if failed else 0)
PY
[ $? -eq 0 ] || fail=1
kill -0 "${PIDS[0]}" 2>/dev/null && ok "lode scope still running" || bad "lode scope died: $(tail -5 "$TMP/scope.err")"
exit $fail
