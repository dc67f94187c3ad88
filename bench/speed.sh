#!/usr/bin/env bash
# speed.sh - per-core speed of Tessera builds, same bytes required: each
# variant renders each scene in one process on one thread (--workers 0
# --threads 1), the variants interleaved round after round; prints every
# run's CPU seconds (user + sys, less sensitive than wall time to a busy
# machine) with the 1-minute load average, then per scene and variant the
# median, and checks that every variant wrote the same image bytes.
#
# usage: bench/speed.sh ROUNDS SIZE SPP "NAME=TESSERA[:ENV=VALUE] ..." SCENE...
#   e.g. bench/speed.sh 5 256 16 "main=/tmp/main/tessera branch=build/release/bin/tessera \
#        branch-avx2=build/release/bin/tessera:TESSERA_NO_AVX512=1" scenes/cornell-box.json
set -euo pipefail
rounds=$1 size=$2 spp=$3 variants=$4
shift 4
tmp=$(mktemp -d /tmp/tessera-speed.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
for i in $(seq 1 "$rounds"); do
  for scene in "$@"; do
    name=$(basename "$scene" .json)
    for v in $variants; do
      label=${v%%=*} rest=${v#*=}
      bin=${rest%%:*} env=X_TESSERA_SPEED=1
      [ "$rest" != "$bin" ] && env=${rest#*:}
      env "$env" /usr/bin/time -o "$tmp/time" -f "%U %S" "$bin" render "$scene" --workers 0 --threads 1 \
        --width "$size" --height "$size" --spp "$spp" --no-progress -o "$tmp/$name-$label.pfm" > /dev/null 2>&1
      echo "$i $name $label $(awk '{print $1 + $2}' "$tmp/time") load $(cut -d' ' -f1 /proc/loadavg)"
    done
  done
done | tee "$tmp/runs"
echo "median CPU s over $rounds rounds ($size x $size, $spp spp, one thread):"
for scene in "$@"; do
  name=$(basename "$scene" .json)
  first=
  for v in $variants; do
    label=${v%%=*}
    med=$(awk -v n="$name" -v l="$label" '$2 == n && $3 == l {print $4}' "$tmp/runs" | sort -g |
          awk '{a[NR] = $1} END {print NR % 2 ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2}')
    same=""
    if [ -z "$first" ]; then first=$label
    elif cmp -s "$tmp/$name-$first.pfm" "$tmp/$name-$label.pfm"; then same="(same bytes as $first)"
    else same="(IMAGE DIFFERS from $first)"; fi
    echo "  $name $label $med $same"
  done
done
