#!/usr/bin/env bash
# meshes-plot.sh - the gnuplot plot of bench/meshes.sh's CSV: wall time of
# `tessera render` (load and build included), of its load + build alone,
# and Cycles' render time, against triangles; icospheres as lines, other
# meshes (Suzanne) as single points. The CSV's last line (a comment) gives
# the load average, shown in the title.
#
# usage: bench/meshes-plot.sh CSV PNG
set -euo pipefail
csv=$1 png=$2
note=$(grep '^#' "$csv" | tail -1 | sed 's/^# *//; s/; .*//')
gnuplot <<GP
set datafile separator ","
set terminal pngcairo size 800,500
set output "$png"
set title "cornell-spheres with meshes, 256x256, 2 cores ($note)" font ",10"
set logscale xy
set xlabel "triangles"
set ylabel "seconds"
set key bottom right
ico(c) = strstrt(strcol(1), "ico") == 1 ? column(c) : NaN
other(c) = strstrt(strcol(1), "ico") == 1 ? NaN : column(c)
plot "$csv" every ::1 using 2:(ico(5)) with linespoints lc 1 pt 7 title "tessera render (load + build included)", \\
     "$csv" every ::1 using 2:(ico(8)) with linespoints lc 2 pt 7 title "Blender Cycles, 2 threads", \\
     "$csv" every ::1 using 2:(ico(4)) with linespoints lc 3 pt 7 title "tessera load + build", \\
     "$csv" every ::1 using 2:(other(5)) with points lc 1 pt 5 ps 1.5 title "Suzanne: tessera", \\
     "$csv" every ::1 using 2:(other(8)) with points lc 2 pt 5 ps 1.5 title "Suzanne: Cycles"
GP
echo "plot: $png"
