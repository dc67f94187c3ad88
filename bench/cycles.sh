#!/usr/bin/env bash
# cycles.sh - Tessera against Blender Cycles in the same run: for each scene
# and sample count, a Cycles render (bench/cycles/render.sh: render time
# inside Blender, BVH build included, start-up excluded) and a Tessera render
# (`tessera render` with its defaults on the local farm: wall time of the
# whole command), interleaved, REPEATS times; the median times and each
# image's relMSE = mean((x - ref)^2 / (ref^2 + 0.01)) against a converged
# Cycles reference (bench/cycles/reference.sh, cached in bench/ref/).
#   efficiency ratio = Tessera s x relMSE / (Cycles s x relMSE): below 1,
#   Tessera reaches a given error sooner.
#   per-sample ratio = Tessera relMSE / Cycles relMSE at the same spp.
# Repeats alternate seeds 1 and 2 (1, 2, 1, ...): relMSE is that of the seed-1
# image, and with 2 or more repeats each renderer's relative variance
#   var = mean((x1 - x2)^2 / (ref^2 + 0.01)) / 2
# (bench/cycles/depthvar.py) is printed too. For an unbiased renderer and a
# perfect reference relMSE tends to var; relMSE - var estimates the squared
# difference between the renderer's converged picture and the reference
# (plus the reference's own noise): the check that the reference is the same
# picture. Times: the median over all repeats.
#
# Writes bench/results/cycles-same-run.csv (medians), cycles-same-run-runs.csv
# (every run), .md and .png (gnuplot) and prints the table. Printed, not
# asserted.
#
# usage: bench/cycles.sh TESSERA_BIN "SCENES" "SPPS" [REPEATS [REF_SPP [SUFFIX]]]
# A scene may be given as FILE@SPP to use a reference of SPP samples for it
# (default REF_SPP, 8192). With BASE_BIN=OTHER_TESSERA_BIN in the environment
# a second Tessera build (say, main before a change) is run in the same
# interleaved loop and gets its own columns (base s, relMSE, ratio). With
# KEEP=DIR every image is kept there as SCENE-SPP-RENDERER-SEED.exr.
set -euo pipefail
bin=$1 scenes=$2 spps=$3 repeats=${4:-3} ref_spp=${5:-8192} suffix=${6:+-$6}
size=256
out=bench/results
mkdir -p "$out"
tmp=$(mktemp -d /tmp/tessera-cycles-bench.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
base=$out/cycles-same-run$suffix
csv=$base.csv runs=$base-runs.csv md=$base.md png=$base.png
base_bin=${BASE_BIN:-}
load0=$(cut -d' ' -f1-3 /proc/loadavg)
command -v "${BLENDER:-blender}" > /dev/null || { echo "cycles.sh: blender not installed (apt-get install blender)" >&2; exit 1; }
cycles_version=$("${BLENDER:-blender}" --version 2>/dev/null | head -1)

median() { sort -g | awk '{a[NR] = $1} END {print (NR % 2) ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2}'; }
now() { date +%s.%N; }

echo "scene,spp,run,cycles_s,cycles_relmse,tessera_s,tessera_relmse,base_s,base_relmse" > "$runs"
echo "scene,spp,cycles_s,cycles_relmse,tessera_s,tessera_relmse,efficiency_ratio,per_sample_ratio,base_s,base_relmse,base_efficiency_ratio,cycles_var,tessera_var" > "$csv"
# seed_var c|t: the relative variance of one image from the seed-1 and seed-2
# renders ($tmp/X1.exr, $tmp/X2.exr), normalised by the reference.
seed_var() {
  "$bin" tonemap "$tmp/${1}1.exr" -o "$tmp/${1}1.pfm" > /dev/null
  "$bin" tonemap "$tmp/${1}2.exr" -o "$tmp/${1}2.pfm" > /dev/null
  bench/cycles/depthvar.py "$tmp/ref.pfm" "$tmp/${1}1.pfm" "$tmp/${1}2.pfm" | cut -d' ' -f2
}
echo "same run: Tessera (local farm, $(nproc) workers) against $cycles_version (CPU, 2 threads), ${size}x$size"
printf "%-16s %5s %9s %11s %10s %11s %10s %10s\n" scene spp "Cycles s" "relMSE" "Tessera s" "relMSE" "eff.ratio" "per-sample"
refs_used=""
for entry in $scenes; do
  scene=${entry%@*} rs=$ref_spp
  [[ $entry == *@* ]] && rs=${entry##*@}
  name=$(basename "$scene" .json)
  ref=$(bench/cycles/reference.sh "$scene" "$size" "$rs")
  refs_used="$refs_used $name $rs spp,"
  "$bin" tonemap "$ref" -o "$tmp/ref.pfm" > /dev/null
  for spp in $spps; do
    for ((r = 1; r <= repeats; r++)); do
      seed=$(((r - 1) % 2 + 1))
      line=$(bench/cycles/render.sh "$scene" -o "$tmp/c$seed.exr" --width $size --height $size --spp "$spp" --seed $seed)
      cs=$(sed -n 's/.*render_s=\([0-9.]*\).*/\1/p' <<< "$line")
      t0=$(now)
      "$bin" render "$scene" --width $size --height $size --spp "$spp" --seed $seed --no-progress -o "$tmp/t$seed.exr" > /dev/null
      t1=$(now)
      ts=$(awk -v a="$t0" -v b="$t1" 'BEGIN {printf "%.3f", b - a}')
      cr=$("$bin" compare "$tmp/c1.exr" "$ref" | awk '{print $4}')
      tr=$("$bin" compare "$tmp/t1.exr" "$ref" | awk '{print $4}')
      bs="" br=""
      if [[ -n $base_bin ]]; then
        t0=$(now)
        "$base_bin" render "$scene" --width $size --height $size --spp "$spp" --no-progress -o "$tmp/b.exr" > /dev/null
        t1=$(now)
        bs=$(awk -v a="$t0" -v b="$t1" 'BEGIN {printf "%.3f", b - a}')
        br=$("$bin" compare "$tmp/b.exr" "$ref" | awk '{print $4}')
      fi
      echo "$name,$spp,$r,$cs,$cr,$ts,$tr,$bs,$br" >> "$runs"
      if [[ -n ${KEEP:-} ]]; then # keep the images, e.g. to compare them with a reference made later
        mkdir -p "$KEEP"
        cp "$tmp/c$seed.exr" "$KEEP/$name-$spp-cycles-$seed.exr"
        cp "$tmp/t$seed.exr" "$KEEP/$name-$spp-tessera-$seed.exr"
      fi
    done
    cv="" tv=""
    if ((repeats >= 2)); then
      cv=$(seed_var c) tv=$(seed_var t)
    fi
    cs=$(awk -F, -v n="$name" -v s="$spp" '$1 == n && $2 == s {print $4}' "$runs" | median)
    ts=$(awk -F, -v n="$name" -v s="$spp" '$1 == n && $2 == s {print $6}' "$runs" | median)
    bs=""
    [[ -n $base_bin ]] && bs=$(awk -F, -v n="$name" -v s="$spp" '$1 == n && $2 == s {print $8}' "$runs" | median)
    awk -v n="$name" -v s="$spp" -v cs="$cs" -v cr="$cr" -v ts="$ts" -v tr="$tr" -v bs="$bs" -v br="$br" \
        -v cv="$cv" -v tv="$tv" 'BEGIN {
      printf "%s,%s,%.3f,%.4g,%.3f,%.4g,%.3f,%.3f", n, s, cs, cr, ts, tr, (ts * tr) / (cs * cr), tr / cr
      if (bs != "") printf ",%.3f,%.4g,%.3f", bs, br, (bs * br) / (cs * cr); else printf ",,,"
      printf ",%s,%s\n", cv, tv }' >> "$csv"
    tail -1 "$csv" | awk -F, '{printf "%-16s %5s %9.2f %11s %10.2f %11s %10s %10s", $1, $2, $3, $4, $5, $6, $7, $8
      if ($12 != "") printf "   var: Cycles %s, Tessera %s", $12, $13
      if ($9 != "") printf "   base: %.2f s, relMSE %s, ratio %s", $9, $10, $11; printf "\n"}'
  done
done

{
  if [[ -n $base_bin ]]; then
    echo "| scene, spp | Cycles s | Cycles relMSE | Tessera s | Tessera relMSE | efficiency ratio | per-sample ratio | base Tessera s | base relMSE | base efficiency ratio |"
    echo "|---|---|---|---|---|---|---|---|---|---|"
    tail -n +2 "$csv" | awk -F, '{printf "| %s %s | %.2f | %s | %.2f | %s | %s | %s | %.2f | %s | %s |\n", $1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11}'
  else
    echo "| scene, spp | Cycles s | Cycles relMSE | Tessera s | Tessera relMSE | efficiency ratio | per-sample ratio | Cycles var | Tessera var | efficiency ratio (var) |"
    echo "|---|---|---|---|---|---|---|---|---|---|"
    tail -n +2 "$csv" | awk -F, '{ e = ($12 != "" && $13 != "") ? sprintf("%.3f", $5 * $13 / ($3 * $12)) : ""
      printf "| %s %s | %.2f | %s | %.2f | %s | %s | %s | %s | %s | %s |\n", $1, $2, $3, $4, $5, $6, $7, $8, $12, $13, e}'
  fi
  echo
  echo "${size}x$size, same run, interleaved, median of $repeats; Cycles: $cycles_version, CPU 2 threads,"
  echo "render time inside Blender (BVH build included, start-up excluded); Tessera: wall time of \`tessera render\`"
  echo "with its defaults (local farm, $(nproc) workers). relMSE against Cycles references (seed 9001):${refs_used%,}."
  echo "efficiency ratio = Tessera s x relMSE / (Cycles s x relMSE); per-sample ratio = Tessera relMSE / Cycles relMSE."
  echo "var: relative variance of one image from seeds 1 and 2 (no reference needed; relMSE - var = squared"
  echo "difference from the reference + the reference's noise); efficiency ratio (var) = Tessera s x var / (Cycles s x var)."
  [[ -n $base_bin ]] && echo "base: a second Tessera build ($base_bin) in the same interleaved loop."
  echo "Made by \`make bench-cycles\` (bench/cycles.sh) on $(date -u +%Y-%m-%d), load average before: $load0, after: $(cut -d' ' -f1-3 /proc/loadavg)."
} > "$md"

if command -v gnuplot > /dev/null; then
  {
    echo "set terminal pngcairo size 900,600 noenhanced"
    echo "set output '$png'"
    echo "set logscale xy"
    echo "set xlabel 'seconds (2 cores)'"
    echo "set ylabel 'relative MSE against the Cycles reference'"
    echo "set title 'Tessera and Cycles, ${size}x$size, same run'"
    echo "set key bottom left"
    echo "set grid"
    echo "set datafile separator ','"
    plot="plot"
    pt=7
    for entry in $scenes; do
      name=$(basename "${entry%@*}" .json)
      awk -F, -v n="$name" '$1 == n {print $3 "," $4}' "$csv" > "$tmp/$name-c.dat"
      awk -F, -v n="$name" '$1 == n {print $5 "," $6}' "$csv" > "$tmp/$name-t.dat"
      plot="$plot '$tmp/$name-t.dat' using 1:2 with linespoints pt $pt lw 2 lc rgb 'red' title 'Tessera $name',"
      plot="$plot '$tmp/$name-c.dat' using 1:2 with linespoints pt $pt lw 2 lc rgb 'black' title 'Cycles $name',"
      pt=$((pt + 2))
    done
    echo "${plot%,}"
  } > "$tmp/plot.gp"
  gnuplot "$tmp/plot.gp" && echo "plot: $png"
fi
cat "$md"
echo "table: $md, data: $csv, every run: $runs"
