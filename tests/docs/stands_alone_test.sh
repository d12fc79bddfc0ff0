#!/usr/bin/env bash
# The repository stands on its own: no file refers to a ticket number or to design notes that
# live outside it. (The pattern is assembled so that this file does not match itself.)
set -u
SRC=$1
notes='DESIGN|STYLE|PLATFORM'
pattern="issue ?#?[0-9]+|(${notes})\.md|\.\./shar""ed"
hits=$(cd "$SRC" && grep -rnE "$pattern" --exclude-dir=.git --exclude-dir=build --exclude-dir='build-*' \
         --exclude-dir=node_modules README.md setup.sh .ci core hal plugins apps config tests cmake docs tools 2>/dev/null)
if [ -n "$hits" ]; then
  echo "FAIL: references to things outside the repository:"
  echo "$hits"
  exit 1
fi
echo "no file refers to ticket numbers or to notes outside the repository"
