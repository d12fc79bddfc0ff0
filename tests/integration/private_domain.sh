# Sourced by the end-to-end test scripts (needs $PY, a python3 interpreter).
# take_private_domain: sets DOMAIN to a DDS domain id no other process on this host uses, and
# holds it for this script's life. The same lock files as lode::testing::private_dds_domain()
# (/tmp/lode-test-domains/<id>, flock), started at an offset from our pid; a domain whose
# Fast DDS discovery ports are bound, or whose shared-memory port files exist, belongs to
# somebody else (another user's `lode run`) and is passed over.
take_private_domain() {
  local dir=/tmp/lode-test-domains i d fd
  mkdir -p "$dir" 2>/dev/null; chmod 1777 "$dir" 2>/dev/null
  for ((i = 0; i < 130; i++)); do
    d=$((100 + ($$ + i) % 130))
    exec {fd}>>"$dir/$d" || continue
    if flock -n "$fd"; then
      if $PY - "$d" <<'PYEOF'
import errno, os, socket, sys
d = int(sys.argv[1])
for p in range(8):
    port = 7400 + 250 * d + 10 + 2 * p
    if os.path.exists(f"/dev/shm/fastrtps_port{port}"):
        sys.exit(1)
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        s.bind(("0.0.0.0", port))
    except OSError as e:
        if e.errno == errno.EADDRINUSE:
            sys.exit(1)
    finally:
        s.close()
PYEOF
      then
        DOMAIN=$d
        echo "[test] private DDS domain $DOMAIN"
        return 0
      fi
    fi
    exec {fd}>&-
  done
  echo "FAIL: no free DDS test domain in 100-229"; exit 1
}
