#!/usr/bin/env bash
# audit_soak.sh - an honest farm is never flagged by the audit (issue 17),
# over more jobs than make test runs: JOBS renders of a small scene on 3
# local workers with --audit 1.0 (every tile rendered by two workers and
# compared), tile sizes cycling through 4 to 32 px. Fails on any mismatch,
# quarantine, or an image that differs from the single-process render.
# usage: bench/audit_soak.sh BIN_DIR [JOBS] [SCENE]
set -euo pipefail
bin=$1
jobs=${2:-100}
scene=${3:-tests/scenes/cornell-small.json}
out=$(mktemp -d /tmp/tessera-audit-soak.XXXXXX)
trap 'rm -rf "$out"' EXIT
"$bin/tessera" render "$scene" --spp 16 --workers 0 --no-progress -o "$out/ref.pfm" > /dev/null
tiles=(4 5 7 8 9 13 16 32)
checked=0
unchecked=0
echo "== $jobs jobs of $scene, 16 spp, 3 workers, --audit 1.0; $(uptime)"
for i in $(seq "$jobs"); do
  t=${tiles[$((i % ${#tiles[@]}))]}
  "$bin/tessera" render "$scene" --spp 16 --workers 3 --tile-size "$t" --audit 1.0 -v --no-progress \
    -o "$out/img.pfm" > "$out/log" 2>&1 || { echo "job $i (tile $t) failed:"; cat "$out/log"; exit 1; }
  if grep -q -e disagree -e "quarantined for" -e QUARANTINED "$out/log" || ! grep -q " 0 mismatches, 0 workers quarantined" "$out/log"; then
    echo "job $i (tile $t): an honest farm was flagged:"; cat "$out/log"; exit 1
  fi
  cmp -s "$out/img.pfm" "$out/ref.pfm" || { echo "job $i (tile $t): image differs from the single-process one"; exit 1; }
  n=$(sed -n 's/.*: \([0-9]*\) tiles checked by two workers.*/\1/p' "$out/log")
  u=$(sed -n 's/.* \([0-9]*\) accepted unchecked.*/\1/p' "$out/log")
  checked=$((checked + n))
  unchecked=$((unchecked + u))
done
echo "$jobs jobs, $checked tiles checked by two workers ($unchecked accepted unchecked while a worker was alone):" \
  "no mismatch, no quarantine, every image identical; $(uptime)"
