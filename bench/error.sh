#!/usr/bin/env bash
# error.sh - time against error: renders of a scene at growing sample counts
# on the local farm, each with its wall time, samples/s, RMSE and relative
# MSE against a converged reference (bench/reference.sh), for Tessera's
# default path and with features switched off or on (independent random
# numbers instead of Sobol, no MIS, no NEE, adaptive sampling).
#
# Writes bench/results/error-SCENE.csv, .md and .png (gnuplot, log-log) and
# prints the table. Printed, not asserted.
#
# usage: bench/error.sh TESSERA_BIN SCENE REF_SPP "SPP LADDER" "ADAPTIVE THRESHOLDS" [ADAPTIVE_MAX_SPP [SUFFIX]]
# SUFFIX names the results (error-SCENE-SUFFIX.*). With ONLY="variant ..." in
# the environment, only those variants are rendered again; the other rows of
# an existing CSV are kept.
set -euo pipefail
bin=$1 scene=$2 ref_spp=$3 ladder=$4 thresholds=$5 adaptive_max=${6:-1024} suffix=${7:+-$7}
only=${ONLY:-}
size=256
name=$(basename "$scene" .json)
ref=$(bench/reference.sh "$bin" "$scene" "$size" "$ref_spp")
ref_noise=$(cat "$ref.noise")
out=bench/results
mkdir -p "$out"
tmp=$(mktemp -d /tmp/tessera-error-bench.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
csv=$out/error-$name$suffix.csv md=$out/error-$name$suffix.md png=$out/error-$name$suffix.png
cores=$(nproc)
header="variant,spp,seconds,msamples_per_s,rmse,relmse,relmse_minus_ref_noise"
if [[ -n $only && -s $csv ]]; then # keep the rows of the variants not rendered again
  { echo "$header"; tail -n +2 "$csv" | awk -F, -v only=" $only " 'index(only, " " $1 " ") == 0'; } > "$tmp/kept.csv"
  mv "$tmp/kept.csv" "$csv"
else
  echo "$header" > "$csv"
fi
wanted() { [[ -z $only || " $only " == *" $1 "* ]]; }

# run VARIANT LABEL_SPP ARGS...: one render, one CSV line.
run() {
  local variant=$1 spp=$2; shift 2
  wanted "$variant" || return 0
  local line err
  line=$("$bin" render "$scene" --width $size --height $size --no-progress -o "$tmp/img.pfm" "$@" | head -1)
  err=$("$bin" compare "$tmp/img.pfm" "$ref")
  local secs rate rmse relmse
  secs=$(awk '{print $3}' <<< "$line")
  rate=$(awk '{print $5}' <<< "$line")
  rmse=$(awk '{print $2}' <<< "$err")
  relmse=$(awk '{print $4}' <<< "$err")
  local corrected
  corrected=$(awk -v a="$relmse" -v b="$ref_noise" 'BEGIN {printf "%.4g", a - b}')
  echo "$variant,$spp,$secs,$rate,$rmse,$relmse,$corrected" >> "$csv"
  printf "%-10s %6s spp %8.2f s %7s Ms/s  rmse %-10s relMSE %-10s (%s without the reference's noise)\n" \
    "$variant" "$spp" "$secs" "$rate" "$rmse" "$relmse" "$corrected"
}

echo "time against error: $name, ${size}x$size, local farm ($cores workers), reference $ref_spp spp"
echo "(reference noise: relMSE $ref_noise, included in relMSE, subtracted in brackets)"
for spp in $ladder; do
  run tessera "$spp" --spp "$spp"
  run random "$spp" --spp "$spp" --sampler random
  run no-mis "$spp" --spp "$spp" --no-mis
  run no-nee "$spp" --spp "$spp" --no-nee
done
for t in $thresholds; do
  run adaptive "$t" --spp "$adaptive_max" --noise-threshold "$t" --min-spp 16
done

{
  echo "| variant | spp (adaptive: threshold) | seconds | Msamples/s | RMSE | relMSE | relMSE - reference noise |"
  echo "|---|---|---|---|---|---|---|"
  tail -n +2 "$csv" | awk -F, '{printf "| %s | %s | %.2f | %s | %s | %s | %s |\n", $1, $2, $3, $4, $5, $6, $7}'
  echo
  echo "$name, ${size}x$size, local farm with $cores workers on $(nproc) cores; reference: $ref_spp spp of"
  echo "independent samples, its own noise relMSE $ref_noise (included in relMSE, subtracted in the last column)."
  echo "Made by \`make bench\` (bench/error.sh) on $(date -u +%Y-%m-%d)."
} > "$md"

if command -v gnuplot > /dev/null; then
  cycles=""
  # No Cycles curve: Cycles must be measured in the same run as Tessera
  # (docs/performance.md, "Against Blender Cycles, in one run").
  {
    echo "set terminal pngcairo size 900,600 noenhanced"
    echo "set output '$png'"
    echo "set logscale xy"
    echo "set xlabel 'wall time, seconds (2 cores)'"
    echo "set ylabel 'relative MSE'"
    echo "set title '$name ${size}x$size: error against time'"
    echo "set key top right"
    echo "set grid"
    echo "set datafile separator ','"
    for v in tessera adaptive random no-mis no-nee; do # one file per line, in time order
      awk -F, -v v="$v" '$1 == v {print $3 "," $6}' "$csv" | sort -t, -g -k1 > "$tmp/$v.dat"
    done
    echo -n "plot '$tmp/tessera.dat' using 1:2 with linespoints pt 7 lw 2 title 'Tessera (Sobol, NEE+MIS)'"
    echo -n ", '$tmp/adaptive.dat' using 1:2 with linespoints pt 9 title 'Tessera adaptive'"
    echo -n ", '$tmp/random.dat' using 1:2 with linespoints pt 5 title 'independent random numbers'"
    echo -n ", '$tmp/no-mis.dat' using 1:2 with linespoints pt 4 title 'no MIS'"
    echo -n ", '$tmp/no-nee.dat' using 1:2 with linespoints pt 3 title 'no NEE'"
    echo "$cycles"
    true
  } > "$tmp/plot.gp"
  gnuplot "$tmp/plot.gp" && echo "plot: $png"
else
  echo "gnuplot not installed: no plot (make deps installs gnuplot-nox)"
fi
echo "table: $md, data: $csv"
