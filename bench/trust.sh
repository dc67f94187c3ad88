#!/usr/bin/env bash
# trust.sh - what encrypted links and audited tiles cost (issue 17), printed
# not asserted: the local farm on one scene, five configurations run
# interleaved round by round (the machine is shared and noisy: compare the
# medians of one run only):
#   plain     --workers N, no token (frames in clear on loopback)
#   sealed    --workers N --token-file T (every frame sealed, conn_seal)
#   audit-X   --workers N --audit X (X of the tiles rendered twice)
# usage: [TRUST_CONFIGS="plain sealed"] bench/trust.sh BIN_DIR [SCENE] [SPP] [ROUNDS] [TILE]
set -euo pipefail
bin=$1
scene=${2:-scenes/cornell-box.json}
spp=${3:-16}
rounds=${4:-5}
tile=${5:-32}
workers=$(nproc)
[ "$workers" -lt 3 ] && workers=3 # an audit mismatch needs a third worker
out=$(mktemp -d /tmp/tessera-trust-bench.XXXXXX)
trap 'rm -rf "$out"' EXIT
echo "bench token $$" > "$out/token"
declare -A runs=(
  [plain]=""
  [sealed]="--token-file $out/token"
  [audit-0.02]="--audit 0.02"
  [audit-0.1]="--audit 0.1"
  [audit-1.0]="--audit 1.0"
)
read -r -a order <<< "${TRUST_CONFIGS:-plain sealed audit-0.02 audit-0.1 audit-1.0}"
median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
echo "== $scene, $spp spp, tiles $tile, $workers local workers, $rounds rounds interleaved"
for r in $(seq "$rounds"); do
  for k in "${order[@]}"; do
    s=$(date +%s.%N)
    # shellcheck disable=SC2086
    "$bin/tessera" render "$scene" --workers "$workers" --spp "$spp" --tile-size "$tile" ${runs[$k]} --no-progress \
      -o "$out/$k.pfm" > "$out/$k.$r.out" 2>&1
    e=$(date +%s.%N)
    echo "$k $(echo "$e - $s" | bc)" >> "$out/times"
    echo "  round $r $k: $(echo "$e - $s" | bc) s"
  done
  for k in "${order[@]}"; do
    cmp -s "$out/${order[0]}.pfm" "$out/$k.pfm" || echo "  round $r: $k's image differs from ${order[0]}'s"
  done
done
base=$(awk -v k="${order[0]}" '$1 == k {print $2}' "$out/times" | median)
for k in "${order[@]}"; do
  m=$(awk -v k="$k" '$1 == k {print $2}' "$out/times" | median)
  printf "%-11s median %6.2f s  (%+.1f%% against the first)\n" "$k" "$m" "$(echo "($m / $base - 1) * 100" | bc -l)"
done
