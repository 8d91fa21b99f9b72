#!/usr/bin/env bash
# End-to-end throughput of `dupac train` on the default Midtown scenario: the
# single-process trainer against the learner with 1, 2 and 4 actor processes on the same cores,
# and the weight-broadcast latency seen by the actors (publish → first step acted with the new
# version) from a monitor's stats stream.
#
# Usage: benches/dist_throughput.sh [path/to/dupac]   (default target/release/dupac)
#        UPDATES=30 (per run; 4 096 samples each)
# Prints one line per configuration: steady-state env steps/s over updates 6..UPDATES (from the
# run's metrics: Δglobal_step / Δtime_s, where time_s counts rollout or waiting + update, not the
# startup or the final evaluation) and the wall-clock of the whole command.
set -euo pipefail
cd "$(dirname "$0")/.."
B=${1:-target/release/dupac}
U=${UPDATES:-30}
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
common=(-q
  --set "train.total_timesteps=$((4096 * U))"
  --set train.pool_size=300
  --set train.eval_every=0
  --set train.eval_pairs=1
  --set train.checkpoint_every=100000)

sps() {
  python3 - "$1" <<'PY'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
a, b = rows[4], rows[-1]
print(f"{(b['global_step'] - a['global_step']) / (b['time_s'] - a['time_s']):.0f}")
PY
}

run() {
  local name=$1
  shift
  local t0 t1
  t0=$(date +%s.%N)
  "$B" "${common[@]}" train --out "$OUT/$name" "$@" > "$OUT/$name.log" 2>&1
  t1=$(date +%s.%N)
  printf '%-16s %8s env steps/s   (command %.0f s)\n' "$name" "$(sps "$OUT/$name/metrics.jsonl")" \
    "$(python3 -c "print($t1 - $t0)")"
}

"$B" -q cache build > /dev/null
run single-process --single-process
run actors-1 --actors 1
run actors-2 --actors 2
run actors-4 --actors 4

# Broadcast latency: learner + 2 actors by hand with a monitor recording the actors' stats.
PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
EP="tcp/127.0.0.1:$PORT"
NET=(--no-multicast-scouting)
"$B" "${common[@]}" learner --out "$OUT/lat" --mode router --listen "$EP" "${NET[@]}" > "$OUT/lat.log" 2>&1 &
L=$!
for k in 0 1; do
  RAYON_NUM_THREADS=1 "$B" -q actor --id $k --threads 1 --pool "$OUT/actors-2/train_pool.jsonl" \
    --mode client --connect "$EP" "${NET[@]}" > "$OUT/a$k.log" 2>&1 &
done
"$B" -q monitor --plain --jsonl "$OUT/lat.jsonl" --mode client --connect "$EP" "${NET[@]}" > /dev/null 2>&1 &
M=$!
wait $L
sleep 1
kill -INT $M 2>/dev/null || true
wait
python3 - "$OUT/lat.jsonl" "$OUT/lat/metrics.jsonl" <<'PY'
import json, sys, statistics as st
lat = [m["Actor"]["last_swap_latency_ms"] for m in map(json.loads, open(sys.argv[1])) if "Actor" in m]
lat = [x for x in lat if x == x]
rows = [json.loads(l) for l in open(sys.argv[2])][4:]
q = lambda xs, p: sorted(xs)[min(len(xs) - 1, int(p * len(xs)))]
print(f"swap latency over {len(lat)} actor stats samples: median {st.median(lat):.1f} ms, p95 {q(lat, .95):.1f} ms, max {max(lat):.1f} ms")
for k in ("time/wait_s", "time/ppo_s", "time/publish_s"):
    print(f"{k}: mean {1000 * st.mean(r[k] for r in rows):.2f} ms per update")
PY
