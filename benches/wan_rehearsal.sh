#!/usr/bin/env bash
# Training over a bad WAN, rehearsed on one machine without sch_netem: a router, a learner and two
# actors, the actors either straight to the router (`clean`) or each through its own
# `dupac relay` (`wan`) with LINK (default: 50 ms ± 20 ms one way, no rate cap) and a fault
# schedule per relay (actor 1: a 5 s stall, a reset, a 20 s partition; actor 2: a reset, a stall),
# counted from the learner's third update (`relay --faults-on-signal`: the preparation of a
# slow binary would otherwise outlast the schedule).
# The figures in docs/reliability.md "Over a WAN" and BENCHMARKS.md come from it.
#
# Usage: benches/wan_rehearsal.sh clean|wan [BIN] [OUT]
#   BIN  the dupac binary (default target/release/dupac)
#   OUT  the output directory (default out/wan/MODE): logs, the run, summary.txt
#   LINK=delay=50ms,jitter=20ms,rate=10mbit  the relays' link (`dupac relay --help`)
#   TIMESTEPS=1048576                         train.total_timesteps (256 updates)
#   POOL=train_pool.jsonl                     the actors' training pairs (as `dupac train` writes
#                                             them for the same configuration and seed): each
#                                             actor reads them instead of drawing its own (minutes)
#   SETS="a.b=v …"                            more settings for the learner and the actors, e.g.
#                                             SETS=distributed.max_chunks_per_version=5 (actors
#                                             one chunk ahead: docs/distributed.md "Staleness")
# Decisions/s: Δ global_step / Δ time_s of OUT/run/metrics.jsonl, update 1 to the last.
set -uo pipefail
MODE=${1:?usage: $0 clean|wan [BIN] [OUT]}
B=${2:-target/release/dupac}
O=${3:-out/wan/$MODE}
LINK=${LINK:-delay=50ms,jitter=20ms}
SET=(--set "train.total_timesteps=${TIMESTEPS:-1048576}")
for kv in ${SETS:-}; do SET+=(--set "$kv"); done
APOOL=(); [ -n "${POOL:-}" ] && APOOL=(--pool "$POOL")
case $MODE in clean | wan) ;; *) echo "mode: clean or wan" >&2; exit 2 ;; esac
rm -rf "$O"; mkdir -p "$O"
PR=$((20000 + RANDOM % 10000)); R=tcp/127.0.0.1:$PR
C=(--mode client --connect "$R" --no-multicast-scouting)
"$B" --no-progress router --listen "$R" --no-multicast-scouting >"$O/router.log" 2>&1 & RP=$!
sleep 1
"$B" --no-progress "${SET[@]}" learner --out "$O/run" "${C[@]}" >"$O/learner.out" 2>"$O/learner.err" & LP=$!
APS=() RPS=()
for id in 1 2; do
    EP=$R
    if [ "$MODE" = wan ]; then
        PA=$((PR + id))
        if [ $id = 1 ]; then F="stall@20s+5s,reset@40s,partition@60s+20s"; else F="reset@30s,stall@70s+5s"; fi
        "$B" --no-progress relay --listen "127.0.0.1:$PA" --upstream "127.0.0.1:$PR" --link "$LINK" \
            --faults "$F" --faults-on-signal >"$O/relay$id.log" 2>&1 &
        RPS+=($!)
        EP=tcp/127.0.0.1:$PA
    fi
    "$B" --no-progress "${SET[@]}" actor --id $id --threads 1 --mode client --connect "$EP" \
        --no-multicast-scouting "${APOOL[@]}" >"$O/actor$id.out" 2>"$O/actor$id.err" &
    APS+=($!)
done
T0=$(date +%s)
if [ "$MODE" = wan ]; then
    # The fault schedules start once the learner has written its third update.
    (while kill -0 $LP 2>/dev/null; do
        if [ "$(grep -c '"update"' "$O/run/metrics.jsonl" 2>/dev/null)" -ge 3 ]; then
            echo "faults from $(($(date +%s) - T0)) s" >"$O/faults_at.txt"
            kill -USR1 "${RPS[@]}"; break
        fi
        sleep 1
    done) &
fi
wait $LP
echo "learner exit $? after $(($(date +%s) - T0)) s" >"$O/summary.txt"
sleep 3
for p in "${APS[@]}" "${RPS[@]}"; do kill -INT "$p" 2>/dev/null; done
sleep 2
kill -INT $RP 2>/dev/null
wait
python3 - "$O/run/metrics.jsonl" >>"$O/summary.txt" <<'EOF'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1]) if '"update"' in l]
a, b = rows[0], rows[-1]
rate = (b["global_step"] - a["global_step"]) / (b["time_s"] - a["time_s"])
print(f"updates {len(rows)}; decisions/s {rate:.0f} (update {a['update']} to {b['update']})")
drops = {k[len("dist/dropped_"):]: int(v) for k, v in b.items() if k.startswith("dist/dropped_") and v}
older = sum(r.get("charts/older_policy_frac", 0) for r in rows) / len(rows)
print(f"drops {drops or 'none'}; older_policy_frac mean {older:.2f}")
EOF
grep -h "done:\|held-out" "$O/learner.out" "$O/learner.err" | tail -2 >>"$O/summary.txt"
# Each actor's exit line: chunks, stale chunks not sent, bytes per decision, shares re-sent.
grep -h "^actor [0-9]*:" "$O"/actor*.out >>"$O/summary.txt"
[ -f "$O/faults_at.txt" ] && cat "$O/faults_at.txt" >>"$O/summary.txt"
for id in 1 2; do [ -f "$O/relay$id.log" ] && tail -1 "$O/relay$id.log" >>"$O/summary.txt"; done
cat "$O/summary.txt"
