#!/usr/bin/env bash
# bench.sh - render speed of the single-process renderer, printed not asserted.
# usage: bench/bench.sh TESSERA_BIN [SCENE] [SPP]
set -euo pipefail
bin=$1
scene=${2:-scenes/cornell-box.json}
spp=${3:-16}
cores=$(nproc)
echo "scene $scene, 512x512, $spp spp, max depth 64, NEE + MIS, $(uname -m), $cores cores"
for t in 1 "$cores"; do
  line=$("$bin" render "$scene" --workers 0 --threads "$t" --spp "$spp" --no-progress -o /tmp/tessera-bench.pfm)
  echo "threads $t: $line"
done
