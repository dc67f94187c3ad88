#!/bin/sh
# runtime-packages.sh - print the Debian packages that hold the shared
# libraries the given programs link (ldd, then dpkg -S), one per line, sorted.
# docker/Dockerfile installs exactly these in its runtime stage, so a new
# library in the Makefile's LDLIBS (say libembree3) needs no edit here.
#
#   docker/runtime-packages.sh build/release/bin/tessera build/release/bin/tessera-worker
#
# Exit status 1, naming the library, when a program misses a library or a
# library belongs to no package.
set -eu
[ $# -ge 1 ] || { echo "usage: $0 PROGRAM..." >&2; exit 2; }
libs=$(for p in "$@"; do
    out=$(ldd "$p") || { echo "error: ldd $p failed" >&2; exit 1; }
    if echo "$out" | grep -q "not found"; then
        echo "error: $p: $(echo "$out" | grep "not found" | head -1)" >&2; exit 1
    fi
    echo "$out" | awk '$2 == "=>" && $3 ~ /^\// { print $3 }'
done | sort -u)
for lib in $libs; do
    # dpkg knows a file by the path its package ships, which may differ from
    # ldd's by the /lib -> /usr/lib merge or a symbolic link: try each.
    pkg=$(dpkg -S "$lib" 2>/dev/null || dpkg -S "$(readlink -f "$lib")" 2>/dev/null ||
          dpkg -S "*/${lib##*/}" 2>/dev/null) || { echo "error: $lib: in no Debian package" >&2; exit 1; }
    echo "$pkg" | head -1 | cut -d: -f1
done | sort -u
