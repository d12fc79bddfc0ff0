#!/usr/bin/env bash
# A clean Debian root file system from the archive this machine's apt uses, with a package
# cache kept outside it so that the next one downloads nothing it already has.
#
#   make_rootfs.sh OUTDIR CACHE_DIR [--include PKG,PKG] [--deb FILE.deb]... [--variant V]
#                  [-- MMDEBSTRAP_OPTION...]
#
#   OUTDIR      the root file system (a directory; must not exist yet, or be empty). The caller
#               removes it.
#   CACHE_DIR   the .deb files apt downloaded (CACHE_DIR/archives) and its package lists
#               (CACHE_DIR/lists), created if missing, copied in before and out after the run.
#   --include   Debian packages to install besides the variant's (repeatable), e.g.
#               --include systemd-sysv,udev for a guest that boots.
#   --deb       a local package file, installed with apt so its dependencies come from the
#               archive (repeatable).
#   --variant   mmdebstrap's variant (default apt: Essential packages plus apt).
#   -- ...      passed on to mmdebstrap before the cache is copied out, e.g.
#               --customize-hook='chroot "$1" lode --version': a hook that fails fails the run.
#
# The suite is the host's (VERSION_CODENAME of /etc/os-release); the sources are the host's
# Debian entries for that suite (/etc/apt/sources.list and sources.list.d/*.list|*.sources),
# and its apt proxy and Check-Valid-Until settings carry over. Needs root (mmdebstrap's root
# mode) and mmdebstrap. Exit 77 when mmdebstrap is missing, 1 on failure.
set -euo pipefail

usage() { sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//' >&2; exit 2; }
[ $# -ge 2 ] || usage
OUT=$1 CACHE=$2
shift 2
includes=() debs=() extra=() variant=apt
while [ $# -gt 0 ]; do
  case "$1" in
    --include) includes+=("$2"); shift 2 ;;
    --deb) debs+=("$(realpath "$2")"); shift 2 ;;
    --variant) variant=$2; shift 2 ;;
    --) shift; extra=("$@"); break ;;
    *) usage ;;
  esac
done
command -v mmdebstrap >/dev/null || { echo "make_rootfs: mmdebstrap is missing (apt-get install mmdebstrap)" >&2; exit 77; }
[ "$(id -u)" -eq 0 ] || { echo "make_rootfs: needs root (mmdebstrap --mode=root)" >&2; exit 1; }
for d in "${debs[@]}"; do [ -f "$d" ] || { echo "make_rootfs: no such package file: $d" >&2; exit 1; }; done

# shellcheck disable=SC1091
suite=$(. /etc/os-release && echo "${VERSION_CODENAME:-}")
[ -n "$suite" ] || { echo "make_rootfs: /etc/os-release names no VERSION_CODENAME" >&2; exit 1; }

# The host's entries for this suite and its -updates/-security companions, as one-line
# sources (the keyring is the host's Debian archive keyring, which mmdebstrap uses anyway).
host_sources() {
  local f
  for f in /etc/apt/sources.list /etc/apt/sources.list.d/*.list; do
    [ -f "$f" ] || continue
    awk -v s="$suite" '$1 == "deb" {
        i = 2; if ($2 ~ /^\[/) { while ($i !~ /\]$/) i++; i++ }
        if ($(i + 1) == s || index($(i + 1), s "-") == 1) { line = "deb " $i; for (j = i + 1; j <= NF; j++) line = line " " $j; print line }
      }' "$f"
  done
  for f in /etc/apt/sources.list.d/*.sources; do
    [ -f "$f" ] || continue
    awk -v s="$suite" -v RS= -F '\n' '{
        types = ""; uris = ""; suites = ""; comps = ""; enabled = "yes"
        for (k = 1; k <= NF; k++) {
          if ($k ~ /^#/) continue
          split($k, kv, ":"); key = tolower(kv[1]); val = substr($k, length(kv[1]) + 2); gsub(/^[ \t]+|[ \t]+$/, "", val)
          if (key == "types") types = val; else if (key == "uris") uris = val
          else if (key == "suites") suites = val; else if (key == "components") comps = val
          else if (key == "enabled") enabled = tolower(val)
        }
        if (enabled == "no" || (" " types " ") !~ / deb /) next
        nu = split(uris, u, " "); ns = split(suites, st, " ")
        for (a = 1; a <= nu; a++) for (b = 1; b <= ns; b++)
          if (st[b] == s || index(st[b], s "-") == 1) print "deb " u[a] " " st[b] " " comps
      }' "$f"
  done
}
mapfile -t mirrors < <(host_sources | awk '!seen[$0]++')
[ ${#mirrors[@]} -gt 0 ] || { echo "make_rootfs: the host's apt has no source for $suite" >&2; exit 1; }

aptopts=()
eval "$(apt-config shell http_proxy Acquire::http::Proxy https_proxy Acquire::https::Proxy \
                         valid_until Acquire::Check-Valid-Until)"
[ -n "${http_proxy:-}" ] && aptopts+=(--aptopt="Acquire::http::Proxy \"$http_proxy\"")
[ -n "${https_proxy:-}" ] && aptopts+=(--aptopt="Acquire::https::Proxy \"$https_proxy\"")
[ -n "${valid_until:-}" ] && aptopts+=(--aptopt="Acquire::Check-Valid-Until \"$valid_until\"")

mkdir -p "$CACHE/archives/partial" "$CACHE/lists/partial"
CACHE=$(realpath "$CACHE")
include_args=()
[ ${#includes[@]} -gt 0 ] && include_args+=(--include="$(IFS=,; echo "${includes[*]}")")
# The local packages are installed by apt inside the finished chroot rather than by
# --include: mmdebstrap's outer apt hands dpkg (inside) paths it cannot see.
deb_hooks=()
if [ ${#debs[@]} -gt 0 ]; then
  deb_hooks+=(--customize-hook='mkdir -p "$1/tmp/make_rootfs-debs"')
  deb_hooks+=(--customize-hook="copy-in ${debs[*]} /tmp/make_rootfs-debs")
  deb_hooks+=(--customize-hook='chroot "$1" sh -c "DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends /tmp/make_rootfs-debs/*.deb"')
  deb_hooks+=(--customize-hook='rm -rf "$1/tmp/make_rootfs-debs"')
fi

# --skip=essential/unlink keeps the Essential packages' files in the archive cache, which is
# copied out before the caller's hooks (kept if one fails) and again after them;
# the lists are kept too, so a second run's apt update fetches only what changed.
mmdebstrap --mode=root --variant="$variant" --skip=essential/unlink \
  "${aptopts[@]}" "${include_args[@]}" \
  --setup-hook='mkdir -p "$1"/var/cache/apt/archives "$1"/var/lib/apt/lists' \
  --setup-hook="sync-in $CACHE/archives /var/cache/apt/archives/" \
  --setup-hook="sync-in $CACHE/lists /var/lib/apt/lists/" \
  "${deb_hooks[@]}" \
  --customize-hook="sync-out /var/cache/apt/archives $CACHE/archives" \
  "${extra[@]}" \
  --customize-hook="sync-out /var/cache/apt/archives $CACHE/archives" \
  --customize-hook="sync-out /var/lib/apt/lists $CACHE/lists" \
  "$suite" "$OUT" "${mirrors[@]}"
