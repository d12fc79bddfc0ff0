# Shared by the end-to-end test scripts (source it): a private temporary folder, processes
# to stop at exit, and ok/bad/check_rc/contains that print one line per check and set $fail.
PY=python3; [ -x /usr/bin/python3 ] && PY=/usr/bin/python3  # the Debian interpreter has h5py
TMP=$(mktemp -d)
# A runtime directory of our own: the local command sockets of the runs this test starts
# cannot meet those of any other `lode run` on the host.
export XDG_RUNTIME_DIR=$TMP/run
mkdir -m 700 "$XDG_RUNTIME_DIR"
PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill -CONT "$p" 2>/dev/null; kill "$p" 2>/dev/null; done
  wait 2>/dev/null
  rm -rf "$TMP"
}
trap cleanup EXIT
fail=0
ok() { echo "ok: $1"; }
bad() { echo "FAIL: $1"; fail=1; }
# check_rc LABEL EXPECTED ACTUAL [LOG]: the exit code, with the log's tail when it differs.
check_rc() {
  if [ "$2" = "$3" ]; then ok "$1"; else bad "$1: exit code $3, expected $2"; [ -n "${4:-}" ] && sed 's/^/    /' "$4" | tail -20; fi
}
# contains LABEL FILE REGEX
contains() { if grep -qE -e "$3" "$2"; then ok "$1"; else bad "$1: no /$3/ in $2:"; sed 's/^/    /' "$2" | tail -20; fi; }
source "$(dirname "${BASH_SOURCE[0]}")/private_domain.sh"  # take_private_domain
