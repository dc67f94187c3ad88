#!/bin/sh
# healthcheck.sh - the image's HEALTHCHECK (installed as tessera-healthcheck).
# Looks at what runs as PID 1:
#   tessera-worker       healthy while it holds an established TCP connection
#                        (to its coordinator; a worker dials out, never listens)
#   tessera-coordinator  healthy while it answers `tessera status` on the port
#                        its --listen names, with its own --token-file
# Exit status 0 healthy, 1 not (with one line saying why).
set -u
args=$(tr '\0' '\n' < /proc/1/cmdline)
prog=$(echo "$args" | head -1)
# opt NAME: the value after --NAME (or of --NAME=VALUE) on PID 1's command line.
opt() { echo "$args" | awk -v o="--$1" '$0 == o { getline; print; exit } index($0, o "=") == 1 { print substr($0, length(o) + 2); exit }'; }
case "${prog##*/}" in
tessera-worker)
    # /proc/net/tcp{,6}: column 4 is the state, 01 = ESTABLISHED.
    if cat /proc/net/tcp /proc/net/tcp6 2>/dev/null | awk 'NR > 1 && $4 == "01" { found = 1 } END { exit !found }'; then
        exit 0
    fi
    echo "worker not connected to a coordinator"; exit 1 ;;
tessera-coordinator|tessera)
    listen=$(opt listen); listen=${listen:-127.0.0.1:7000}
    port=${listen##*:}
    token=$(opt token-file)
    if [ -n "$token" ]; then
        out=$(tessera status --coordinator "127.0.0.1:$port" --token-file "$token" 2>&1)
    else
        out=$(env -u TESSERA_TOKEN_FILE tessera status --coordinator "127.0.0.1:$port" 2>&1)
    fi && exit 0
    echo "coordinator does not answer on port $port: $out" | head -c 300; exit 1 ;;
*)
    exit 0 ;; # something else (a shell, --help): nothing to check
esac
