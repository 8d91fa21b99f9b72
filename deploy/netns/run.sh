#!/usr/bin/env bash
# A multi-host DUPAC run on one machine: every process gets its own network namespace (its own
# interfaces, addresses and ports, like a separate host), and the namespaces are wired to one
# Ethernet bridge, so all traffic crosses a real (virtual) network over TCP:
#
#     namespace    address        process
#     <p>-r        10.77.0.1/24   dupac router  (listens on tcp/0.0.0.0:7447)
#     <p>-l        10.77.0.2/24   dupac learner (client of tcp/10.77.0.1:7447)
#     <p>-a1       10.77.0.3/24   dupac actor --id 1 (client)
#     <p>-a2       10.77.0.4/24   dupac actor --id 2 (client)
#     <p>-m        10.77.0.5/24   dupac monitor (client, read-only)
#     <p>-sw       -              the bridge `br0` and the host ends of the veth pairs
#
# (<p> is `dupac<pid>`, so concurrent runs do not collide; nothing is added to the machine's
# own network namespace.) It follows deploy/README.md as written, under a work directory in
# place of `/` and outside the repository: the binary is stripped and installed as
# ROOT/usr/local/bin/dupac, the Zenoh files as ROOT/etc/dupac/zenoh/*.json5; the run's config
# is made with `dupac config > run.toml` in the "hosts'" working directory (no data/ there: the
# Midtown city is the copy built into the binary), then `cache build` and `pairs`, the router,
# the learner, actor 1 and the monitor with the README's step-by-step commands, and actor 2 as
# its systemd unit starts it (deploy/systemd/actor-start.sh 2). Every process uses its role's
# Zenoh file with `--connect tcp/10.77.0.1:7447`. The config is the default one (the real
# Midtown scenario, its cache grid and radio) with a tiny training (16 PPO updates of 256
# steps, pools of 50 pairs, 8 held-out pairs); DUPAC_NETNS_CITY=procedural uses a 500 m
# procedural city instead. The script waits for the learner to finish, then checks:
#   - the install: the stripped binary, the built-in Midtown data used (Midtown only);
#   - the learner exited 0 within the timeout;
#   - metrics.jsonl has one row per update (total_timesteps / (num_envs * num_steps)) and the
#     last row is that update;
#   - both actors exited 0 and printed their summary line, acting with a final version > 0;
#   - the learner's namespace really received traffic over its veth;
#   - the router left cleanly on SIGINT;
# and prints PASS or FAIL. Namespaces and processes are removed on exit, failure included.
#
# Usage: deploy/netns/run.sh [path/to/dupac]
#   default binary: target/release/dupac of this repository, or target/debug/dupac when that
#   one is missing or newer.
# Environment:
#   DUPAC_NETNS_CITY=midtown     midtown (the default scenario) or procedural (a 500 m city:
#                                no cache build of note, for the long partition run)
#   DUPAC_NETNS_TIMEOUT=120      seconds the learner may take
#   DUPAC_NETNS_TIMESTEPS=4096   train.total_timesteps (a multiple of 256)
#   DUPAC_NETNS_DELAY_MS=0       one-way delay added with netem on every host's link (needs tc)
#   DUPAC_NETNS_RELAY=           a WAN without netem: each actor host runs `dupac relay` with
#                                this link spec (e.g. delay=50ms,jitter=20ms,rate=10mbit) between
#                                its actor (connecting to tcp/127.0.0.1:7448) and the router
#   DUPAC_NETNS_RELAY_FAULTS=none  the relays' fault schedule (e.g. stall@20s+3s,reset@40s)
#   DUPAC_NETNS_KEEP=1           keep the work directory (logs, run output) after a PASS
#   DUPAC_NETNS_PARTITION_S=0    > 0: partition actor 2 (its link down) for this many seconds
#                                once training runs, then heal it. Longer than the
#                                zenoh lease (10 s) to be a real partition. The run is then
#                                long (DUPAC_NETNS_TIMESTEPS defaults to 256 * 100000) and is
#                                stopped with SIGINT once actor 2 is back; extra checks: the
#                                learner trained on during the partition with actor 1 alone
#                                (dist/alive_actors 2 → 1), actor 2 rejoined (→ 2) and acted with
#                                versions newer than the partition; drops (stale chunks) reported
# Exit status: 0 PASS, 1 FAIL, 2 usage error, 77 skipped (not root, no `ip`, no namespaces,
# no `strip`).

set -uo pipefail

SCRIPT_DIR=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
REPO=$(cd "$SCRIPT_DIR/../.." && pwd)
ZENOH_DIR="$SCRIPT_DIR/../zenoh"

TIMEOUT=${DUPAC_NETNS_TIMEOUT:-120}
PARTITION_S=${DUPAC_NETNS_PARTITION_S:-0}
[[ "$PARTITION_S" =~ ^[0-9]+$ ]] || { echo "error: DUPAC_NETNS_PARTITION_S must be a number of seconds" >&2; exit 2; }
if [ "$PARTITION_S" -gt 0 ]; then
    TIMESTEPS=${DUPAC_NETNS_TIMESTEPS:-25600000}
else
    TIMESTEPS=${DUPAC_NETNS_TIMESTEPS:-4096}
fi
DELAY_MS=${DUPAC_NETNS_DELAY_MS:-0}
RELAY=${DUPAC_NETNS_RELAY:-}
RELAY_FAULTS=${DUPAC_NETNS_RELAY_FAULTS:-none}
CITY=${DUPAC_NETNS_CITY:-midtown}
NUM_ENVS=4
NUM_STEPS=64
SUBNET=10.77.0
ROUTER_IP=$SUBNET.1
ENDPOINT="tcp/$ROUTER_IP:7447"

log() { printf '[netns %5.1fs] %s\n' "$(elapsed)" "$*"; }
T0=$(date +%s.%N)
elapsed() { awk -v a="$T0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }'; }
skip() {
    RESULT=SKIP
    echo "SKIP: $*"
    echo "(the netns rehearsal needs root, iproute2's \`ip\` and network namespace support)"
    exit 77
}
die() {
    echo "error: $*" >&2
    exit 2
}

# ---------------------------------------------------------------- arguments and preconditions
case "${1:-}" in
    -h | --help)
        sed -n '2,/^$/p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
        exit 0
        ;;
esac
[ $# -le 1 ] || die "usage: $0 [path/to/dupac]"
if [ $# -eq 1 ]; then
    BIN=$1
else
    # target/release/dupac, unless target/debug/dupac is newer (a stale release build would
    # fail with config keys it does not know).
    BIN=$REPO/target/release/dupac
    if [ ! -x "$BIN" ] || [ "$REPO/target/debug/dupac" -nt "$BIN" ]; then
        BIN=$REPO/target/debug/dupac
    fi
fi
[ -x "$BIN" ] || die "no dupac binary at $BIN (build with \`cargo build --release\` or pass its path)"
BIN=$(cd "$(dirname "$BIN")" && pwd)/$(basename "$BIN")
for f in router learner actor monitor; do
    [ -f "$ZENOH_DIR/$f.json5" ] || die "missing $ZENOH_DIR/$f.json5"
done
if ! [[ "$TIMESTEPS" =~ ^[0-9]+$ ]] || [ "$TIMESTEPS" -eq 0 ] ||
    [ $((TIMESTEPS % (NUM_ENVS * NUM_STEPS))) -ne 0 ]; then
    die "DUPAC_NETNS_TIMESTEPS must be a positive multiple of $((NUM_ENVS * NUM_STEPS))"
fi
[[ "$TIMEOUT" =~ ^[0-9]+$ ]] || die "DUPAC_NETNS_TIMEOUT must be a number of seconds"
[[ "$DELAY_MS" =~ ^[0-9]+$ ]] || die "DUPAC_NETNS_DELAY_MS must be a number of milliseconds"
[[ "$CITY" =~ ^(midtown|procedural)$ ]] || die "DUPAC_NETNS_CITY must be midtown or procedural"

[ "$(uname -s)" = Linux ] || skip "network namespaces are Linux-only (this is $(uname -s))"
[ "$(id -u)" -eq 0 ] || skip "not root (uid $(id -u)); run with sudo"
IP=$(command -v ip || true)
[ -n "$IP" ] || for p in /usr/sbin/ip /sbin/ip /usr/bin/ip; do [ -x "$p" ] && IP=$p && break; done
[ -n "$IP" ] || skip "iproute2's \`ip\` command is not installed"
STRIP=$(command -v strip || true)
[ -n "$STRIP" ] || skip "binutils' \`strip\` (deploy/README.md's install step) is not installed"
if [ "$DELAY_MS" -gt 0 ]; then
    TC=$(command -v tc || true)
    [ -n "$TC" ] || [ ! -x /usr/sbin/tc ] || TC=/usr/sbin/tc
    [ -n "$TC" ] || skip "DUPAC_NETNS_DELAY_MS needs tc (iproute2)"
fi

# ---------------------------------------------------------------- state and cleanup
P="dupac$$"
NS_SW="$P-sw"
HOSTS=(r l a1 a2 m) # router, learner, actor 1, actor 2, monitor
CREATED_NS=()
declare -A PID    # process name -> pid
declare -A REAPED # process name -> 1 once waited for (its pid is no longer ours)
WORK=$(mktemp -d "${TMPDIR:-/tmp}/dupac-netns.XXXXXX") || die "mktemp failed"
RESULT=FAIL

alive() { [ -z "${REAPED[$1]:-}" ] && kill -0 "${PID[$1]}" 2>/dev/null; }

# shellcheck disable=SC2317 # invoked by the EXIT trap
cleanup() {
    local pid ns name running=()
    trap - EXIT INT TERM
    # Our processes not reaped yet first (TERM, then KILL after 5 s), then anything left
    # in our namespaces (only what we started can be there), then the namespaces themselves.
    for name in "${!PID[@]}"; do
        [ -n "${REAPED[$name]:-}" ] || running+=("$name")
    done
    for name in "${running[@]}"; do kill -TERM "${PID[$name]}" 2>/dev/null; done
    for _ in $(seq 50); do
        local alive=0
        for name in "${running[@]}"; do alive "$name" && alive=1; done
        [ "$alive" -eq 0 ] && break
        sleep 0.1
    done
    for name in "${running[@]}"; do
        if alive "$name"; then
            echo "$name (pid ${PID[$name]}) still running 5 s after SIGTERM: SIGKILL"
            kill -KILL "${PID[$name]}" 2>/dev/null
        fi
        wait "${PID[$name]}" 2>/dev/null
    done
    for ns in "${CREATED_NS[@]}"; do
        for pid in $("$IP" netns pids "$ns" 2>/dev/null); do kill -KILL "$pid" 2>/dev/null; done
    done
    for ns in "${CREATED_NS[@]}"; do "$IP" netns del "$ns" 2>/dev/null; done
    if [ "$RESULT" != FAIL ] && [ -z "${DUPAC_NETNS_KEEP:-}" ]; then
        rm -rf "$WORK"
    else
        echo "work directory kept: $WORK"
    fi
}
trap cleanup EXIT
trap 'echo "interrupted"; exit 130' INT TERM

# ---------------------------------------------------------------- the network
# Any failure here is the machine's (no namespace support in a container, no bridge module):
# reported as a skip with the error, before any dupac process has started.
setup_error() { skip "cannot build the namespaces: $*"; }
addns() {
    local out
    out=$("$IP" netns add "$1" 2>&1) || setup_error "ip netns add $1: $out"
    CREATED_NS+=("$1")
}
ipn() {
    local out
    out=$("$IP" "$@" 2>&1) || setup_error "ip $*: $out"
}

addns "$NS_SW"
ipn -n "$NS_SW" link add br0 type bridge
ipn -n "$NS_SW" link set br0 up
k=1
for h in "${HOSTS[@]}"; do
    ns="$P-$h"
    addns "$ns"
    # One veth pair per host: `eth0` inside the host, `v-<h>` on the bridge.
    ipn -n "$NS_SW" link add "v-$h" type veth peer name eth0 netns "$ns"
    ipn -n "$NS_SW" link set "v-$h" master br0
    ipn -n "$NS_SW" link set "v-$h" up
    ipn -n "$ns" link set lo up
    ipn -n "$ns" addr add "$SUBNET.$k/24" dev eth0
    ipn -n "$ns" link set eth0 up
    if [ "$DELAY_MS" -gt 0 ]; then
        out=$("$IP" netns exec "$ns" "$TC" qdisc add dev eth0 root netem delay "${DELAY_MS}ms" 2>&1) ||
            setup_error "tc netem on $ns: $out"
    fi
    k=$((k + 1))
done
delay=""
[ "$DELAY_MS" -eq 0 ] || delay=", netem delay $DELAY_MS ms on every link"
log "namespaces ${CREATED_NS[*]} on bridge br0 ($SUBNET.0/24)$delay"

FAILS=()
REPORT=()
check() { # check OK|FAIL message
    REPORT+=("$1  $2")
    [ "$1" = ok ] || FAILS+=("$2")
}

# ---------------------------------------------------------------- the install (deploy/README.md)
# "Install": the stripped binary and the Zenoh files, under $ROOT instead of /.
ROOT=$WORK/root
DUPAC=$ROOT/usr/local/bin/dupac
ZDIR=$ROOT/etc/dupac/zenoh
"$STRIP" --strip-debug -o "$WORK/dupac" "$BIN" || die "strip --strip-debug $BIN failed"
install -D -m 755 "$WORK/dupac" "$DUPAC" || die "install of the binary failed"
install -d "$ZDIR" && install -m 644 "$ZENOH_DIR"/*.json5 "$ZDIR/" || die "install of the zenoh files failed"
rm -f "$WORK/dupac"
mib() { awk -v b="$(stat -c %s "$1")" 'BEGIN { printf "%.0f MiB", b / 1048576 }'; }
[ "$(stat -c %s "$DUPAC")" -lt "$(stat -c %s "$BIN")" ] && s=ok || s=FAIL
check "$s" "installed the stripped binary: $(mib "$BIN") → $(mib "$DUPAC")"
log "installed $DUPAC ($(mib "$BIN") → $(mib "$DUPAC") stripped) and $ZDIR/*.json5"

# The "hosts'" working directory, outside the repository: relative paths of the config
# (cache.path, pairs.eval_file, the learner's --out) land here; it has no data/ folder.
SITE=$WORK/site
mkdir -p "$SITE" && cd "$SITE" || die "cannot make $SITE"

# `dupac config > run.toml`: the default config, with the rehearsal's edits given as --set
# (the README's "edit it"): a tiny training, this run's name.
SETS=(
    --set "distributed.run=netns-$$" --set distributed.actor_envs=2 --set distributed.chunk_steps=32
    --set "train.num_envs=$NUM_ENVS" --set "train.num_steps=$NUM_STEPS" --set "train.total_timesteps=$TIMESTEPS"
    --set train.pool_size=50 --set train.checkpoint_every=2 --set train.eval_every=5 --set train.eval_pairs=8
    --set ppo.num_minibatches=2 --set 'ppo.hidden=[32, 32]' --set pairs.eval_per_bin=4
)
if [ "$CITY" = midtown ]; then
    SETS+=(--set 'pairs.eval_bins_m=[200, 300]')
else
    SETS+=(
        --set scenario.city=procedural --set scenario.n_sites=8 --set scenario.procedural.size_m=500
        --set scenario.procedural.n_sites=8 --set cache.horizontal_m=10 --set cache.vertical_m=10
        --set pairs.min_m=40 --set pairs.max_m=70 --set 'pairs.eval_bins_m=[50, 60]' --set pairs.bin_tolerance=0.1
    )
fi
CONFIG=run.toml
OUT=$SITE/runs/r1
"$DUPAC" "${SETS[@]}" config >"$CONFIG" 2>"$WORK/prepare.log" || {
    echo "FAIL: dupac config > run.toml:"
    cat "$WORK/prepare.log"
    exit 1
}
UPDATES=$((TIMESTEPS / (NUM_ENVS * NUM_STEPS)))

# Step 2 (learner host) and step 3 (actor hosts; here the same working directory, so the
# cache is only checked): the RSRP cache and the held-out pairs once, before the processes.
T_PREP=$(date +%s.%N)
if ! "$DUPAC" --config "$CONFIG" -v cache build >>"$WORK/prepare.log" 2>&1 ||
    ! "$DUPAC" --config "$CONFIG" -q pairs >>"$WORK/prepare.log" 2>&1 ||
    ! "$DUPAC" --config "$CONFIG" -q cache build >>"$WORK/prepare.log" 2>&1; then
    echo "FAIL: preparing the RSRP cache / held-out pairs:"
    cat "$WORK/prepare.log"
    exit 1
fi
PREP_S=$(awk -v a="$T_PREP" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }')
if [ "$CITY" = midtown ]; then
    grep -q '^city = "osm"' "$CONFIG" && s=ok || s=FAIL
    check "$s" "run.toml from \`dupac config\`: the default (Midtown OSM) scenario"
    grep -q 'data/nyc_midtown_buildings.geojson in .*: using the copy built into this binary' "$WORK/prepare.log" &&
        grep -q 'data/nyc_midtown_cells.csv in .*: using the copy built into this binary' "$WORK/prepare.log" &&
        [ ! -e "$SITE/data" ] && s=ok || s=FAIL
    check "$s" "no data/ in $SITE: the Midtown buildings and cells built into the binary were used"
fi
cache=$(grep -o 'built [^ ]*: .*' "$WORK/prepare.log" | head -n 1)
log "$CITY: $CONFIG from \`dupac config\` ($UPDATES updates); cache and pairs in ${PREP_S} s${cache:+ ($cache)}"

# ---------------------------------------------------------------- the processes
# start NAME HOST ARGS...: runs dupac in namespace <p>-HOST, output in $WORK/NAME.log.
start() {
    local name=$1 host=$2
    shift 2
    "$IP" netns exec "$P-$host" "$DUPAC" "$@" >"$WORK/$name.log" 2>&1 </dev/null &
    PID[$name]=$!
}
# wait_exit NAME SECONDS: waits for NAME to exit; sets RC (124 if still running).
wait_exit() {
    local name=$1 deadline
    deadline=$(($(date +%s%N) / 1000000 + $2 * 1000))
    while alive "$name" && [ $(($(date +%s%N) / 1000000)) -lt "$deadline" ]; do sleep 0.1; done
    if alive "$name"; then
        RC=124
    else
        wait "${PID[$name]}"
        RC=$?
        REAPED[$name]=1
    fi
}

NET=(--connect "$ENDPOINT" --no-multicast-scouting)
start router r router --zenoh-config "$ZDIR/router.json5" --no-multicast-scouting
# The router is up when the learner's namespace can open a TCP connection to it.
up=0
for _ in $(seq 100); do
    alive router || break
    if "$IP" netns exec "$P-l" bash -c "exec 3<>/dev/tcp/$ROUTER_IP/7447" 2>/dev/null; then
        up=1
        break
    fi
    sleep 0.1
done
if [ $up -eq 0 ]; then
    echo "FAIL: the router is not reachable at $ENDPOINT from the learner's namespace"
    echo "--- router.log"
    tail -n 30 "$WORK/router.log"
    exit 1
fi
log "router up at $ENDPOINT (reached from $P-l)"

# Without --duration-s the monitor leaves when the learner's stats say the run is done.
start monitor m --config "$CONFIG" -q monitor --plain --jsonl "$WORK/monitor.jsonl" \
    --zenoh-config "$ZDIR/monitor.json5" "${NET[@]}"
T_LEARNER=$(date +%s.%N)
start learner l --config "$CONFIG" -q learner --out runs/r1 \
    --zenoh-config "$ZDIR/learner.json5" "${NET[@]}"
# The actors' way to the router: straight, or through a relay on their own host.
ACTOR_EP=$ENDPOINT
if [ -n "$RELAY" ]; then
    for a in 1 2; do
        start "relay$a" "a$a" -q relay --listen 127.0.0.1:7448 --upstream "$ROUTER_IP:7447" \
            --link "$RELAY" --faults "$RELAY_FAULTS" --report-every-s 0
    done
    ACTOR_EP=tcp/127.0.0.1:7448
    sleep 0.5
    log "actors through dupac relay ($RELAY; faults: $RELAY_FAULTS)"
fi
start actor1 a1 --config "$CONFIG" -q actor --id 1 \
    --zenoh-config "$ZDIR/actor.json5" --connect "$ACTOR_EP" --no-multicast-scouting
# Actor 2 as dupac-actor@2.service runs it: actor-start.sh with dupac.env's variables.
"$IP" netns exec "$P-a2" env DUPAC_CONFIG="$CONFIG" DUPAC_ZENOH_DIR="$ZDIR" DUPAC_ROUTER="$ACTOR_EP" \
    DUPAC_BIN="$DUPAC" DUPAC_ACTOR_ARGS= \
    sh "$SCRIPT_DIR/../systemd/actor-start.sh" 2 >"$WORK/actor2.log" 2>&1 </dev/null &
PID[actor2]=$!
log "learner, actor 1 (step by step), actor 2 (actor-start.sh) and a monitor started; waiting up to ${TIMEOUT} s for the learner"

# ---------------------------------------------------------------- checks

# rows_now: update rows in the learner's metrics so far.
rows_now() {
    local n
    n=$(grep -c '"update":' "$OUT/metrics.jsonl" 2>/dev/null)
    echo "${n:-0}"
}
# alive_seq: dist/alive_actors of every row, one per line.
alive_seq() { grep -o '"dist/alive_actors":[0-9]*' "$OUT/metrics.jsonl" 2>/dev/null | cut -d: -f2; }

if [ "$PARTITION_S" -gt 0 ]; then
    # ------------------------------------------------------------ the partition
    # Up to 30 s for 20 updates (120 s through a relay: at 10 Mbit/s ≈ 1 update/s).
    WAIT_DS=300; [ -n "$RELAY" ] && WAIT_DS=1200
    for _ in $(seq "$WAIT_DS"); do [ "$(rows_now)" -ge 20 ] && break; sleep 0.1; done
    before=$(rows_now)
    [ "$before" -ge 20 ] && s=ok || s=FAIL
    check "$s" "training before the partition: $before updates"
    log "partition: actor 2's link down for ${PARTITION_S} s (at update $before)"
    ipn -n "$P-a2" link set eth0 down
    sleep "$PARTITION_S"
    during=$(rows_now)
    ipn -n "$P-a2" link set eth0 up
    log "partition healed at update $during"
    [ "$during" -gt "$before" ] && s=ok || s=FAIL
    check "$s" "the learner trained on during the partition: updates $before → $during"
    # Back: rows with both actors alive again after rows with one.
    healed=0
    for _ in $(seq 600); do
        if alive_seq | awk 'BEGIN{st=0} $1==2 && st==0 {st=1} $1==1 && st==1 {st=2} $1==2 && st==2 {st=3} END{exit st==3 ? 0 : 1}'; then
            healed=1
            break
        fi
        sleep 0.1
    done
    [ $healed -eq 1 ] && s=ok || s=FAIL
    check "$s" "dist/alive_actors went 2 → 1 (partition seen after the lease) → 2 (actor 2 rejoined)"
    # Let the rejoined actor deliver, then stop the run as an operator would.
    sleep 3
    PARTITION_END=$during
    kill -INT "${PID[learner]}" 2>/dev/null
fi


wait_exit learner "$TIMEOUT"
LEARNER_RC=$RC
LEARNER_S=$(awk -v a="$T_LEARNER" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }')
ACTOR_WAIT=30
if [ "$LEARNER_RC" -eq 124 ]; then
    check FAIL "learner still running after ${TIMEOUT} s"
    # Stop it the way an operator would (SIGINT: checkpoint, exit) so that the checks below
    # see what it wrote; actors wait for a learner that sent no Stop, so do not wait long.
    log "learner timed out after ${LEARNER_S} s; sending it SIGINT"
    kill -INT "${PID[learner]}" 2>/dev/null
    wait_exit learner 15
    ACTOR_WAIT=2
else
    [ "$LEARNER_RC" -eq 0 ] && s=ok || s=FAIL
    check "$s" "learner exited with $LEARNER_RC after ${LEARNER_S} s"
    log "learner done (exit $LEARNER_RC, ${LEARNER_S} s)"
fi

rows=0
last=none
if [ -f "$OUT/metrics.jsonl" ]; then
    rows=$(grep -c '"update":' "$OUT/metrics.jsonl")
    last=$(tail -n 1 "$OUT/metrics.jsonl" | grep -o '"update":[0-9.]*' | cut -d: -f2)
    last=${last%.0}
fi
if [ "$PARTITION_S" -gt 0 ]; then
    [ "$rows" -gt 0 ] && [ "$last" = "$rows" ] && s=ok || s=FAIL
    check "$s" "metrics.jsonl: $rows update rows, last update $last (no gaps)"
    drops=$(tail -n 1 "$OUT/metrics.jsonl" | grep -o '"dist/dropped_[a-z_]*":[0-9.]*' | tr '\n' ' ')
    REPORT+=("info  drops counted by the learner: ${drops:-none}")
else
    [ "$rows" -eq "$UPDATES" ] && [ "$last" = "$UPDATES" ] && s=ok || s=FAIL
    check "$s" "metrics.jsonl: $rows update rows (expected $UPDATES), last update $last"
fi
for f in checkpoint.bin policy.bin metrics.csv config.toml; do
    [ -s "$OUT/$f" ] && s=ok || s=FAIL
    check "$s" "learner wrote $f"
done

for a in 1 2; do
    [ "$PARTITION_S" -gt 0 ] && kill -INT "${PID[actor$a]}" 2>/dev/null
    wait_exit "actor$a" $ACTOR_WAIT
    line=$(grep -E "^actor $a: " "$WORK/actor$a.log" | tail -n 1)
    ver=$(sed -nE 's/.*acted with versions [0-9]+\.\.=([0-9]+).*/\1/p' <<<"$line")
    [ "$RC" -eq 0 ] && s=ok || s=FAIL
    check "$s" "actor $a exited with $RC$([ "$RC" -eq 124 ] && echo " (still running $ACTOR_WAIT s after the learner)")"
    [ -n "$ver" ] && [ "$ver" -gt 0 ] && s=ok || s=FAIL
    check "$s" "actor $a summary: ${line:-<none>}"
    if [ "$PARTITION_S" -gt 0 ] && [ "$a" -eq 2 ]; then
        [ -n "$ver" ] && [ "$ver" -gt "$PARTITION_END" ] && s=ok || s=FAIL
        check "$s" "actor 2 acted after the partition: last version ${ver:-?} > $PARTITION_END"
    fi
done

grep -qF "actor-start: actor 2 with $ZDIR/actor.json5" "$WORK/actor2.log" && s=ok || s=FAIL
check "$s" "actor 2 started by its unit's actor-start.sh, with the shared actor.json5"

rx=$("$IP" netns exec "$P-l" cat /sys/class/net/eth0/statistics/rx_bytes 2>/dev/null || echo 0)
tx=$("$IP" netns exec "$P-l" cat /sys/class/net/eth0/statistics/tx_bytes 2>/dev/null || echo 0)
[ "$rx" -gt 0 ] && [ "$tx" -gt 0 ] && s=ok || s=FAIL
check "$s" "learner's eth0 carried $((rx / 1024)) KiB in, $((tx / 1024)) KiB out"

# The monitor ends with the run; how many stats it saw depends on timing: informative only
# (it is killed at cleanup if it missed the learner's last stats).
[ "$PARTITION_S" -gt 0 ] && kill -INT "${PID[monitor]}" 2>/dev/null
wait_exit monitor $((ACTOR_WAIT < 10 ? ACTOR_WAIT : 10))
mon=0
[ -f "$WORK/monitor.jsonl" ] && mon=$(wc -l <"$WORK/monitor.jsonl")
REPORT+=("info  monitor received $mon stats messages (exit $RC)")

kill -INT "${PID[router]}" 2>/dev/null
wait_exit router 10
[ "$RC" -eq 0 ] && s=ok || s=FAIL
check "$s" "router exited with $RC on SIGINT"

# ---------------------------------------------------------------- summary
echo
echo "== DUPAC netns rehearsal: router, learner, 2 actors, monitor in separate namespaces =="
for r in "${REPORT[@]}"; do echo "  $r"; done
if [ ${#FAILS[@]} -eq 0 ]; then
    RESULT=PASS
    echo "PASS ($(elapsed) s in all)"
    exit 0
fi
echo "FAIL: ${#FAILS[@]} check(s) failed"
for name in router learner actor1 actor2 monitor; do
    echo "--- tail of $WORK/$name.log"
    tail -n 25 "$WORK/$name.log" 2>/dev/null
done
exit 1
