#!/bin/sh
# ExecStart of dupac-learner.service: starts `dupac learner`, adding `--resume` when the run's
# output directory already holds a checkpoint (after a crash, a reboot or `systemctl stop`,
# which sends SIGINT: the learner writes its checkpoint and exits 0). `exec` makes dupac the
# service's main process, so systemd's SIGINT reaches it directly.
#
# Reads (from /etc/dupac/dupac.env through EnvironmentFile=, or from the caller's
# environment when run by hand):
#   DUPAC_CONFIG      the run's DUPAC TOML config                      (required)
#   DUPAC_OUT         the run's output directory                        (required)
#   DUPAC_ROUTER      router endpoint, e.g. tcp/10.0.0.1:7447           (optional: else the
#                     connect endpoints of learner.json5 are used)
#   DUPAC_ZENOH_DIR   folder of learner.json5 (default /etc/dupac/zenoh)
#   DUPAC_BIN         the dupac binary (default /usr/local/bin/dupac)
#   DUPAC_LEARNER_ARGS extra arguments, split at spaces (e.g. `--device cuda`)
set -eu

: "${DUPAC_CONFIG:?set DUPAC_CONFIG to the TOML config of the run, e.g. in /etc/dupac/dupac.env}"
: "${DUPAC_OUT:?set DUPAC_OUT to the output directory of the run, e.g. in /etc/dupac/dupac.env}"
bin=${DUPAC_BIN:-/usr/local/bin/dupac}
zenoh=${DUPAC_ZENOH_DIR:-/etc/dupac/zenoh}/learner.json5

set -- --config "$DUPAC_CONFIG" --quiet learner --out "$DUPAC_OUT" --zenoh-config "$zenoh"
if [ -n "${DUPAC_ROUTER:-}" ]; then
    set -- "$@" --connect "$DUPAC_ROUTER"
fi
if [ -f "$DUPAC_OUT/checkpoint.bin" ]; then
    echo "learner-start: resuming from $DUPAC_OUT/checkpoint.bin"
    set -- "$@" --resume
else
    echo "learner-start: new run in $DUPAC_OUT"
fi
# Word splitting of the extra arguments is intended.
# shellcheck disable=SC2086
exec "$bin" "$@" ${DUPAC_LEARNER_ARGS:-}
