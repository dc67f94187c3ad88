#!/usr/bin/env bash
# layers.sh - fail when a file includes a header from a layer it may not use.
#
# The layers (README "Where things are"), each allowed what follows it:
#   cli          -> coordinator worker job render image net base
#   coordinator  -> job render image net base
#   worker       -> job render net base
#   job          -> render net base      (what a job and a tile are on the wire)
#   render       -> base                 (scene, shapes, accel, materials, lights, cameras, integrator)
#   image        -> base                 (codecs, tone mapping, comparison)
#   net          -> base                 (frames, messages, connections, auth)
#   base         -> (nothing)            (common/*.h: vectors, JSON, files, threads over ranges, args, logging, limits)
# A quoted include names its layer by its first folder ("render/scene.h"); a
# plain name is the including file's sibling if one exists, else a base header.
# Usage: layers.sh [ROOT] (default: this checkout). Prints each crossing as
# FILE:LINE: LAYER may not include HEADER; exit 1 if any.
set -u
cd "${1:-$(dirname "$0")/..}" || exit 2
declare -A allowed=(
  [cli]="cli coordinator worker job render image net base"
  [coordinator]="coordinator job render image net base"
  [worker]="worker job render net base"
  [bench]="coordinator job render image net base"
  [job]="job render net base"
  [render]="render base" [image]="image base" [net]="net base" [base]="base"
)
layer_of_file() {
  case "$1" in
    common/*/*) local r=${1#common/}; echo "${r%%/*}" ;;
    common/*) echo base ;;
    *) echo "${1%%/*}" ;;
  esac
}
bad=0
while IFS= read -r f; do
  layer=$(layer_of_file "$f")
  [ -n "${allowed[$layer]:-}" ] || continue
  dir=$(dirname "$f")
  while IFS=: read -r line inc; do
    case "$inc" in
      */*) target=${inc%%/*}
           [ "$target" = ".." ] && target="(relative path)" ;;
      *) if [ -e "$dir/$inc" ]; then target=$layer
         elif [ -e "common/$inc" ]; then target=base
         else continue; fi ;;
    esac
    case " ${allowed[$layer]} " in
      *" $target "*) ;;
      *) echo "$f:$line: $layer may not include \"$inc\" ($target)"; bad=1 ;;
    esac
  done < <(grep -n '^[[:space:]]*#[[:space:]]*include[[:space:]]*"' "$f" | sed -E 's/^([0-9]+):[^"]*"([^"]+)".*/\1:\2/')
done < <(find common cli coordinator worker bench -name '*.[ch]' 2>/dev/null | sort)
if [ $bad -eq 0 ]; then echo "layers: every #include stays within its layer"; fi
exit $bad
