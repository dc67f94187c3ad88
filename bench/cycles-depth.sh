#!/usr/bin/env bash
# cycles-depth.sh - variance by path length, Tessera and Cycles: where does
# each renderer's error per sample come from? For each scene and depth limit
# d, both renderers render twice (seeds 1 and 2) at SPP samples:
#   Tessera `--max-depth d`, Cycles max bounces d - 1 (every kind).
# Tessera's max_depth counts path vertices after the camera: with d = 1 the
# first hit is lit by light sampling and the BSDF ray may still hit the light
# (direct light only, paths of 2 segments). Cycles' max bounces counts the
# bounces after the first hit: 0 = direct light only. So Tessera d = Cycles
# d - 1; the mean columns check the mapping (they must agree).
# From the pairs (bench/cycles/depthvar.py): the relative variance of the
# depth-d image and of its increment over d - 1 (the paths of exactly d + 1
# segments), each at SPP spp, normalised by the converged full Cycles
# reference as relMSE is. "full" is each renderer's default limit (Tessera
# the scene's max_depth, Cycles 1024), its increment over the largest d.
#
# Writes bench/results/cycles-depth.csv and .md, prints the table.
# usage: bench/cycles-depth.sh TESSERA_BIN "SCENES" "DEPTHS" SPP [REF_SPP [SUFFIX]]
# (SUFFIX: write cycles-depth-SUFFIX.{csv,md}, e.g. a second sample count)
# SIZE=N renders N x N (default 256; 128 for quick looks). KEEP=DIR keeps
# every image there as SCENE-RENDERER-DEPTH-SEED.pfm (for per-pixel maps,
# bench/cycles/pixelvar.py).
set -euo pipefail
bin=$1 scenes=$2 depths=$3 spp=$4 ref_spp=${5:-8192} suffix=${6:+-$6}
size=${SIZE:-256}
out=bench/results
mkdir -p "$out"
tmp=$(mktemp -d /tmp/tessera-cycles-depth.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
csv=$out/cycles-depth$suffix.csv md=$out/cycles-depth$suffix.md
here=$(dirname "$0")
load0=$(cut -d' ' -f1-3 /proc/loadavg)

# render RENDERER DEPTH SEED: $tmp/RENDERER-DEPTH-SEED.pfm
render() {
  local who=$1 d=$2 seed=$3 f=$tmp/$1-$2-$3
  if [[ $who == tessera ]]; then
    local lim=(); [[ $d != full ]] && lim=(--max-depth "$d")
    "$bin" render "$scene" --width $size --height $size --spp "$spp" --seed "$seed" "${lim[@]}" \
      --no-progress -o "$f.exr" > /dev/null
  else
    local b=1024; [[ $d != full ]] && b=$((d - 1))
    "$here/cycles/render.sh" "$scene" -o "$f.exr" --width $size --height $size --spp "$spp" --seed "$seed" \
      --max-bounces "$b" > /dev/null
  fi
  "$bin" tonemap "$f.exr" -o "$f.pfm" > /dev/null
}

echo "scene,depth,tessera_mean,tessera_var,tessera_inc_var,cycles_mean,cycles_var,cycles_inc_var,inc_var_ratio" > "$csv"
echo "variance by depth limit, ${size}x$size, $spp spp, relative to the converged Cycles image"
printf "%-16s %5s | %9s %10s %10s | %9s %10s %10s | %s\n" scene depth "T mean" "T var" "T inc var" "C mean" "C var" \
  "C inc var" "inc T/C"
for entry in $scenes; do # FILE or FILE@REF_SPP, as in cycles.sh
  scene=${entry%@*} rs=$ref_spp
  [[ $entry == *@* ]] && rs=${entry##*@}
  name=$(basename "$scene" .json)
  ref=$("$here/cycles/reference.sh" "$scene" "$size" "$rs")
  "$bin" tonemap "$ref" -o "$tmp/ref.pfm" > /dev/null
  [[ -n ${KEEP:-} ]] && mkdir -p "$KEEP" && cp "$tmp/ref.pfm" "$KEEP/$name-ref.pfm"
  prev=""
  for d in $depths full; do
    declare -A res=()
    for who in tessera cycles; do
      render $who "$d" 1
      render $who "$d" 2
      f=$tmp/$who-$d
      if [[ -n $prev ]]; then
        res[$who]=$("$here/cycles/depthvar.py" "$tmp/ref.pfm" "$f-1.pfm" "$f-2.pfm" "$tmp/$who-$prev-1.pfm" "$tmp/$who-$prev-2.pfm")
      else # the first limit's increment is the image itself
        r=$("$here/cycles/depthvar.py" "$tmp/ref.pfm" "$f-1.pfm" "$f-2.pfm")
        res[$who]="$r $(cut -d' ' -f2 <<< "$r")"
      fi
    done
    read -r tm tv ti <<< "${res[tessera]}"
    read -r cm cv ci <<< "${res[cycles]}"
    ratio=$(awk -v a="$ti" -v b="$ci" 'BEGIN {printf "%.3f", (b > 0) ? a / b : 0}')
    echo "$name,$d,$tm,$tv,$ti,$cm,$cv,$ci,$ratio" >> "$csv"
    printf "%-16s %5s | %9.5f %10.4g %10.4g | %9.5f %10.4g %10.4g | %s\n" "$name" "$d" "$tm" "$tv" "$ti" "$cm" "$cv" "$ci" "$ratio"
    if [[ -n ${KEEP:-} ]]; then
      mkdir -p "$KEEP"
      for f in "$tmp"/*-"$d"-[12].pfm; do cp "$f" "$KEEP/$name-$(basename "$f")"; done
    fi
    [[ -n $prev ]] && rm -f "$tmp"/*-"$prev"-[12].*
    prev=$d
  done
done

{
  echo "| scene | Tessera --max-depth (Cycles bounces) | Tessera mean | Cycles mean | Tessera var | Cycles var | Tessera increment var | Cycles increment var | increment T/C |"
  echo "|---|---|---|---|---|---|---|---|---|"
  tail -n +2 "$csv" | awk -F, '{ c = ($2 == "full") ? "full (64 / 1024)" : sprintf("%s (%d)", $2, $2 - 1);
    printf "| %s | %s | %.5f | %.5f | %.3g | %.3g | %.3g | %.3g | %s |\n", $1, c, $3, $6, $4, $7, $5, $8, $9 }'
  echo
  echo "${size}x$size, $spp spp, two seeds per cell; var = relative variance of the image, increment var = of the"
  echo "image minus the one with the depth limit one lower (the paths one segment longer), both normalised like relMSE"
  echo "by the converged full Cycles image. Made by \`make bench-cycles-depth\` (bench/cycles-depth.sh) on $(date -u +%Y-%m-%d),"
  echo "load average before: $load0, after: $(cut -d' ' -f1-3 /proc/loadavg)."
} > "$md"
echo "table: $md, data: $csv"
