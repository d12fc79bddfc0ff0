#!/usr/bin/env bash
# The bash completion (`lode --bash-completion`) and, when help2man is there, the man pages
# of `lode`, all from its own option declarations: lode.1 for the overview and lode-CMD.1 for
# every command `lode --help` lists, so a new command gets its page. The pages are compressed
# (gzip -9n, no timestamp), as Debian installs man pages.
# usage: lode_docs.sh LODE OUTDIR
set -eu
LODE=$1
OUT=$2
mkdir -p "$OUT/man1"
"$LODE" --bash-completion > "$OUT/lode.bash"
command -v help2man >/dev/null || exit 0
rm -f "$OUT"/man1/*.1 "$OUT"/man1/*.1.gz
# Only the first line of `lode --version`: the rest is the plugin search path of this very
# binary, folders of the build tree that mean nothing on an installed system.
version=$("$LODE" --version | head -1)
help2man --no-info --version-string="$version" \
  --name="run, check and inspect lodestone pipelines" --output="$OUT/man1/lode.1" "$LODE"
"$LODE" --help | sed -n '/^Subcommands:/,/^$/p' | awk 'NR > 1 && NF' | while read -r cmd description; do
  help2man --no-info --version-string="$version" --help-option="$cmd --help" \
    --name="$description" --output="$OUT/man1/lode-$cmd.1" "$LODE"
done
gzip -9n "$OUT"/man1/*.1
