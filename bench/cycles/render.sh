#!/usr/bin/env bash
# cycles/render.sh - render a Tessera scene with Blender Cycles through
# render_scene.py (see its header for the scene map and the settings).
# Prints render_scene.py's one result line on stdout:
#   CYCLES render_s=SECONDS spp=N width=W height=H max_bounces=B triangles=T
# and Blender's own log on stderr only when it fails.
#
# usage: bench/cycles/render.sh SCENE -o OUT.exr [render_scene.py options]
set -euo pipefail
here=$(dirname "$0")
log=$(mktemp)
trap 'rm -f "$log"' EXIT
if ! "${BLENDER:-blender}" -b --factory-startup -noaudio --python-exit-code 1 \
     --python "$here/render_scene.py" -- "$@" > "$log" 2>&1; then
  cat "$log" >&2
  echo "cycles/render.sh: blender failed on $1" >&2
  exit 1
fi
grep '^CYCLES ' "$log"
