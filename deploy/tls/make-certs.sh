#!/usr/bin/env bash
# Makes a private certificate authority and the certificates of one DUPAC run, plus ready-to-use
# Zenoh configs with mutual TLS and access control (docs/reliability.md).
#
#   deploy/tls/make-certs.sh OUT_DIR [--router-host NAME_OR_IP]... [--actors N] [--days N]
#                            [--certs-dir DIR]
#
# OUT_DIR receives:
#   ca.pem, ca.key                   the run's private CA (keep ca.key off the run's hosts)
#   router.pem, router.key           CN dupac-router; subjectAltName: localhost, 127.0.0.1 and
#                                    every --router-host (the names actors use in tls/HOST:7447)
#   learner.pem/.key                 CN dupac-learner  (may publish weights, stats, Stop)
#   actor-<i>.pem/.key, i < N        CN dupac-actor-<i> (may publish its own trajectories, stats and
#                                    liveliness token only: `dupac actor --id <i>`; --actors 2)
#   monitor.pem/.key                 CN dupac-monitor  (reads stats, weights, ctrl, liveliness:
#                                    monitors and pilots)
#   router.json5, learner.json5,     deploy/zenoh/secure/*.json5 with the files' directory on
#   actor-<i>.json5, monitor.json5   the run's hosts (--certs-dir, e.g. /etc/dupac/tls; default
#                                    OUT_DIR's absolute path) and the first --router-host filled
#                                    in; the router's access control has one rule set per actor id
#
# Keys are ECDSA P-256 (PKCS#8 PEM), certificates X.509 v3 signed by the CA, valid --days (365).
# Copy to each host only what its role needs: ca.pem + that role's .pem/.key + its .json5.
# Needs openssl ≥ 1.1.1.
set -euo pipefail

usage() { sed -n '2,22p' "$0" | sed 's/^# \{0,1\}//'; exit 2; }
[ $# -ge 1 ] || usage
OUT=$1; shift
HOSTS=()
DAYS=365
ACTORS=2
CERTS_DIR=
while [ $# -gt 0 ]; do
  case $1 in
    --router-host) HOSTS+=("$2"); shift 2 ;;
    --days) DAYS=$2; shift 2 ;;
    --actors) ACTORS=$2; shift 2 ;;
    --certs-dir) CERTS_DIR=$2; shift 2 ;;
    -h|--help) usage ;;
    *) echo "make-certs.sh: unknown argument '$1'" >&2; usage ;;
  esac
done
[[ $ACTORS =~ ^[0-9]+$ && $ACTORS -ge 1 && $ACTORS -le 4096 ]] \
  || { echo "make-certs.sh: --actors must be in 1..=4096, not '$ACTORS'" >&2; exit 2; }
command -v openssl >/dev/null || { echo "make-certs.sh: openssl not found" >&2; exit 1; }
HERE=$(cd "$(dirname "$0")" && pwd)
TEMPLATES="$HERE/../zenoh/secure"
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
CERTS_DIR=${CERTS_DIR:-$OUT}
[[ $CERTS_DIR == /* && $CERTS_DIR != *'|'* ]] \
  || { echo "make-certs.sh: --certs-dir must be an absolute path, not '$CERTS_DIR'" >&2; exit 2; }
umask 077

key() { openssl genpkey -algorithm EC -pkeyopt ec_paramgen_curve:P-256 -out "$1" 2>/dev/null; }

key "$OUT/ca.key"
openssl req -x509 -new -key "$OUT/ca.key" -sha256 -days "$DAYS" -subj "/CN=dupac-run-ca" \
  -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign" \
  -out "$OUT/ca.pem"

# leaf NAME CN EXT_USAGE [SAN]
leaf() {
  local name=$1 cn=$2 usage=$3 san=${4:-}
  key "$OUT/$name.key"
  openssl req -new -key "$OUT/$name.key" -subj "/CN=$cn" -out "$OUT/$name.csr"
  {
    echo "basicConstraints=critical,CA:FALSE"
    echo "keyUsage=critical,digitalSignature,keyEncipherment"
    echo "extendedKeyUsage=$usage"
    [ -n "$san" ] && echo "subjectAltName=$san"
  } >"$OUT/$name.ext"
  openssl x509 -req -in "$OUT/$name.csr" -CA "$OUT/ca.pem" -CAkey "$OUT/ca.key" \
    -CAcreateserial -days "$DAYS" -sha256 -extfile "$OUT/$name.ext" -out "$OUT/$name.pem" 2>/dev/null
  rm -f "$OUT/$name.csr" "$OUT/$name.ext"
}

SAN="DNS:localhost,IP:127.0.0.1"
for h in "${HOSTS[@]+"${HOSTS[@]}"}"; do
  if [[ $h =~ ^[0-9.]+$ || $h == *:* ]]; then SAN="$SAN,IP:$h"; else SAN="$SAN,DNS:$h"; fi
done
# The router is a server to every process and a client of none; the others are clients.
leaf router dupac-router serverAuth,clientAuth "$SAN"
leaf learner dupac-learner clientAuth
for ((i = 0; i < ACTORS; i++)); do leaf "actor-$i" "dupac-actor-$i" clientAuth; done
leaf monitor dupac-monitor clientAuth
rm -f "$OUT/ca.srl"

ROUTER_HOST=${HOSTS[0]:-localhost}
fill() { sed -e "s|CERTS_DIR|$CERTS_DIR|g" -e "s|ROUTER_HOST|$ROUTER_HOST|g" "$@"; }
for role in learner monitor; do fill "$TEMPLATES/$role.json5" >"$OUT/$role.json5"; done
for ((i = 0; i < ACTORS; i++)); do
  fill -e "s|/actor\.pem|/actor-$i.pem|g" -e "s|/actor\.key|/actor-$i.key|g" \
    "$TEMPLATES/actor.json5" >"$OUT/actor-$i.json5"
done
# The router: one rule set per actor id, bound to that id's certificate.
RULES=$(mktemp); SUBJECTS=$(mktemp); POLICIES=$(mktemp)
for ((i = 0; i < ACTORS; i++)); do
  cat >>"$RULES" <<EOF
      {
        id: "actor-$i-publishes",
        permission: "allow",
        flows: ["ingress"],
        messages: ["put"],
        key_exprs: ["dupac/*/traj/$i", "dupac/*/stats/actor/$i"],
      },
      {
        id: "actor-$i-alive",
        permission: "allow",
        flows: ["ingress"],
        messages: ["liveliness_token"],
        key_exprs: ["dupac/*/alive/actor/$i"],
      },
EOF
  echo "      { id: \"actor-$i\", cert_common_names: [\"dupac-actor-$i\"] }," >>"$SUBJECTS"
  echo "      { rules: [\"presence\", \"actor-receive\", \"actor-observe\", \"liveliness-observe\", \"actor-$i-publishes\", \"actor-$i-alive\"], subjects: [\"actor-$i\"] }," >>"$POLICIES"
done
fill -e "/ACTOR_RULES/r $RULES" -e "/ACTOR_SUBJECTS/r $SUBJECTS" -e "/ACTOR_POLICIES/r $POLICIES" \
  "$TEMPLATES/router.json5" >"$OUT/router.json5"
rm -f "$RULES" "$SUBJECTS" "$POLICIES"
chmod 644 "$OUT"/*.pem "$OUT"/*.json5
echo "certificates and configs of the run in $OUT, naming $CERTS_DIR (router reachable as: localhost 127.0.0.1 ${HOSTS[*]+"${HOSTS[*]}"})"
