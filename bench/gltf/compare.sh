#!/usr/bin/env bash
# compare.sh - Tessera against Blender Cycles on scenes/gltf/emissive-box.glb
# with every material replaced by Lambert (albedo 0.7) in both renderers
# (Tessera: bench/gltf/emissive-box-lambert.json; Cycles: cycles_gltf.py
# --lambert 0.7), where the two models agree: diffuse + one-sided emission.
# For each number of bounces, prints the image means and the 16-pixel block
# differences (bench/cycles/blocks.py of the `cycles` branch, or a copy).
# usage: bench/gltf/compare.sh TESSERA_BIN [SPP] [BOUNCES...]
set -eu
T=${1:?tessera binary}; SPP=${2:-64}; shift 2 || true
BOUNCES=${*:-0 1 3 63}
OUT=${OUT:-build/gltf-compare}; mkdir -p "$OUT"
BLOCKS=${BLOCKS:-bench/cycles/blocks.py}
for b in $BOUNCES; do
  blender -b --factory-startup --python-exit-code 1 --python bench/gltf/cycles_gltf.py -- \
    scenes/gltf/emissive-box.glb -o "$OUT/c$b.exr" --width 160 --height 120 --spp "$SPP" --lambert 0.7 \
    --bounces "$b" 2>&1 | grep -E "^CYCLES|rror" || true
  "$T" tonemap "$OUT/c$b.exr" -o "$OUT/c$b.pfm" > /dev/null
  "$T" render bench/gltf/emissive-box-lambert.json --spp "$SPP" --max-depth $((b + 1)) --no-progress \
    -o "$OUT/t$b.pfm" > /dev/null 2>&1
  echo "bounces after the first hit: $b (Cycles max_bounces $b, Tessera max_depth $((b + 1)))"
  python3 "$BLOCKS" "$OUT/t$b.pfm" "$OUT/c$b.pfm" 16
done
