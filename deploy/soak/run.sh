#!/usr/bin/env bash
# Soak test of the distributed system (docs/reliability.md): a learner and N actors on
# this machine (loopback TCP) train a fixed budget while actors are killed with SIGKILL and
# restarted at random, and the learner is killed with SIGKILL in the middle and restarted with
# --resume. Then the same budget again without faults, as the baseline. Reports:
#   - memory (VmRSS) of every process over time, sampled every second (memory.csv), and
#     whether any process grew: mean RSS over its last quarter > 1.25 × the mean over its
#     second quarter + 16 MiB (processes alive ≥ 20 samples);
#   - updates completed (the learning curve has one row per update, no gaps);
#   - chunks dropped by the learner, by reason;
#   - the final held-out evaluation of both runs: the faulty run's success rate must be no
#     worse than the baseline's minus SOAK_TOLERANCE.
# Writes report.md, memory.csv and both runs' directories under the work directory, and prints
# PASS or FAIL.
#
# Usage: deploy/soak/run.sh [path/to/dupac]   (default: target/release/dupac of this repository)
# Environment:
#   SOAK_CONFIG=FILE        DUPAC config (default: a small procedural city, fast updates)
#   SOAK_UPDATES=400        updates of each run (the budget)
#   SOAK_ACTORS=3           actor processes
#   SOAK_KILL_EVERY_S=3     mean seconds between actor kills (uniform 1..2×)
#   SOAK_TOLERANCE=0.15     allowed drop of held-out success rate against the baseline
#   SOAK_SEED=1             seed of the kill schedule and of train.seed
#   SOAK_DIR=DIR            work directory (default: a new one under $TMPDIR; kept)
# Exit status: 0 PASS, 1 FAIL, 2 usage error.
set -uo pipefail

SCRIPT_DIR=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
REPO=$(cd "$SCRIPT_DIR/../.." && pwd)
case "${1:-}" in -h | --help) sed -n '2,/^$/p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; exit 0 ;; esac
BIN=${1:-$REPO/target/release/dupac}
[ -x "$BIN" ] || { echo "error: no dupac binary at $BIN" >&2; exit 2; }
UPDATES=${SOAK_UPDATES:-400}
ACTORS=${SOAK_ACTORS:-3}
KILL_EVERY=${SOAK_KILL_EVERY_S:-3}
TOL=${SOAK_TOLERANCE:-0.15}
SEED=${SOAK_SEED:-1}
for v in UPDATES ACTORS KILL_EVERY SEED; do
    [[ "${!v}" =~ ^[0-9]+$ ]] && [ "${!v}" -gt 0 ] || { echo "error: SOAK_$v must be a positive integer" >&2; exit 2; }
done
WORK=${SOAK_DIR:-$(mktemp -d "${TMPDIR:-/tmp}/dupac-soak.XXXXXX")}
mkdir -p "$WORK"
RANDOM=$SEED
T0=$(date +%s.%N)
now() { awk -v a="$T0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }'; }
log() { printf '[soak %6ss] %s\n' "$(now)" "$*"; }

CONFIG=${SOAK_CONFIG:-}
if [ -z "$CONFIG" ]; then
    CONFIG=$WORK/run.toml
    cat >"$CONFIG" <<TOML
# Written by deploy/soak/run.sh: a small procedural run with many fast updates.
[scenario]
city = "procedural"
n_sites = 8
[scenario.procedural]
size_m = 500
n_sites = 8
[cache]
horizontal_m = 10
vertical_m = 10
path = "$WORK/rsrp.bin"
[pairs]
min_m = 40
max_m = 70
eval_bins_m = [50, 60]
eval_per_bin = 50
bin_tolerance = 0.1
eval_file = "$WORK/eval.jsonl"
test_file = "$WORK/test.jsonl"
[train]
num_envs = 4
num_steps = 64
pool_size = 50
checkpoint_every = 10
eval_every = 1000000
eval_pairs = 100
[ppo]
num_minibatches = 2
hidden = [32, 32]
[distributed]
actor_envs = 2
chunk_steps = 32
stats_every_s = 0.5
silent_after_s = 3.0
TOML
fi
BATCH=$("$BIN" --config "$CONFIG" config 2>/dev/null | awk -F' = ' '/^num_envs/ {e=$2} /^num_steps/ {s=$2} END {print e*s}')
[ "${BATCH:-0}" -gt 0 ] || { echo "error: cannot read train.num_envs/num_steps from $CONFIG" >&2; exit 2; }
TIMESTEPS=$((UPDATES * BATCH))
"$BIN" --config "$CONFIG" -q cache build >"$WORK/prepare.log" 2>&1 &&
    "$BIN" --config "$CONFIG" -q pairs >>"$WORK/prepare.log" 2>&1 ||
    { echo "FAIL: preparing cache/pairs"; cat "$WORK/prepare.log"; exit 1; }
echo "t_s,run,name,pid,rss_kib" >"$WORK/memory.csv"

declare -A PID
STARTED=()
cleanup() {
    for n in "${!PID[@]}"; do kill -KILL "${PID[$n]}" 2>/dev/null; done
    wait 2>/dev/null
}
trap cleanup EXIT
trap 'echo interrupted; exit 130' INT TERM

free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])' 2>/dev/null || echo $((20000 + RANDOM % 20000)); }

# start RUN NAME ARGS...: a dupac process of run RUN, logs in $WORK/RUN/NAME.log (appended).
start() {
    local run=$1 name=$2
    shift 2
    "$BIN" --config "$CONFIG" -q "$@" >>"$WORK/$run/$name.log" 2>&1 </dev/null &
    PID[$name]=$!
}
alive() { [ -n "${PID[$1]:-}" ] && kill -0 "${PID[$1]}" 2>/dev/null; }
sample_memory() {
    local run=$1 t n rss
    t=$(now)
    for n in "${!PID[@]}"; do
        rss=$(awk '/^VmRSS:/ {print $2}' "/proc/${PID[$n]}/status" 2>/dev/null)
        [ -n "$rss" ] && echo "$t,$run,$n,${PID[$n]},$rss" >>"$WORK/memory.csv"
    done
}
rows() { local n; n=$(grep -c '"update":' "$WORK/$1/out/metrics.jsonl" 2>/dev/null); echo "${n:-0}"; }

# run_once RUN FAULTS(0|1): one training run of the budget; sets RUN_RC.
run_once() {
    local run=$1 faults=$2 port ep next_kill learner_restarted=0 kills=0 victim
    mkdir -p "$WORK/$run"
    port=$(free_port)
    ep=tcp/127.0.0.1:$port
    local common=(--set "distributed.run=soak-$run-$$" --set "train.total_timesteps=$TIMESTEPS" --set "train.seed=$SEED")
    local lnet=(--mode router --listen "$ep" --no-multicast-scouting)
    local anet=(--mode client --connect "$ep" --no-multicast-scouting)
    start "$run" learner "${common[@]}" learner --out "$WORK/$run/out" "${lnet[@]}"
    for a in $(seq "$ACTORS"); do start "$run" "actor$a" "${common[@]}" actor --id "$a" --threads 1 "${anet[@]}"; done
    next_kill=$(awk -v t="$(now)" -v k="$KILL_EVERY" -v r=$RANDOM 'BEGIN { printf "%.1f", t + k * (1 + r / 32768) }')
    while true; do
        sample_memory "$run"
        if [ "$faults" -eq 1 ]; then
            if [ $learner_restarted -eq 0 ] && [ "$(rows "$run")" -ge $((UPDATES / 2)) ]; then
                log "$run: SIGKILL to the learner at update $(rows "$run"); restarting it with --resume"
                rows "$run" >"$WORK/$run/learner_killed_at"
                kill -KILL "${PID[learner]}" 2>/dev/null
                wait "${PID[learner]}" 2>/dev/null
                sleep 1
                start "$run" learner "${common[@]}" learner --out "$WORK/$run/out" --resume "${lnet[@]}"
                learner_restarted=2
            fi
            if awk -v t="$(now)" -v n="$next_kill" 'BEGIN { exit !(t >= n) }'; then
                victim=$((RANDOM % ACTORS + 1))
                kill -KILL "${PID[actor$victim]}" 2>/dev/null
                wait "${PID[actor$victim]}" 2>/dev/null
                kills=$((kills + 1))
                start "$run" "actor$victim" "${common[@]}" actor --id "$victim" --threads 1 "${anet[@]}"
                next_kill=$(awk -v t="$(now)" -v k="$KILL_EVERY" -v r=$RANDOM 'BEGIN { printf "%.1f", t + k * (1 + r / 32768) }')
            fi
        fi
        alive learner || break
        sleep 1
    done
    wait "${PID[learner]}" 2>/dev/null
    RUN_RC=$?
    for a in $(seq "$ACTORS"); do
        # The learner's Stop ends the actors; wait a little, then make sure.
        for _ in $(seq 50); do alive "actor$a" || break; sleep 0.1; done
        kill -KILL "${PID[actor$a]}" 2>/dev/null
        wait "${PID[actor$a]}" 2>/dev/null
    done
    unset 'PID[learner]'
    for a in $(seq "$ACTORS"); do unset "PID[actor$a]"; done
    echo "$kills" >"$WORK/$run/kills"
    log "$run: learner exited $RUN_RC at update $(rows "$run"); $kills actor kills"
}

log "work directory $WORK; $UPDATES updates × $BATCH samples, $ACTORS actors, a kill every ~${KILL_EVERY}–$((2 * KILL_EVERY)) s"
run_once faulty 1
FAULTY_RC=$RUN_RC
run_once baseline 0
BASE_RC=$RUN_RC

# ---------------------------------------------------------------- analysis
FAILS=0
REPORT=$WORK/report.md
metric() { tail -n 1 "$WORK/$1/out/metrics.jsonl" | grep -o "\"$2\":[-0-9.e]*" | cut -d: -f2; }
check() { if [ "$1" = ok ]; then echo "- ok: $2"; else echo "- **FAIL**: $2"; FAILS=$((FAILS + 1)); fi; }
{
    echo "# DUPAC soak test"
    echo
    echo "$(date -u +%Y-%m-%dT%H:%MZ), $(nproc) cores; $UPDATES updates × $BATCH samples; $ACTORS actors;"
    echo "actor kills every ${KILL_EVERY}–$((2 * KILL_EVERY)) s; learner SIGKILL + --resume at update $(cat "$WORK/faulty/learner_killed_at" 2>/dev/null || echo '?'); seed $SEED"
    echo
    echo "## Checks"
    for run in faulty baseline; do
        n=$(rows "$run")
        gaps=$(grep -o '"update":[0-9]*' "$WORK/$run/out/metrics.jsonl" | cut -d: -f2 |
            awk 'NR > 1 && $1 != prev + 1 { g++ } { prev = $1 } END { print g + 0 }')
        rc=$([ "$run" = faulty ] && echo "$FAULTY_RC" || echo "$BASE_RC")
        [ "$rc" -eq 0 ] && [ "$n" -eq "$UPDATES" ] && [ "$gaps" -eq 0 ] && s=ok || s=FAIL
        check $s "$run run: learner exit $rc, $n/$UPDATES updates, $gaps gaps in the curve"
    done
    fs=$(metric faulty eval/success_rate)
    bs=$(metric baseline eval/success_rate)
    awk -v f="${fs:-nan}" -v b="${bs:-nan}" -v t="$TOL" 'BEGIN { exit !(f + 0 == f && b + 0 == b && f >= b - t) }' && s=ok || s=FAIL
    check $s "held-out success: faulty ${fs:-?} vs baseline ${bs:-?} (tolerance $TOL)"
    # Memory: per process instance (run, name, pid), quarters of its samples.
    growth=$(awk -F, 'NR > 1 { k = $2 "/" $3 "/" $4; n[k]++; v[k, n[k]] = $5 }
        END {
            for (k in n) {
                m = n[k]; q = int(m / 4); if (m < 20) continue
                s2 = 0; s4 = 0
                for (i = q + 1; i <= 2 * q; i++) s2 += v[k, i]
                for (i = m - q + 1; i <= m; i++) s4 += v[k, i]
                a = s2 / q; b = s4 / q
                printf "%s %d %.0f %.0f %s\n", k, m, a / 1024, b / 1024, (b > 1.25 * a + 16384) ? "GROWS" : "flat"
            }
        }' "$WORK/memory.csv" | sort)
    if [ -z "$growth" ]; then
        echo "- not measured: memory (no process lived 20 samples; raise SOAK_UPDATES)"
    else
        if grep -q GROWS <<<"$growth"; then s=FAIL; else s=ok; fi
        check $s "memory bounded: no process grew (last-quarter mean ≤ 1.25 × second-quarter mean + 16 MiB)"
    fi
    echo
    echo "## Memory (VmRSS, MiB) of processes alive ≥ 20 s"
    echo
    echo "| run/process/pid | samples | 2nd quarter mean | last quarter mean | |"
    echo "|---|---:|---:|---:|---|"
    [ -z "$growth" ] || while read -r k m a b g; do echo "| $k | $m | $a | $b | $g |"; done <<<"$growth"
    echo
    echo "## Runs"
    echo
    echo "| | faulty | baseline |"
    echo "|---|---:|---|"
    echo "| actor kills | $(cat "$WORK/faulty/kills") | 0 |"
    for m in update global_step time_s eval/success_rate eval/collision_rate charts/episodic_return; do
        echo "| $m | $(metric faulty "$m") | $(metric baseline "$m") |"
    done
    for r in stale incarnation overflow garbage schema dimensions non_finite fingerprint wrong_run too_large; do
        echo "| dropped: $r | $(metric faulty "dist/dropped_$r") | $(metric baseline "dist/dropped_$r") |"
    done
    echo
    echo "(memory.csv has every sample: t_s, run, name, pid, rss_kib)"
} >"$REPORT"
cat "$REPORT"
if [ $FAILS -eq 0 ]; then echo "PASS ($(now) s; $WORK)"; exit 0; fi
echo "FAIL: $FAILS check(s); logs in $WORK"
exit 1
