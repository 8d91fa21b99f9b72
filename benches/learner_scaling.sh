#!/usr/bin/env bash
# How far one learner process scales with its actors: the real learner (`dupac
# learner`, router on loopback) against N actor processes that replay recorded chunks
# (`dupac actor --replay`: actors of unbounded speed, each sending its share of every version
# as soon as the weights arrive), N = 2 8 32 64, with today's default configuration.
#
# First one real actor records 16 chunks (`dupac actor --record --max-chunks 16`); then for each
# N a fresh learner runs UPDATES updates of 4 096 samples. Per N it prints: accepted samples/s
# and updates/s in the steady state (updates 6..UPDATES, Δglobal_step / Δtime_s from the run's
# metrics), the bytes/s of trajectory messages arriving at the learner over the same updates
# (`dist/received_mb`), the chunks the learner dropped (all reasons, `dist/dropped_*`) and the
# learner's peak resident memory.
#
# Usage: benches/learner_scaling.sh [path/to/dupac] [--device cpu|cuda|wgpu]
#        UPDATES=30 NS="2 8 32 64"
#        POOL=train_pool.jsonl: the actors' training pairs (as `dupac train` writes them for the
#        default configuration), read by every actor instead of drawn by each (minutes per
#        actor process: with N = 64 on a small machine, most of the bench)
set -euo pipefail
cd "$(dirname "$0")/.."
B=target/release/dupac
DEVICE=cpu
while [ $# -gt 0 ]; do
  case "$1" in
    --device) DEVICE=$2; shift 2 ;;
    *) B=$1; shift ;;
  esac
done
U=${UPDATES:-30}
NS=${NS:-"2 8 32 64"}
OUT=$(mktemp -d)
trap 'pkill -P $$ 2>/dev/null || true; rm -rf "$OUT"' EXIT
"$B" -q config \
  --set "train.total_timesteps=$((4096 * U))" \
  --set train.eval_every=0 \
  --set train.eval_pairs=1 \
  --set train.checkpoint_every=100000 > "$OUT/config.toml"
port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
learner() { # out-dir endpoint
  /usr/bin/time -f "%M" -o "$1.time" \
    "$B" -q --config "$OUT/config.toml" learner --out "$1" --device "$DEVICE" \
    --mode router --listen "$2" --no-multicast-scouting > "$1.log" 2>&1
}
POOLARG=(); [ -n "${POOL:-}" ] && POOLARG=(--pool "$POOL")
actor() { # id endpoint extra…
  local id=$1 ep=$2
  shift 2
  "$B" -q --config "$OUT/config.toml" actor --id "$id" --threads 1 \
    --mode client --connect "$ep" --no-multicast-scouting "${POOLARG[@]}" "$@"
}

# Record.
EP="tcp/127.0.0.1:$(port)"
learner "$OUT/record" "$EP" &
L=$!
actor 0 "$EP" --max-chunks 16 --record "$OUT/chunks.bin" > "$OUT/record-actor.log" 2>&1
pkill -INT -f -- "learner --out $OUT/record" || true
wait $L 2>/dev/null || true
echo "recorded $(du -h "$OUT/chunks.bin" | cut -f1) of chunks ($DEVICE learner, $U updates per N, $(nproc) cores)"
printf "%4s %14s %10s %10s %8s %12s\n" N "samples/s" "updates/s" "MB/s in" drops "learner RSS"

for n in $NS; do
  EP="tcp/127.0.0.1:$(port)"
  R="$OUT/n$n"
  learner "$R" "$EP" &
  L=$!
  pids=()
  for k in $(seq 1 "$n"); do
    actor "$k" "$EP" --replay "$OUT/chunks.bin" > "$R-actor$k.log" 2>&1 &
    pids+=($!)
  done
  wait $L || true
  kill "${pids[@]}" 2>/dev/null || true
  wait "${pids[@]}" 2>/dev/null || true
  python3 - "$R/metrics.jsonl" "$R.time" "$n" <<'PY'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
n = int(sys.argv[3])
# The steady state: from update 6, or from the first update with every actor alive (N actor
# processes take a while to load the world on a small machine), to the last.
alive = [r for r in rows if r.get("dist/alive_actors", 0) >= n]
start = max(5, rows.index(alive[0]) if alive else 5)
a, b = rows[min(start, len(rows) - 2)], rows[-1]
dt = b["time_s"] - a["time_s"]
sps = (b["global_step"] - a["global_step"]) / dt
ups = (b["update"] - a["update"]) / dt
mbps = (b["dist/received_mb"] - a["dist/received_mb"]) / dt
drops = sum(v for k, v in b.items() if k.startswith("dist/dropped_") and v)
rss_kb = float(open(sys.argv[2]).read().split()[-1])
most = max(r.get("dist/alive_actors", 0) for r in rows)
print(f"{n:>4} {sps:14.0f} {ups:10.2f} {mbps:10.2f} {drops:8.0f} {rss_kb / 1024:9.0f} MB"
      f"   (updates {a['update']:.0f}..{b['update']:.0f}, at most {most:.0f} actors alive)")
PY
done
