#!/usr/bin/env bash
# Run inside a fresh root file system by package_test.sh (as root, from a mmdebstrap hook):
#   installed_checks.sh runtime   after `lodestone` alone was installed with apt
#   installed_checks.sh sdk DIR   after lodestone-dev, a compiler and cmake: build the
#                                 out-of-tree plugin in DIR (tests/external_plugin) with
#                                 find_package(lodestone), install it, load it with /usr/bin/lode
# Prints one line per check; the first failure exits 1 (it fails the mmdebstrap run).
set -euo pipefail
fail() { echo "FAIL: $*" >&2; exit 1; }
ok() { echo "ok: $*"; }
# grep that reads all its input: with pipefail, `lode ... | grep -q` fails when grep exits
# first and lode dies of SIGPIPE.
has() { grep "$@" >/dev/null; }
WORK=$(mktemp -d /tmp/lode-check.XXXXXX)
chmod 755 "$WORK"
# A private runtime directory: the local command sockets of these runs meet nothing else.
export XDG_RUNTIME_DIR=$WORK/run
mkdir -m 700 "$XDG_RUNTIME_DIR"
unset LODE_PLUGIN_PATH

case "${1:-}" in
runtime)
  version=$(lode --version) || fail "lode --version"
  echo "$version" | sed 's/^/    /'
  echo "$version" | has "/usr/bin/../lib/lodestone/plugins" \
    || fail "lode --version does not search the installed plugin folder"
  lode plugins estimator.glsdc --json | has '"file": "/usr/bin/../lib/lodestone/plugins/' \
    || fail "lode does not load its plugins from /usr/lib/lodestone/plugins"
  ok "lode --version; the shipped plugins load from /usr/bin/../lib/lodestone/plugins"
  getent group realtime >/dev/null || fail "no group realtime"
  id -nG lode | tr ' ' '\n' | has -x realtime || fail "no user lode in group realtime"
  [ "$(getent passwd lode | cut -d: -f7)" = /usr/sbin/nologin ] || fail "user lode has a login shell"
  ok "group realtime and user lode (no login shell) exist"
  # Configured again (a reinstall or an upgrade), the scripts change nothing and do not fail.
  /var/lib/dpkg/info/lodestone.postinst configure 0.1.0-1 || fail "postinst configure, run a second time"
  [ "$(getent passwd | grep -c '^lode:')" = 1 ] && [ "$(getent group | grep -c '^realtime:')" = 1 ] \
    || fail "a second postinst run duplicated the user or the group"
  ok "postinst is idempotent"
  for f in /lib/systemd/system/lode@.service /lib/udev/rules.d/60-lodestone.rules \
           /etc/security/limits.d/lodestone.conf /usr/share/man/man1/lode-run.1.gz \
           /usr/share/bash-completion/completions/lode /usr/share/doc/lodestone/copyright; do
    [ -e "$f" ] || fail "$f is not installed"
  done
  [ -d /etc/lodestone ] || fail "/etc/lodestone is not installed"
  dpkg-query --control-show lodestone conffiles | has /etc/security/limits.d/lodestone.conf \
    || fail "the limits file is not a conffile"
  ok "unit, udev rule, limits (a conffile), /etc/lodestone, man page, completion, copyright"
  # A shipped pipeline from another folder, as the service user would run it: the example
  # files stand alone and the plugins are found relative to /usr/bin/lode.
  mkdir "$WORK/lode" && chown lode:realtime "$XDG_RUNTIME_DIR" "$WORK/lode"
  (cd / && setpriv --reuid=lode --regid=realtime --init-groups \
     lode run /usr/share/lodestone/config/kawato_planar.yaml --no-telemetry --quiet \
     --summary-json "$WORK/lode/summary.json" >"$WORK/run.log" 2>&1) \
    || { cat "$WORK/run.log"; fail "lode run kawato_planar.yaml (as user lode)"; }
  grep -q '"result": "completed"' "$WORK/lode/summary.json" || fail "lode run did not complete: $(cat "$WORK/run.log")"
  ok "lode run /usr/share/lodestone/config/kawato_planar.yaml as user lode, from /"
  for yaml in /usr/share/lodestone/config/*.yaml /usr/share/lodestone/config/replay/*.yaml; do
    (cd / && lode check "$yaml" >/dev/null) || fail "lode check $yaml"
  done
  ok "lode check: every installed example pipeline"
  ;;
sdk)
  SRC=$2
  cmake -S "$SRC" -B "$WORK/build" -DCMAKE_BUILD_TYPE=Release >"$WORK/cmake.log" 2>&1 \
    || { cat "$WORK/cmake.log"; fail "configure the plugin with find_package(lodestone)"; }
  cmake --build "$WORK/build" >"$WORK/build.log" 2>&1 || { cat "$WORK/build.log"; fail "build the plugin"; }
  ok "built tests/external_plugin against lodestone-dev"
  ctest --test-dir "$WORK/build" --output-on-failure >"$WORK/ctest.log" 2>&1 \
    || { cat "$WORK/ctest.log"; fail "the plugin's own test"; }
  ok "the plugin's own test passes"
  # Installed with the plugin project's default prefix: the SDK's, i.e. the package's folder.
  cmake --install "$WORK/build" >"$WORK/install.log" 2>&1 || { cat "$WORK/install.log"; fail "install the plugin"; }
  [ -f /usr/lib/lodestone/plugins/lode-filter.external_gain.so ] \
    || fail "the plugin was not installed into /usr/lib/lodestone/plugins: $(cat "$WORK/install.log")"
  lode plugins | has "filter.external_gain" || fail "lode plugins does not list filter.external_gain"
  lode plugins filter.external_gain --json \
    | has '"file": "/usr/bin/../lib/lodestone/plugins/lode-filter.external_gain.so"' \
    || fail "lode loads filter.external_gain from elsewhere: $(lode plugins filter.external_gain --json | grep '"file"')"
  ok "lode plugins lists filter.external_gain from /usr/lib/lodestone/plugins"
  # LODE_PLUGIN_PATH comes first: the build folder's copy wins over the installed one.
  LODE_PLUGIN_PATH=$WORK/build lode plugins filter.external_gain --json \
    | has "\"file\": \"$WORK/build/lode-filter.external_gain.so\"" \
    || fail "LODE_PLUGIN_PATH does not override the installed plugin"
  ok "LODE_PLUGIN_PATH overrides the installed plugin"
  (cd / && lode run "$SRC/pipeline.yaml" --duration 0.05 --no-telemetry --quiet \
     --summary-json "$WORK/summary.json" >"$WORK/run.log" 2>&1) \
    || { cat "$WORK/run.log"; fail "lode run with the external plugin"; }
  grep -q '"result": "completed"' "$WORK/summary.json" || fail "lode run did not complete: $(cat "$WORK/run.log")"
  ok "a pipeline using filter.external_gain runs"
  ;;
*) echo "usage: $0 runtime | sdk PLUGIN_SOURCE_DIR" >&2; exit 2 ;;
esac
rm -rf "$WORK"
