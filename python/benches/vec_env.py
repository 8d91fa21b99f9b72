"""Decisions per second of the vectorised Python env against the same work in Rust alone.

On 1 and on 2 threads (``num_threads``: the env steps its N environments on a pool of that
many threads), the default Midtown scenario with the cached radio map, the held-out pairs with their guide paths, N = 64 environments, uniform
random moves and sites drawn once. The same decisions are made twice from the same seed:

* Python: T calls of ``dupac.gym.DupacVecEnv.step`` (arrays in and out, the GIL released in
  each call, autoreset in the same step), the loop in Python;
* Rust: one call of ``VecEnv._step_many`` making the same T × N decisions in Rust alone
  (``Env::act`` and the resets, no observation copied out), on the same threads.

Run from the repository root (the RSRP cache and the held-out pairs are made on first use,
≈ 1 min): ``python python/benches/vec_env.py [--envs 64] [--decisions 200] [--repeats 3]
[--threads 1 2]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import dupac
from dupac.gym import DupacVecEnv


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--envs", type=int, default=64)
    ap.add_argument("--decisions", type=int, default=200, help="decisions per environment")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--association", default="learned")
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    args = ap.parse_args()
    sc = dupac.Scenario(association=args.association)
    n, t = args.envs, args.decisions
    rng = np.random.default_rng(0)
    moves = rng.uniform(-1, 1, (t, n, 3))
    sites = rng.integers(0, sc.num_sites, (t, n))
    rows = []
    for threads in args.threads:
        vec = DupacVecEnv(n, sc, split="eval", seed=0, num_threads=threads)
        print(f"{sc.city}: {n} environments on {vec.num_threads} threads, {t} decisions each, "
              f"obs_dim {vec.single_observation_space.shape[0]}")
        py_rates, rust_rates = [], []
        for r in range(args.repeats):
            vec.reset(seed=r)
            t0 = time.perf_counter()
            for k in range(t):
                action = {"move": moves[k], "site": sites[k]} if vec.learned else moves[k]
                vec.step(action)
            py_rates.append(n * t / (time.perf_counter() - t0))
            vec.reset(seed=r)
            t0 = time.perf_counter()
            vec._vec._step_many(moves, sites)
            rust_rates.append(n * t / (time.perf_counter() - t0))
            print(f"  repeat {r}: Python {py_rates[-1]:,.0f} decisions/s, Rust {rust_rates[-1]:,.0f} decisions/s")
        rows.append((threads, float(np.median(py_rates)), float(np.median(rust_rates))))
    print("threads | Python decisions/s | Rust decisions/s | Python / Rust | Python / Python on 1 thread")
    base = rows[0][1]
    for threads, py, rust in rows:
        print(f"{threads} | {py:,.0f} | {rust:,.0f} | {py / rust:.1%} | {py / base:.2f}x")


if __name__ == "__main__":
    main()
