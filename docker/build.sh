#!/usr/bin/env bash
# build.sh - `make docker`: build the tessera image from docker/Dockerfile.
#
#   GIT_ID=ID [TESSERA_IMAGE=tessera:latest] docker/build.sh [docker build options...]
#
# 1. The base images: when debian:12 / debian:12-slim are missing (no
#    registry), docker/base-image.sh makes them with debootstrap.
# 2. docker/token (or $TESSERA_TOKEN_FILE): created with 32 random bytes, hex,
#    when missing; readable by the image's user (uid 10001), never in the
#    image (.dockerignore) nor on a command line.
# 3. docker build on the default bridge network; if the build stage's apt-get
#    cannot reach the mirror from there, once more with --network host (or at
#    once with TESSERA_DOCKER_NETWORK=host).
# Prints the image's size and the build's time. Exit status 0 or 1.
set -euo pipefail
cd "$(dirname "$0")/.."
image=${TESSERA_IMAGE:-tessera:latest}
git_id=${GIT_ID:-$(git rev-parse --short=12 HEAD 2>/dev/null || echo nogit)}

docker info > /dev/null 2>&1 || { echo "error: no Docker engine answers (docker info)" >&2; exit 1; }
docker/base-image.sh

token=${TESSERA_TOKEN_FILE:-docker/token}
if [ ! -e "$token" ]; then
    ( umask 077; head -c 32 /dev/urandom | od -An -tx1 | tr -d ' \n' > "$token" )
    if [ "$(id -u)" -eq 0 ]; then
        chown 10001:0 "$token" && chmod 0440 "$token"   # the image's user reads it; root anyway
    else
        chmod 0644 "$token"
        echo "note: $token is readable by every local user (the containers' uid 10001 must read it)"
    fi
    echo "token: made $token"
fi

mkdir -p build/docker
log=build/docker/build.log
build() { # build [extra docker build options]: 0 or the status of docker build
    docker build -f docker/Dockerfile --build-arg GIT_ID="$git_id" -t "$image" "$@" . > "$log" 2>&1
}
net=()
[ "${TESSERA_DOCKER_NETWORK:-}" = host ] && net=(--network host)
start=$(date +%s.%N)
if ! build "${net[@]}" "$@"; then
    if [ ${#net[@]} -eq 0 ] && grep -qE "Temporary failure resolving|Could not connect|Failed to fetch|Unable to connect" "$log"; then
        echo "the build stage's apt-get cannot reach the mirror from the bridge network; again with --network host"
        build --network host "$@" || { tail -30 "$log" >&2; echo "error: docker build failed; log: $log" >&2; exit 1; }
    else
        tail -30 "$log" >&2; echo "error: docker build failed; log: $log" >&2; exit 1
    fi
fi
size=$(docker image inspect -f '{{.Size}}' "$image")
awk -v i="$image" -v g="$git_id" -v s="$size" -v t0="$start" -v t1="$(date +%s.%N)" -v l="$log" \
    'BEGIN { printf "image %s: build %s, %.1f MB, built in %.1f s (log: %s)\n", i, g, s / 1e6, t1 - t0, l }'
