#!/usr/bin/env bash
# accel.sh - where the flat intersector stops paying: the Cornell box plus a
# tessellated sphere of growing triangle count, rendered with
# render.accel = "flat" and "bvh" (one process, one thread), interleaved.
# Printed, not asserted.
# usage: bench/accel.sh TESSERA_BIN [ROUNDS]
set -euo pipefail
bin=$1 rounds=${2:-3}
dir=$(mktemp -d /tmp/tessera-accel-bench.XXXXXX)
trap 'rm -rf "$dir"' EXIT
# A UV sphere of radius 80 with n rings and 2n segments: 4n(n-1) triangles.
sphere_obj() {
  awk -v n="$1" 'BEGIN {
    pi = atan2(0, -1); m = 2 * n
    print "v 0 80 0"; print "v 0 -80 0"
    for (i = 1; i < n; i++) for (j = 0; j < m; j++) {
      th = pi * i / n; ph = 2 * pi * j / m
      printf "v %.6f %.6f %.6f\n", 80 * sin(th) * cos(ph), 80 * cos(th), 80 * sin(th) * sin(ph)
    }
    for (i = 1; i < n; i++) for (j = 0; j < m; j++) {
      a = 3 + (i - 1) * m + j; b = 3 + (i - 1) * m + (j + 1) % m
      if (i == 1) print "f 1", b, a
      else { c = a - m; d = b - m; print "f", c, d, b; print "f", c, b, a }
      if (i == n - 1) print "f 2", a, b
    }
  }'
}
echo "triangles  flat Msamples/s  bvh Msamples/s  (median of $rounds, 128x128, 16 spp, 1 thread)"
for n in 2 3 4 6 8 12; do
  sphere_obj "$n" > "$dir/sphere.obj"
  for a in flat bvh; do
    sed -e "s/\"seed\": 1/\"seed\": 1, \"accel\": \"$a\"/" \
        -e "s|\"shapes\": \[|\"shapes\": [ {\"type\": \"mesh\", \"file\": \"$dir/sphere.obj\", \"material\": \"white\", \"translate\": [370, 330, 380]},|" \
        scenes/cornell-box.json > "$dir/$a.json"
  done
  tris=$("$bin" render "$dir/flat.json" --workers 0 --width 4 --height 4 --spp 1 -v --no-progress -o "$dir/x.pfm" 2>&1 |
         awk '/^scene/ {print $3}')
  declare -A rate=()
  for r in $(seq "$rounds"); do
    for a in flat bvh; do
      rate[$a]+="$("$bin" render "$dir/$a.json" --workers 0 --threads 1 --width 128 --height 128 --spp 16 \
                   --no-progress -o "$dir/$a.pfm" | awk '{print $5}') "
    done
  done
  med() { tr ' ' '\n' <<< "$1" | grep . | sort -g | awk '{v[NR] = $1} END {print v[int((NR + 1) / 2)]}'; }
  printf "%9s  %15s  %14s\n" "$tris" "$(med "${rate[flat]}")" "$(med "${rate[bvh]}")"
  unset rate
done
