#!/usr/bin/env bash
# base-image.sh - make the Debian 12 base images docker/Dockerfile names
# (debian:12 and debian:12-slim) when the engine has neither and no registry
# can be reached: debootstrap a minimal bookworm into build/docker/rootfs from
# the Debian mirror this host's own apt uses, and `docker import` it.
#
#   docker/base-image.sh            # does nothing when both tags exist
#   TESSERA_DEBIAN_MIRROR=URL docker/base-image.sh   # another mirror
#
# The mirror is read at run time from /etc/apt/sources.list.d/*.sources
# (deb822 "URIs:") or /etc/apt/sources.list, so no host name is written into
# the repository. Where debian:12 can be pulled, pull it instead
# (`docker pull debian:12 && docker pull debian:12-slim`): this script then
# leaves the pulled images alone. Needs root (debootstrap) and ~300 MB.
# Exit status: 0 when both tags exist afterwards, 1 on any failure.
set -euo pipefail
cd "$(dirname "$0")/.."

have() { docker image inspect "$1" > /dev/null 2>&1; }

# host_mirror: print the first Debian archive URI of the host's apt sources
# (not the security archive), or nothing.
host_mirror() {
    local f uri
    for f in /etc/apt/sources.list.d/*.sources; do
        [ -r "$f" ] || continue
        # deb822: stanzas separated by blank lines; take URIs of "Types: deb" stanzas.
        uri=$(awk 'BEGIN { RS = ""; FS = "\n" }
                   { deb = 0; u = "";
                     for (i = 1; i <= NF; i++) {
                       if ($i ~ /^Types:/ && $i ~ /(^|[ \t])deb([ \t]|$)/) deb = 1;
                       if ($i ~ /^URIs:/) { split($i, a, /[ \t]+/); u = a[2] }
                     }
                     if (deb && u != "" && u !~ /security/) { print u; exit } }' "$f")
        [ -n "$uri" ] && { echo "$uri"; return; }
    done
    if [ -r /etc/apt/sources.list ]; then
        # deb [options] URI suite components...
        awk '$1 == "deb" { i = 2; if ($2 ~ /^\[/) { while ($i !~ /\]$/) i++; i++ }
                           if ($i !~ /security/) { print $i; exit } }' /etc/apt/sources.list
    fi
}

if have debian:12 && have debian:12-slim; then
    echo "base images: debian:12 and debian:12-slim present"
    exit 0
fi
if have debian:12; then
    docker tag debian:12 debian:12-slim
    echo "base images: tagged debian:12 as debian:12-slim"
    exit 0
fi

mirror=${TESSERA_DEBIAN_MIRROR:-$(host_mirror)}
if [ -z "$mirror" ]; then
    echo "error: no Debian mirror in /etc/apt/sources.list.d/*.sources or /etc/apt/sources.list;" \
         "set TESSERA_DEBIAN_MIRROR=URL" >&2
    exit 1
fi
command -v debootstrap > /dev/null || {
    echo "installing debootstrap"
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq -o DPkg::Lock::Timeout=900 debootstrap
}
if [ "$(id -u)" -ne 0 ]; then
    echo "error: debootstrap needs root to make the base image (or: docker pull debian:12)" >&2
    exit 1
fi

rootfs=build/docker/rootfs
rm -rf "$rootfs"
mkdir -p "$rootfs"
echo "base images: debootstrap --variant=minbase bookworm from $mirror (a minute or two)"
start=$(date +%s)
if ! debootstrap --variant=minbase bookworm "$rootfs" "$mirror" > build/docker/debootstrap.log 2>&1; then
    tail -20 build/docker/debootstrap.log >&2
    echo "error: debootstrap failed; the whole log: build/docker/debootstrap.log" >&2
    exit 1
fi
# Nothing the image needs: package caches and lists (the Dockerfile runs
# apt-get update itself), logs.
rm -rf "$rootfs"/var/cache/apt/archives/*.deb "$rootfs"/var/lib/apt/lists/* "$rootfs"/var/log/*.log
tar --numeric-owner -C "$rootfs" -c . |
    docker import --change 'CMD ["bash"]' \
        --change 'LABEL org.opencontainers.image.description="debian bookworm minbase, made by tessera docker/base-image.sh"' \
        - debian:12 > /dev/null
docker tag debian:12 debian:12-slim
rm -rf "$rootfs"
echo "base images: debian:12 and debian:12-slim imported ($(docker image inspect -f '{{.Size}}' debian:12 | awk '{printf "%.0f MB", $1/1e6}'), $(( $(date +%s) - start )) s)"
