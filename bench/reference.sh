#!/usr/bin/env bash
# reference.sh - a converged reference image for the time-against-error
# benchmark, cached under bench/ref/ (not in git) and named after what made
# it: scene file contents, size, sample count. Also writes its noise
# estimate: the relative MSE between the reference and its own first half of
# samples. With independent samples that equals the reference's own variance
# (x_half - x_full = (x_half - y_half)/2, variance 2 s^2/(4 n/2) = s^2/n).
#
# usage: bench/reference.sh TESSERA_BIN SCENE SIZE SPP
# prints the path of the reference; its noise is in the same name + .noise
set -euo pipefail
bin=$1 scene=$2 size=$3 spp=$4
name=$(basename "$scene" .json)
sum=$(sha256sum "$scene" | cut -c1-12)
dir=bench/ref
ref=$dir/$name-$size-$spp-$sum.pfm
mkdir -p "$dir"
if [[ ! -s $ref || ! -s $ref.noise ]]; then
  half=$dir/$name-$size-$((spp / 2))-$sum.half.pfm
  # Independent random numbers and a seed no benchmark uses: the reference
  # shares no sample pattern with what it measures.
  common=(render "$scene" --width "$size" --height "$size" --sampler random --seed 9001 --no-progress)
  echo "reference: $name at ${size}x$size, $spp spp (cached in $dir once made)" >&2
  "$bin" "${common[@]}" --spp $((spp / 2)) -o "$half" >&2
  "$bin" "${common[@]}" --spp "$spp" -o "$ref.tmp.pfm" >&2
  "$bin" compare "$half" "$ref.tmp.pfm" | awk '{print $4}' > "$ref.noise"
  mv "$ref.tmp.pfm" "$ref"
  rm -f "$half"
fi
echo "$ref"
