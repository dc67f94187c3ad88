#!/usr/bin/env bash
# ab.sh - A/B of Tessera builds on the error per unit of work: each build
# renders each scene twice (seeds 1 and 2) at SPP on the local farm; prints
# the CPU seconds per render (user + sys of tessera and its workers, less
# sensitive to a busy machine than wall time), the image's relative variance
# from the two seeds (bench/cycles/depthvar.py, normalised by NORM_DIR/SCENE.pfm,
# any well-converged image of the scene) and their product (lower is better),
# and the mean of the seed-1 image (builds that change only the noise agree).
#
# usage: bench/ab.sh SPP NORM_DIR "NAME=BIN_DIR ..." SCENE...
#   BIN_DIR holds that build's tessera and tessera-worker.
set -euo pipefail
spp=$1 norm=$2 builds=$3
shift 3
tmp=$(mktemp -d /tmp/tessera-ab.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
here=$(dirname "$0")
printf "%-16s %-10s %10s %11s %12s %10s\n" scene build "CPU s" "rel. var" "CPU s x var" "mean"
for scene in "$@"; do
  name=$(basename "$scene" .json)
  for b in $builds; do
    label=${b%%=*} dir=${b#*=}
    cpu=0
    for seed in 1 2; do
      out=$tmp/$label-$seed
      c=$( { /usr/bin/time -f "%U %S" "$dir/tessera" render "$scene" --width 256 --height 256 --spp "$spp" --seed $seed \
             --no-progress -o "$out.exr" > /dev/null; } 2>&1 | tail -1 | awk '{print $1 + $2}')
      cpu=$(awk -v a="$cpu" -v b="$c" 'BEGIN {print a + b}')
      "$dir/tessera" tonemap "$out.exr" -o "$out.pfm" > /dev/null
    done
    read -r mean v <<< "$("$here/cycles/depthvar.py" "$norm/$name.pfm" "$tmp/$label-1.pfm" "$tmp/$label-2.pfm")"
    awk -v n="$name" -v l="$label" -v c="$cpu" -v v="$v" -v m="$mean" \
      'BEGIN {printf "%-16s %-10s %10.2f %11.4g %12.4g %10.6f\n", n, l, c / 2, v, c / 2 * v, m}'
  done
done
