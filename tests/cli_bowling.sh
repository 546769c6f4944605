#!/usr/bin/env bash
# Both bowling scenes hold their expect: blocks at a reduced resolution (spacing 2.5 cm,
# about 4.7K particles, the first 1.5 s: impact, bounce and roll, or plunge and sink).
# Args: STF_BINARY PROJECT_DIR
set -u
stf=$1; src=$2
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT; cd "$tmp"
rc=0
for s in bowling_ball bowling_ball_no_history; do
  "$stf" check "$src/scenes/$s.yaml" -o "$s.h5" --set fluid.spacing=0.025 --duration 1.5 --quiet \
    || { echo "cli_bowling: $s failed its expectations" >&2; rc=1; }
done
exit $rc
