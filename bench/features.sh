#!/usr/bin/env bash
# features.sh - what a scene does not use costs nothing, and what the
# specialised path gains: the Cornell box as it is, with unused glass, mirror
# and glossy materials defined, and through the general intersector
# (render.accel = "bvh") instead of the flat one chosen for it. One process,
# one thread, interleaved rounds, medians. Printed, not asserted.
# usage: bench/features.sh TESSERA_BIN [ROUNDS]
set -euo pipefail
bin=$1 rounds=${2:-5}
dir=$(mktemp -d /tmp/tessera-features-bench.XXXXXX)
trap 'rm -rf "$dir"' EXIT
cp scenes/cornell-box.json "$dir/plain.json"
sed 's/"materials": {/"materials": {\n    "unused glass": {"type": "glass", "ior": 1.5},\n    "unused mirror": {"type": "mirror", "reflectance": [0.9, 0.9, 0.9]},\n    "unused glossy": {"type": "glossy", "diffuse": [0.3, 0.3, 0.3], "specular": [0.5, 0.5, 0.5], "exponent": 50},/' \
  scenes/cornell-box.json > "$dir/unused.json"
sed 's/"seed": 1/"seed": 1, "accel": "bvh"/' scenes/cornell-box.json > "$dir/bvh.json"
for v in plain unused bvh; do
  "$bin" render "$dir/$v.json" --workers 0 --width 4 --height 4 --spp 1 -v --no-progress -o "$dir/x.pfm" 2>&1 |
    awk -v v="$v" '/^features|^intersector/ {print v ": " $0}'
done
declare -A rate=()
for r in $(seq "$rounds"); do
  for v in plain unused bvh; do
    rate[$v]+="$("$bin" render "$dir/$v.json" --workers 0 --threads 1 --width 128 --height 128 --spp 32 \
                 --no-progress -o "$dir/$v.pfm" | awk '{print $5}') "
  done
done
med() { tr ' ' '\n' <<< "$1" | grep . | sort -g | awk '{v[NR] = $1} END {print v[int((NR + 1) / 2)]}'; }
echo "Msamples/s, one thread, 128x128, 32 spp, median of $rounds interleaved rounds:"
echo "  cornell-box as it is (flat intersector):         $(med "${rate[plain]}")   [${rate[plain]% }]"
echo "  with unused glass, mirror and glossy materials:  $(med "${rate[unused]}")   [${rate[unused]% }]"
echo "  through the general BVH path instead:            $(med "${rate[bvh]}")   [${rate[bvh]% }]"
cmp -s "$dir/plain.pfm" "$dir/unused.pfm" && echo "  unused materials: the same image, byte for byte" ||
  echo "  unused materials: the image DIFFERS"
cmp -s "$dir/plain.pfm" "$dir/bvh.pfm" && echo "  bvh path: the same image, byte for byte" || echo "  bvh path: the image differs"
