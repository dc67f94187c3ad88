#!/usr/bin/env bash
# meshes.sh - big meshes: cornell-spheres with each sphere an icosphere of
# 20*4^L triangles (bench/icosphere.c, bench/mesh_scene.py), rendered by
# `tessera render` with its defaults (local farm, one worker per core) and
# in one process, 256x256 at SPP samples per pixel. Printed and written to
# bench/results/meshes.csv; not asserted.
#
# Columns: level, triangles, the intersector auto chose, load_build_s (one
# process: scene load and intersector build, measured as a 1-pixel render),
# render_s (the "rendered" line of the default local-farm run: workers'
# load and build included), wall_s (that run's wall time), msamples_s,
# peak_rss_mb (the largest process of that run), inproc_s (wall time with
# --workers 0), and cycles_s, left empty for bench/cycles/ to fill (same
# scenes, same resolution and spp).
#
# usage: bench/meshes.sh BIN_DIR [LEVELS] [SPP] [ROUNDS]
#   LEVELS default "5 6 7 8 9" (41k ... 10.5M triangles), SPP 64, ROUNDS 1
#   (with more rounds the median of each figure is kept)
set -euo pipefail
bin=$1 levels=${2:-5 6 7 8 9} spp=${3:-64} rounds=${4:-1}
here=$(cd "$(dirname "$0")" && pwd)
dir=${MESH_BENCH_DIR:-/tmp/tessera-meshes}
mkdir -p "$dir" "$here/results"
cc -O2 -o "$dir/icosphere" "$here/icosphere.c" -lm
csv="$here/results/meshes.csv"
echo "level,triangles,accel,load_build_s,render_s,wall_s,msamples_s,peak_rss_mb,inproc_s,cycles_s" > "$csv"
med() { tr ' ' '\n' <<< "$1" | grep . | sort -g | awk '{v[NR] = $1} END {print v[int((NR + 1) / 2)]}'; }
printf "%5s %10s %7s %13s %9s %8s %11s %12s %9s\n" level triangles accel load+build_s render_s wall_s Msamples/s \
  peak_RSS_MB inproc_s
for L in $levels; do
  obj="$dir/ico$L.obj"
  [ -s "$obj" ] || "$dir/icosphere" "$L" > "$obj"
  python3 "$here/mesh_scene.py" "$here/../scenes/cornell-spheres.json" "$obj" > "$dir/spheres$L.json"
  lb="" rs="" ws="" ms="" rss="" ip=""
  for r in $(seq "$rounds"); do
    info=$( { /usr/bin/time -f "wall %e" "$bin/tessera" render "$dir/spheres$L.json" --workers 0 --width 1 --height 1 \
              --spp 1 -v --no-progress -o "$dir/x.pfm"; } 2>&1) || { echo "level $L: $info" >&2; exit 1; }
    tris=$(awk '/^scene/ {print $3}' <<< "$info")
    accel=$(awk '/^intersector:/ {print $2}' <<< "$info" | tr -d ',')
    lb+="$(awk '/^wall/ {print $2}' <<< "$info") "
    out=$( { /usr/bin/time -f "wall %e rss %M" "$bin/tessera" render "$dir/spheres$L.json" --width 256 --height 256 \
             --spp "$spp" --no-progress -o "$dir/farm$L.pfm"; } 2>&1) || { echo "level $L: $out" >&2; exit 1; }
    rs+="$(awk '/^rendered/ {print $3}' <<< "$out") "
    ms+="$(awk '/^rendered/ {print $5}' <<< "$out") "
    ws+="$(awk '/^wall/ {print $2}' <<< "$out") "
    rss+="$(awk '/^wall/ {printf "%.0f", $4 / 1024}' <<< "$out") "
    one=$( { /usr/bin/time -f "wall %e" "$bin/tessera" render "$dir/spheres$L.json" --workers 0 --width 256 --height 256 \
             --spp "$spp" --no-progress -o "$dir/one$L.pfm"; } 2>&1) || { echo "level $L: $one" >&2; exit 1; }
    ip+="$(awk '/^wall/ {print $2}' <<< "$one") "
    cmp -s "$dir/farm$L.pfm" "$dir/one$L.pfm" || { echo "level $L: farm and in-process images differ" >&2; exit 1; }
  done
  printf "%5s %10s %7s %13s %9s %8s %11s %12s %9s\n" "$L" "$tris" "$accel" "$(med "$lb")" "$(med "$rs")" "$(med "$ws")" \
    "$(med "$ms")" "$(med "$rss")" "$(med "$ip")"
  echo "$L,$tris,$accel,$(med "$lb"),$(med "$rs"),$(med "$ws"),$(med "$ms"),$(med "$rss"),$(med "$ip")," >> "$csv"
done
echo "written: $csv (spp $spp, rounds $rounds; $(nproc) cores; load average $(cut -d' ' -f1-3 /proc/loadavg))"
