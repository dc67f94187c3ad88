#!/usr/bin/env bash
# cycles-seeds.sh - the same-run comparison of bench/cycles.sh without a
# converged reference: each renderer renders each cell twice (seeds 1 and 2),
# and its error is the relative variance of one image,
#   var = mean((x1 - x2)^2 / (ref^2 + 0.01)) / 2,
# which is what relMSE against a perfect reference tends to for an unbiased
# renderer (both are: their means agree, docs/performance.md). REF (any
# well-converged Cycles image of the scene, default 256 spp,
# bench/cycles/reference.sh) only normalises, as in relMSE. Use it when a
# reference of thousands of samples cannot be made in time (a busy machine).
# Times: the median of the two renders (Cycles inside Blender, Tessera the
# wall time of `tessera render` with its defaults). BASE_BIN as in cycles.sh.
#   efficiency ratio = Tessera s x var / (Cycles s x var)
#
# Writes bench/results/cycles-seeds.{csv,md}.
# usage: bench/cycles-seeds.sh TESSERA_BIN "SCENES" "SPPS" [NORM_SPP]
set -euo pipefail
bin=$1 scenes=$2 spps=$3 norm_spp=${4:-256}
base_bin=${BASE_BIN:-}
size=256
here=$(dirname "$0")
out=bench/results
mkdir -p "$out"
tmp=$(mktemp -d /tmp/tessera-cycles-seeds.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
csv=$out/cycles-seeds.csv md=$out/cycles-seeds.md
now() { date +%s.%N; }
# tess BIN OUT SEED: wall seconds of one tessera render
tess() {
  local t0 t1
  t0=$(now)
  "$1" render "$scene" --width $size --height $size --spp "$spp" --seed "$3" --no-progress -o "$2.exr" > /dev/null
  t1=$(now)
  "$bin" tonemap "$2.exr" -o "$2.pfm" > /dev/null
  awk -v a="$t0" -v b="$t1" 'BEGIN {printf "%.3f", b - a}'
}
var() { "$here/cycles/depthvar.py" "$tmp/ref.pfm" "$1-1.pfm" "$1-2.pfm" | cut -d' ' -f2; }
mid() { awk -v a="$1" -v b="$2" 'BEGIN {printf "%.3f", (a + b) / 2}'; }

echo "scene,spp,cycles_s,cycles_var,tessera_s,tessera_var,efficiency_ratio,per_sample_ratio,base_s,base_var,base_efficiency_ratio" > "$csv"
for entry in $scenes; do
  scene=${entry%@*}
  name=$(basename "$scene" .json)
  ref=$("$here/cycles/reference.sh" "$scene" "$size" "$norm_spp")
  "$bin" tonemap "$ref" -o "$tmp/ref.pfm" > /dev/null
  for spp in $spps; do
    declare -a cs=() ts=() bs=()
    for seed in 1 2; do # interleaved
      line=$("$here/cycles/render.sh" "$scene" -o "$tmp/c-$seed.exr" --width $size --height $size --spp "$spp" --seed $seed)
      cs[$seed]=$(sed -n 's/.*render_s=\([0-9.]*\).*/\1/p' <<< "$line")
      "$bin" tonemap "$tmp/c-$seed.exr" -o "$tmp/c-$seed.pfm" > /dev/null
      ts[$seed]=$(tess "$bin" "$tmp/t-$seed" $seed)
      [[ -n $base_bin ]] && bs[$seed]=$(tess "$base_bin" "$tmp/b-$seed" $seed)
    done
    c_s=$(mid "${cs[1]}" "${cs[2]}") t_s=$(mid "${ts[1]}" "${ts[2]}")
    c_v=$(var "$tmp/c") t_v=$(var "$tmp/t")
    b_s="" b_v=""
    if [[ -n $base_bin ]]; then b_s=$(mid "${bs[1]}" "${bs[2]}") b_v=$(var "$tmp/b"); fi
    awk -v n="$name" -v s="$spp" -v cs="$c_s" -v cv="$c_v" -v ts="$t_s" -v tv="$t_v" -v bs="$b_s" -v bv="$b_v" 'BEGIN {
      printf "%s,%s,%.3f,%.4g,%.3f,%.4g,%.3f,%.3f", n, s, cs, cv, ts, tv, ts * tv / (cs * cv), tv / cv
      if (bs != "") printf ",%.3f,%.4g,%.3f", bs, bv, bs * bv / (cs * cv); else printf ",,,"
      printf "\n" }' >> "$csv"
    tail -1 "$csv"
  done
done
{
  echo "| scene, spp | Cycles s | Cycles var | Tessera s | Tessera var | efficiency ratio | per-sample ratio | base Tessera s | base var | base efficiency ratio |"
  echo "|---|---|---|---|---|---|---|---|---|---|"
  tail -n +2 "$csv" | awk -F, '{printf "| %s %s | %.2f | %s | %.2f | %s | %s | %s | %s | %s | %s |\n", $1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11}'
  echo
  echo "${size}x$size, same run, interleaved; var = relative variance of one image from two seeds, normalised by a"
  echo "$norm_spp-spp Cycles image; times: mean of the two renders (Cycles inside Blender, Tessera wall time, local farm)."
  [[ -n $base_bin ]] && echo "base: a second Tessera build ($base_bin) in the same loop."
  echo "Made by bench/cycles-seeds.sh on $(date -u +%Y-%m-%d), load average before: $(cut -d' ' -f1-3 /proc/loadavg)."
} > "$md"
echo "table: $md, data: $csv"
