#!/usr/bin/env bash
# meshes.sh - big meshes against Blender Cycles in the same run: the
# cornell-spheres scene with each sphere replaced by a mesh
# (bench/mesh_scene.py): an icosphere of 20*4^L triangles
# (bench/icosphere.c) for each level L, and Blender's Suzanne with K levels
# of subdivision surface (bench/suzanne.py, "suzanneK"), a mesh a real user
# would render. Each round runs, interleaved, per scene:
#   1. `tessera render --workers 0` of one pixel: load + intersector build;
#   2. `tessera render` with its defaults at 256x256, SPP samples: the wall
#      time (loading and build included), its Msamples/s, peak RSS;
#   3. Cycles on the same scene (bench/cycles/render.sh: 2 threads, box
#      filter 1 px, no adaptive sampling / denoising / clamping, Filter
#      Glossy 0, caustics, 1024 bounces; scene sync and BVH build included,
#      Blender start-up and its Python OBJ reader excluded).
#   4. `tessera render --roulette-depth 1`, as 2. but with Cycles' own
#      roulette rule (paths may end from the second vertex, as Cycles' with
#      Min Light Bounces 0): about the same work per sample as Cycles.
# With more rounds the median of each figure is kept. Then, unless
# MESH_ERROR=0, the noise per sample of each (the default, Cycles' rule,
# Cycles): two more renders with other seeds, and half the relative MSE
# between them, mean((a-b)^2/(b^2+0.01)) / 2 (`tessera compare`), the
# variance of one image at SPP; equal_error = the time ratio times the
# variance ratio, Tessera's time against Cycles' for the same noise.
# round_ratios: each round's Tessera/Cycles from that round's two renders,
# made minutes apart (slash-separated), and round_ratio_median their
# median, beside `ratio`, whose medians may come from different rounds; on
# a VM whose speed drifts, the rounds' spread says how far one run's ratio
# can be trusted (2026-12-02: ico6 0.57 and 0.64 in two runs an hour
# apart, one run's rounds 0.52/0.69/0.58). Printed, and written to
# bench/results/meshes.csv with a gnuplot plot bench/results/meshes.png
# (bench/meshes-plot.sh).
# Not asserted. MESH_NO_CYCLES=1 skips Cycles (columns left empty).
#
# usage: bench/meshes.sh BIN_DIR [SCENES] [SPP] [ROUNDS]
#   SCENES default "5 6 7 8 suzanne5" (icosphere levels 5-8: 41k ... 2.6M
#   triangles; Suzanne 5: 2M), SPP 64, ROUNDS 1
set -euo pipefail
bin=$1 scenes=${2:-5 6 7 8 suzanne5} spp=${3:-64} rounds=${4:-1}
here=$(cd "$(dirname "$0")" && pwd)
dir=${MESH_BENCH_DIR:-/tmp/tessera-meshes}
mkdir -p "$dir" "$here/results"
cc -O2 -o "$dir/icosphere" "$here/icosphere.c" -lm
csv="$here/results/meshes.csv"
load0=$(cut -d' ' -f1-3 /proc/loadavg)
echo "scene,triangles,accel,load_build_s,render_s,msamples_s,peak_rss_mb,cycles_s,ratio,tessera_var,cycles_var,equal_error,rr1_s,rr1_ratio,rr1_var,rr1_equal_error,round_ratios,round_ratio_median" > "$csv"
# The median of a list of numbers (the lower middle one of an even count;
# nothing, and success, for an empty list: the columns MESH_NO_CYCLES leaves empty).
med() { tr ' ' '\n' <<< "$1" | sort -g | awk 'NF {v[++n] = $1} END {if (n) print v[int((n + 1) / 2)]}'; }
fmt="%10s %10s %7s %13s %9s %11s %12s %9s %14s %11s %11s %11s %7s %10s %10s %11s %16s %13s\n"
printf "$fmt" scene triangles accel load+build_s render_s Msamples/s peak_RSS_MB cycles_s tessera/cycles \
  tessera_var cycles_var equal_error rr1_s rr1/cycles rr1_var rr1_eq_err round_ratios round_median
tc() { "$bin/tessera" compare "$1" "$2" | awk '{printf "%.4g", $4 / 2}'; } # half the relative MSE of two images

# The OBJ of mesh $1 (icoL or suzanneK; made once, cached in $dir).
mesh_obj() {
  local obj="$dir/$1.obj"
  if [ ! -s "$obj" ]; then
    case $1 in
      suzanne*) "${BLENDER:-blender}" -b --factory-startup -noaudio --python-exit-code 1 --python "$here/suzanne.py" \
                  -- "${1#suzanne}" "$obj.tmp" > "$dir/suzanne.log" 2>&1 || { cat "$dir/suzanne.log" >&2; exit 1; } ;;
      *) "$dir/icosphere" "${1#ico}" > "$obj.tmp" ;;
    esac
    mv "$obj.tmp" "$obj"
  fi
  echo "$obj"
}

for sc in $scenes; do
  case $sc in suzanne*) name=$sc ;; *) name=ico$sc ;; esac
  obj=$(mesh_obj "$name")
  json="$dir/$name.json"
  python3 "$here/mesh_scene.py" "$here/../scenes/cornell-spheres.json" "$obj" > "$json"
  t256=("$bin/tessera" render "$json" --width 256 --height 256 --spp "$spp" --no-progress) # the benchmark's render
  lb="" rs="" ms="" rss="" cy="" r1="" rr=""
  for r in $(seq "$rounds"); do
    info=$( { /usr/bin/time -f "wall %e" "$bin/tessera" render "$json" --workers 0 --width 1 --height 1 \
              --spp 1 -v --no-progress -o "$dir/x.pfm"; } 2>&1) || { echo "$name: $info" >&2; exit 1; }
    tris=$(awk '/^scene/ {print $3}' <<< "$info")
    accel=$(awk '/^intersector:/ {print $2}' <<< "$info" | tr -d ',')
    lb+="$(awk '/^wall/ {print $2}' <<< "$info") "
    out=$( { /usr/bin/time -f "wall %e rss %M" "${t256[@]}" -o "$dir/t-$name.pfm"; } 2>&1) || { echo "$name: $out" >&2; exit 1; }
    tw=$(awk '/^wall/ {print $2}' <<< "$out") # this round's wall time
    rs+="$tw "
    ms+="$(awk '/^rendered/ {print $5}' <<< "$out") "
    rss+="$(awk '/^wall/ {printf "%.0f", $4 / 1024}' <<< "$out") "
    out=$( { /usr/bin/time -f "wall %e" "${t256[@]}" --roulette-depth 1 -o "$dir/r-$name.pfm"; } 2>&1) ||
      { echo "$name: $out" >&2; exit 1; }
    r1+="$(awk '/^wall/ {print $2}' <<< "$out") "
    if [ -z "${MESH_NO_CYCLES:-}" ]; then
      line=$("$here/cycles/render.sh" "$json" -o "$dir/c-$name.exr" --width 256 --height 256 --spp "$spp" --seed 1)
      cw=$(sed -n 's/.*render_s=\([0-9.]*\).*/\1/p' <<< "$line")
      cy+="$cw "
      rr+="$(awk -v t="$tw" -v c="$cw" 'BEGIN {printf "%.2f", t / c}') "
    fi
  done
  c=$(med "$cy") t=$(med "$rs") t1=$(med "$r1")
  ratio=$( [ -n "$c" ] && awk -v t="$t" -v c="$c" 'BEGIN {printf "%.2f", t / c}' || true)
  ratio1=$( [ -n "$c" ] && awk -v t="$t1" -v c="$c" 'BEGIN {printf "%.2f", t / c}' || true)
  tv="" cv="" v1="" eq="" eq1=""
  if [ "${MESH_ERROR:-1}" != 0 ]; then
    for sd in 1001 1002; do
      "${t256[@]}" --seed $sd -q -o "$dir/e-$name-$sd.pfm" > /dev/null
      "${t256[@]}" --seed $sd --roulette-depth 1 -q -o "$dir/e1-$name-$sd.pfm" > /dev/null
      if [ -z "${MESH_NO_CYCLES:-}" ]; then
        "$here/cycles/render.sh" "$json" -o "$dir/ec-$name-$sd.exr" --width 256 --height 256 --spp "$spp" \
          --seed $sd > /dev/null
      fi
    done
    tv=$(tc "$dir/e-$name-1001.pfm" "$dir/e-$name-1002.pfm") v1=$(tc "$dir/e1-$name-1001.pfm" "$dir/e1-$name-1002.pfm")
    if [ -z "${MESH_NO_CYCLES:-}" ]; then
      cv=$(tc "$dir/ec-$name-1001.exr" "$dir/ec-$name-1002.exr")
      eq=$(awk -v r="$t" -v c="$c" -v a="$tv" -v b="$cv" 'BEGIN {printf "%.2f", r / c * a / b}')
      eq1=$(awk -v r="$t1" -v c="$c" -v a="$v1" -v b="$cv" 'BEGIN {printf "%.2f", r / c * a / b}')
    fi
  fi
  rlist=$(tr -s ' ' '/' <<< "${rr% }") rmed=$(med "$rr")
  printf "$fmt" "$name" "$tris" "$accel" "$(med "$lb")" "$t" "$(med "$ms")" "$(med "$rss")" "${c:--}" "${ratio:--}" \
    "${tv:--}" "${cv:--}" "${eq:--}" "$t1" "${ratio1:--}" "${v1:--}" "${eq1:--}" "${rlist:--}" "${rmed:--}"
  echo "$name,$tris,$accel,$(med "$lb"),$t,$(med "$ms"),$(med "$rss"),$c,$ratio,$tv,$cv,$eq,$t1,$ratio1,$v1,$eq1,$rlist,$rmed" >> "$csv"
done
load1=$(cut -d' ' -f1-3 /proc/loadavg)
echo "written: $csv (256x256, spp $spp, rounds $rounds; $(nproc) cores; load average $load0 at the start, $load1 at the end)"
echo "# load average $load0 to $load1; $(nproc) cores; 256x256, $spp spp; $(date -u +%F)" >> "$csv"
if command -v gnuplot > /dev/null; then "$here/meshes-plot.sh" "$csv" "$here/results/meshes.png"; fi
