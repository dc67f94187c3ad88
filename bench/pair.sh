#!/usr/bin/env bash
# pair.sh - paired A/B of two builds' render CPU, for changes of a few per
# cent that wall times on a shared 2-core VM cannot resolve: each round runs
# A and B at once, one per core (taskset), each `tessera render SCENE
# --workers 0 --threads 1` with the given options, and swaps the cores every
# round (the two cores of a VM need not be equally fast). Prints each
# round's user CPU, the ratio of the sums, B/A (below 1: B is faster), and
# the median of the rounds' ratios with its interquartile range, which a
# few outlying rounds move less than the sums (on the twenty-fifth
# session's host single rounds ranged 0.6-1.5 for builds within about 10%
# of each other). Noise: about +-3% at 6-8 rounds of a 1 s render, +-1% at 16
# on a quiet host; changes below that need more rounds. Nothing is asserted.
#
# usage: bench/pair.sh A_BIN_DIR B_BIN_DIR ROUNDS SCENE [tessera render options]
#   e.g. bench/pair.sh /tmp/old/bin build/release/bin 16 ico5.json --width 96 --height 96 --spp 64
set -euo pipefail
a=$1 b=$2 n=$3 scene=$4
shift 4
tmp=$(mktemp -d /tmp/tessera-pair.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
sa=0 sb=0
: > "$tmp/ratios"
for r in $(seq "$n"); do
  ca=$(( r % 2 )) cb=$(( (r + 1) % 2 ))
  /usr/bin/time -f "%U" -o "$tmp/ta" taskset -c $ca "$a/tessera" render "$scene" --workers 0 --threads 1 \
    --no-progress -o "$tmp/a.pfm" "$@" > /dev/null 2>&1 &
  /usr/bin/time -f "%U" -o "$tmp/tb" taskset -c $cb "$b/tessera" render "$scene" --workers 0 --threads 1 \
    --no-progress -o "$tmp/b.pfm" "$@" > /dev/null 2>&1 &
  wait
  ta=$(tail -1 "$tmp/ta") tb=$(tail -1 "$tmp/tb")
  sa=$(awk -v x="$sa" -v y="$ta" 'BEGIN {print x + y}') sb=$(awk -v x="$sb" -v y="$tb" 'BEGIN {print x + y}')
  awk -v r="$r" -v x="$ta" -v y="$tb" -v f="$tmp/ratios" \
    'BEGIN {printf "round %d: A %.2f s, B %.2f s, B/A %.3f\n", r, x, y, y / x; printf "%.6f\n", y / x >> f}'
done
awk -v x="$sa" -v y="$sb" 'BEGIN {printf "user CPU: A %.2f s, B %.2f s, B/A %.3f\n", x, y, y / x}'
sort -g "$tmp/ratios" | awk '{v[NR] = $1} END {
  printf "median of the rounds'"'"' B/A %.3f (interquartile %.3f-%.3f, %d rounds)\n", v[int((NR + 1) / 2)], v[int((NR + 3) / 4)], v[int((3 * NR + 3) / 4)], NR}'
