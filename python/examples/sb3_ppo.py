"""Stable-Baselines3 PPO on the DUPAC Gymnasium environment, compared with DUPAC's own policy.

SB3 has no hybrid (continuous + discrete) action, so this trains the paper's base method: the
policy moves the UAV, A3 picks the serving site (``association="a3"``). It trains for
``--timesteps`` decisions on Midtown's training pool, then flies the first ``--pairs`` held-out
pairs (spread over the distance bins) with it and with a base-method policy trained by
``dupac train`` (``--dupac-policy``), and prints success, distance overhead and time in excellent
RSRP for both.

    pip install './python[sb3]'
    python python/examples/sb3_ppo.py --timesteps 200000 --pairs 70
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import dupac
from dupac.gym import DupacEnv


def fly(env: DupacEnv, act, pair: int) -> dict:
    """One held-out pair flown with ``act(obs) -> move``: outcome, overhead, excellent time."""
    obs, _ = env.reset(seed=0, options={"pair": pair, "reversed": False})
    classes, flown = [], 0.0
    while True:
        obs, _, te, tr, info = env.step(act(obs))
        steps = env.last_steps()
        classes.extend(steps["rsrp_class"].tolist())
        # The distance flown plus what is left to the destination (the goal radius on arrival),
        # as dupac eval measures the overhead.
        flown = float(steps["distance_flown_m"][-1] + steps["distance_to_goal_m"][-1])
        if te or tr:
            return {
                "goal": info["outcome"] == "goal",
                "flown_m": flown,
                "excellent": float(np.mean(np.array(classes) == 0)),
            }


def report(name: str, rows: list[dict], shortest: np.ndarray) -> None:
    ok = [i for i, r in enumerate(rows) if r["goal"]]
    over = [rows[i]["flown_m"] / shortest[i] - 1 for i in ok]
    exc = [rows[i]["excellent"] for i in ok]
    print(
        f"{name:28s} success {len(ok)}/{len(rows)} ({len(ok) / len(rows):.1%}), "
        f"overhead {np.mean(over) if ok else float('nan'):.1%}, "
        f"excellent {np.mean(exc) if ok else float('nan'):.1%} (successful flights)"
    )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--timesteps", type=int, default=200_000)
    ap.add_argument("--envs", type=int, default=8)
    ap.add_argument("--pairs", type=int, default=70)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--dupac-policy", default="results/complete/real/base_s1/policy.bin")
    args = ap.parse_args()

    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env

    torch.set_num_threads(1)
    # The observation a committed DUPAC policy was trained with, so that both fly
    # the same environment.
    sc = dupac.Scenario(policy=args.dupac_policy)
    vec = make_vec_env(lambda: DupacEnv(sc), n_envs=args.envs, seed=args.seed)
    model = PPO("MlpPolicy", vec, n_steps=512, batch_size=1024, seed=args.seed, verbose=0)
    t0 = time.perf_counter()
    model.learn(total_timesteps=args.timesteps)
    print(f"SB3 PPO: {args.timesteps} decisions in {time.perf_counter() - t0:.0f} s")

    env = DupacEnv(sc, split="eval")
    pairs = sc.pairs("eval")
    n = len(pairs["id"])
    chosen = [k * n // args.pairs for k in range(args.pairs)]
    shortest = pairs["shortest_m"][chosen]
    sb3 = [fly(env, lambda o: model.predict(o, deterministic=True)[0], k) for k in chosen]
    ours = dupac.Policy(args.dupac_policy)
    base = [fly(env, lambda o: ours.act(o)[0], k) for k in chosen]
    report(f"SB3 PPO ({args.timesteps} decisions)", sb3, shortest)
    report("dupac train (base method)", base, shortest)


if __name__ == "__main__":
    main()
