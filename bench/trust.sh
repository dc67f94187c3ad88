#!/usr/bin/env bash
# trust.sh - what encrypted links and audited tiles cost (issue 17), printed
# not asserted: the local farm on one scene, five configurations run
# interleaved round by round (the machine is shared and noisy: compare the
# medians of one run only). Wall time, and CPU time (user + system of the
# coordinator and its local workers, /usr/bin/time), which the load of other
# processes disturbs far less:
#   plain     --workers N --audit 0, no token (frames in clear on loopback)
#   sealed    --workers N --audit 0 --token-file T (every frame sealed, conn_seal)
#   audit-X   --workers N --audit X (X of the tiles rendered twice; 0.02 is the default)
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
  [plain]="--audit 0"
  [sealed]="--audit 0 --token-file $out/token"
  [audit-0.02]="--audit 0.02"
  [audit-0.1]="--audit 0.1"
  [audit-1.0]="--audit 1.0"
)
read -r -a order <<< "${TRUST_CONFIGS:-plain sealed audit-0.02 audit-0.1 audit-1.0}"
median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
echo "== $scene, $spp spp, tiles $tile, $workers local workers, $rounds rounds interleaved; $(uptime)"
for r in $(seq "$rounds"); do
  for k in "${order[@]}"; do
    # shellcheck disable=SC2086
    /usr/bin/time -f "%e %U %S" -o "$out/time" "$bin/tessera" render "$scene" --workers "$workers" --spp "$spp" \
      --tile-size "$tile" ${runs[$k]} --no-progress -o "$out/$k.pfm" > "$out/$k.$r.out" 2>&1
    read -r wall user sys < "$out/time"
    cpu=$(echo "$user + $sys" | bc)
    echo "$k $wall $cpu" >> "$out/times"
    echo "  round $r $k: wall $wall s, cpu $cpu s"
  done
  for k in "${order[@]}"; do
    cmp -s "$out/${order[0]}.pfm" "$out/$k.pfm" || echo "  round $r: $k's image differs from ${order[0]}'s"
  done
done
base=$(awk -v k="${order[0]}" '$1 == k {print $2}' "$out/times" | median)
cbase=$(awk -v k="${order[0]}" '$1 == k {print $3}' "$out/times" | median)
for k in "${order[@]}"; do
  m=$(awk -v k="$k" '$1 == k {print $2}' "$out/times" | median)
  c=$(awk -v k="$k" '$1 == k {print $3}' "$out/times" | median)
  printf "%-11s median wall %6.2f s (%+6.1f%%)  cpu %7.2f s (%+6.1f%%)  against the first\n" "$k" "$m" \
    "$(echo "($m / $base - 1) * 100" | bc -l)" "$c" "$(echo "($c / $cbase - 1) * 100" | bc -l)"
done
echo "== done; $(uptime)"
