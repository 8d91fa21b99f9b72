#!/bin/sh
# ExecStart of dupac-actor@.service: starts `dupac actor --id ID` with the actor's own Zenoh
# config when there is one. `exec` makes dupac the service's main process, so systemd's SIGINT
# reaches it directly.
#
# Usage: actor-start.sh ID   (the unit passes its instance, %i)
#
# The Zenoh config is DUPAC_ZENOH_DIR/actor-ID.json5 when that file exists (a secured run:
# deploy/tls/make-certs.sh writes one per actor id, naming that actor's certificate), else
# DUPAC_ZENOH_DIR/actor.json5 (plain TCP: one file for every actor). A secured router refuses
# any actor without its certificate, so a missing per-actor file cannot downgrade a secured
# run: the actor fails to connect and says so in the journal.
#
# Reads (from /etc/dupac/dupac.env through EnvironmentFile=, or from the caller's
# environment when run by hand):
#   DUPAC_CONFIG      the run's DUPAC TOML config                      (required)
#   DUPAC_ROUTER      router endpoint, e.g. tcp/10.0.0.1:7447           (optional: else the
#                     connect endpoints of the Zenoh config are used)
#   DUPAC_ZENOH_DIR   folder of the Zenoh configs (default /etc/dupac/zenoh)
#   DUPAC_BIN         the dupac binary (default /usr/local/bin/dupac; for a run by hand:
#                     the units' ExecStartPre builds the cache with /usr/local/bin/dupac)
#   DUPAC_ACTOR_ARGS  extra arguments, split at spaces (e.g. `--threads 8`)
set -eu

[ $# -eq 1 ] || { echo "usage: $0 ACTOR_ID" >&2; exit 2; }
id=$1
: "${DUPAC_CONFIG:?set DUPAC_CONFIG to the TOML config of the run, e.g. in /etc/dupac/dupac.env}"
bin=${DUPAC_BIN:-/usr/local/bin/dupac}
dir=${DUPAC_ZENOH_DIR:-/etc/dupac/zenoh}

zenoh=$dir/actor-$id.json5
[ -f "$zenoh" ] || zenoh=$dir/actor.json5
if [ ! -f "$zenoh" ]; then
    echo "actor-start: neither $dir/actor-$id.json5 nor $dir/actor.json5 exists" >&2
    exit 1
fi
echo "actor-start: actor $id with $zenoh"

set -- --config "$DUPAC_CONFIG" --quiet actor --id "$id" --zenoh-config "$zenoh"
if [ -n "${DUPAC_ROUTER:-}" ]; then
    set -- "$@" --connect "$DUPAC_ROUTER"
fi
# Word splitting of the extra arguments is intended.
# shellcheck disable=SC2086
exec "$bin" "$@" ${DUPAC_ACTOR_ARGS:-}
