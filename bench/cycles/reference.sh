#!/usr/bin/env bash
# cycles/reference.sh - a converged Blender Cycles reference for the same-run
# comparison (bench/cycles.sh), cached under bench/ref/ (not in git) like
# bench/reference.sh: named after the scene's contents, the size, the sample
# count, the bounce limit and what builds the scene (Blender's version, the
# sphere tessellation, render_scene.py's SCENE_MAP_VERSION). Seed 9001, which
# no measured render uses. The render log (with its CYCLES line) is kept next
# to it as .log.
#
# usage: bench/cycles/reference.sh SCENE SIZE SPP [MAX_BOUNCES [SPHERE_SUBDIV]]
# prints the path of the reference (an OpenEXR, linear float RGB)
set -euo pipefail
scene=$1 size=$2 spp=$3 bounces=${4:-1024} subdiv=${5:-8}
here=$(dirname "$0")
blender=${BLENDER:-blender}
name=$(basename "$scene" .json)
version=$("$blender" --version 2>/dev/null | head -1 | tr -cd '0-9.')
map=$(grep -m1 '^SCENE_MAP_VERSION' "$here/render_scene.py" | tr -cd '0-9')
sum=$( { cat "$scene"; echo "blender $version subdiv $subdiv map $map"; } | sha256sum | cut -c1-12)
dir=bench/ref
ref=$dir/cycles-$name-$size-$spp-b$bounces-$sum.exr
mkdir -p "$dir"
if [[ ! -s $ref ]]; then
  echo "cycles reference: $name at ${size}x$size, $spp spp, $bounces bounces (cached in $dir once made)" >&2
  "$here/render.sh" "$scene" -o "$ref.tmp.exr" --width "$size" --height "$size" --spp "$spp" --seed 9001 \
    --max-bounces "$bounces" --sphere-subdiv "$subdiv" > "$ref.log"
  mv "$ref.tmp.exr" "$ref"
fi
echo "$ref"
