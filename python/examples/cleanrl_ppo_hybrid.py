"""PPO for DUPAC's hybrid action in one file, as CleanRL writes it (``ppo_continuous_action.py``).

The policy has CleanRL's Gaussian head for the move (state-independent log-std) and one more
head, a categorical over the M sites: the learned association of the paper. An action's
log-probability is the sum of the two heads', its entropy the sum of theirs; everything else is
CleanRL's PPO (observation and reward normalisation, GAE, clipped surrogate and value loss,
advantage normalisation, gradient norm clip, learning-rate annealing), read top to bottom. The
environments are DUPAC's own vector env (:class:`dupac.gym.DupacVecEnv`, stepped in Rust on the
host's cores).

After training it flies every held-out pair of the scenario both ways with the deterministic
policy (the mean move, the most probable site) and prints the success rate and the mean *site
regret* (best site's RSRP − the chosen site's, dB per step: 0 when the policy always serves the
strongest site).

    pip install './python[sb3]'     # PyTorch
    python python/examples/cleanrl_ppo_hybrid.py --total-timesteps 300000
    python python/examples/cleanrl_ppo_hybrid.py --set scenario.city=procedural --set ...

This is an example of the interface, not DUPAC's trainer: ``dupac train`` trains the paper's
policy (per-step site choice, its observation and reward departures, the distributed actors).
"""

from __future__ import annotations

import argparse
import random
import time
from dataclasses import dataclass, field

import gymnasium
import numpy as np
import torch
import torch.nn as nn
from torch.distributions.categorical import Categorical
from gymnasium.wrappers.utils import RunningMeanStd
from torch.distributions.normal import Normal

import dupac
from dupac.gym import DupacEnv, DupacVecEnv


@dataclass
class Args:
    seed: int = 1
    """seed of the experiment (torch, numpy and the environments)"""
    set: list[str] = field(default_factory=list)
    """configuration overrides, as `dupac --set a.b=v` (e.g. a smaller city)"""
    total_timesteps: int = 300_000
    """total decisions of the experiment"""
    learning_rate: float = 3e-4
    num_envs: int = 8
    num_steps: int = 128
    """decisions per environment per rollout"""
    anneal_lr: bool = True
    gamma: float = 0.95
    """DUPAC's `ppo.gamma` (CleanRL's 0.99 learned no held-out flight on Midtown in 1 M decisions,
    python/README.md "CleanRL")"""
    gae_lambda: float = 0.95
    num_minibatches: int = 4
    update_epochs: int = 10
    norm_adv: bool = True
    clip_coef: float = 0.2
    clip_vloss: bool = True
    ent_coef: float = 0.0
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    target_kl: float | None = None
    torch_threads: int = 1
    """threads of torch (the networks are small; the environments use the other cores)"""

    @property
    def batch_size(self) -> int:
        return self.num_envs * self.num_steps

    @property
    def minibatch_size(self) -> int:
        return self.batch_size // self.num_minibatches

    @property
    def num_iterations(self) -> int:
        return self.total_timesteps // self.batch_size


def layer_init(layer: nn.Linear, std: float = np.sqrt(2), bias_const: float = 0.0) -> nn.Linear:
    torch.nn.init.orthogonal_(layer.weight, std)
    torch.nn.init.constant_(layer.bias, bias_const)
    return layer


class Agent(nn.Module):
    def __init__(self, obs_dim: int, num_sites: int):
        super().__init__()
        self.critic = nn.Sequential(
            layer_init(nn.Linear(obs_dim, 64)),
            nn.Tanh(),
            layer_init(nn.Linear(64, 64)),
            nn.Tanh(),
            layer_init(nn.Linear(64, 1), std=1.0),
        )
        self.actor_trunk = nn.Sequential(
            layer_init(nn.Linear(obs_dim, 64)),
            nn.Tanh(),
            layer_init(nn.Linear(64, 64)),
            nn.Tanh(),
        )
        self.actor_mean = layer_init(nn.Linear(64, 3), std=0.01)
        self.actor_logstd = nn.Parameter(torch.zeros(1, 3))
        self.site_logits = layer_init(nn.Linear(64, num_sites), std=0.01)
        # The training observations' running mean and variance (updated by `observe` while
        # training; evaluation normalises with them as they are).
        self.register_buffer("obs_mean", torch.zeros(obs_dim, dtype=torch.float64))
        self.register_buffer("obs_var", torch.ones(obs_dim, dtype=torch.float64))

    def normalize(self, obs: np.ndarray) -> torch.Tensor:
        """Raw observations as the networks see them: by the training statistics, clipped."""
        x = torch.as_tensor(obs, dtype=torch.float64)
        return ((x - self.obs_mean) / torch.sqrt(self.obs_var + 1e-8)).clamp(-10, 10).float()

    def observe(self, obs: np.ndarray, rms: RunningMeanStd) -> torch.Tensor:
        """Training: updates the statistics with a batch of raw observations, then normalises."""
        rms.update(obs)
        self.obs_mean.copy_(torch.as_tensor(rms.mean))
        self.obs_var.copy_(torch.as_tensor(rms.var))
        return self.normalize(obs)

    def get_value(self, x):
        return self.critic(x)

    def get_action_and_value(self, x, move=None, site=None):
        h = self.actor_trunk(x)
        mean = self.actor_mean(h)
        move_probs = Normal(mean, self.actor_logstd.expand_as(mean).exp())
        site_probs = Categorical(logits=self.site_logits(h))
        if move is None:
            move = move_probs.sample()
            site = site_probs.sample()
        logprob = move_probs.log_prob(move).sum(1) + site_probs.log_prob(site)
        entropy = move_probs.entropy().sum(1) + site_probs.entropy()
        return move, site, logprob, entropy, self.critic(x)

    def act_deterministic(self, x):
        h = self.actor_trunk(x)
        return self.actor_mean(h), self.site_logits(h).argmax(1)


def to_env(move: torch.Tensor, site: torch.Tensor) -> dict:
    """The action DUPAC's environments take: the move clipped to its box, the site."""
    return {"move": np.clip(move.cpu().numpy(), -1.0, 1.0), "site": site.cpu().numpy()}


def train(args: Args, scenario: dupac.Scenario | None = None, log=print) -> Agent:
    """Trains the agent for ``args.total_timesteps`` decisions on the scenario's training pool."""
    random.seed(args.seed)
    np.random.seed(args.seed)
    torch.manual_seed(args.seed)
    torch.set_num_threads(args.torch_threads)
    device = torch.device("cpu")

    # env setup
    scenario = scenario or dupac.Scenario(set=args.set)
    envs = DupacVecEnv(args.num_envs, scenario, seed=args.seed)
    assert envs.learned, "the learned association (scenario association='learned') is needed"
    # CleanRL's normalisation: rewards by the running std of the discounted return (DUPAC's
    # rewards are in dBm-weighted units: returns of −10³), clipped to ±10; observations by their
    # running mean and std, clipped to ±10 (`Agent.normalize`: Gymnasium's observation wrappers
    # refuse a same-step autoreset env, so the statistics live with the agent).
    envs = gymnasium.wrappers.vector.NormalizeReward(envs, gamma=args.gamma)
    envs = gymnasium.wrappers.vector.ClipReward(envs, -10.0, 10.0)
    obs_dim = envs.single_observation_space.shape[0]
    num_sites = int(envs.single_action_space["site"].n)

    agent = Agent(obs_dim, num_sites).to(device)
    optimizer = torch.optim.Adam(agent.parameters(), lr=args.learning_rate, eps=1e-5)

    # storage
    obs = torch.zeros((args.num_steps, args.num_envs, obs_dim)).to(device)
    moves = torch.zeros((args.num_steps, args.num_envs, 3)).to(device)
    sites = torch.zeros((args.num_steps, args.num_envs), dtype=torch.long).to(device)
    logprobs = torch.zeros((args.num_steps, args.num_envs)).to(device)
    rewards = torch.zeros((args.num_steps, args.num_envs)).to(device)
    dones = torch.zeros((args.num_steps, args.num_envs)).to(device)
    values = torch.zeros((args.num_steps, args.num_envs)).to(device)

    global_step = 0
    start_time = time.time()
    obs_rms = RunningMeanStd(shape=(obs_dim,))
    next_obs, _ = envs.reset(seed=args.seed)
    next_obs = agent.observe(next_obs, obs_rms)
    next_done = torch.zeros(args.num_envs).to(device)

    for iteration in range(1, args.num_iterations + 1):
        if args.anneal_lr:
            frac = 1.0 - (iteration - 1.0) / args.num_iterations
            optimizer.param_groups[0]["lr"] = frac * args.learning_rate

        returns_seen, goals_seen = [], []
        for step in range(0, args.num_steps):
            global_step += args.num_envs
            obs[step] = next_obs
            dones[step] = next_done

            with torch.no_grad():
                move, site, logprob, _, value = agent.get_action_and_value(next_obs)
                values[step] = value.flatten()
            moves[step], sites[step], logprobs[step] = move, site, logprob

            next_obs, reward, terminations, truncations, infos = envs.step(to_env(move, site))
            # Same-step autoreset: a step that ends an episode returns the next episode's first
            # observation; the value bootstrap stops at the end as CleanRL's does.
            next_done = np.logical_or(terminations, truncations)
            rewards[step] = torch.tensor(reward).to(device).view(-1)
            next_obs = agent.observe(next_obs, obs_rms)
            next_done = torch.Tensor(next_done).to(device)

            if "final_info" in infos:
                # The environments' own returns, before the reward scaling.
                ended = infos["_final_info"]
                returns_seen.extend(infos["final_info"]["episode"]["r"][ended].tolist())
                goals_seen.extend((infos["final_info"]["outcome"][ended] == 0).tolist())

        # bootstrap value if not done
        with torch.no_grad():
            next_value = agent.get_value(next_obs).reshape(1, -1)
            advantages = torch.zeros_like(rewards).to(device)
            lastgaelam = 0
            for t in reversed(range(args.num_steps)):
                if t == args.num_steps - 1:
                    nextnonterminal = 1.0 - next_done
                    nextvalues = next_value
                else:
                    nextnonterminal = 1.0 - dones[t + 1]
                    nextvalues = values[t + 1]
                delta = rewards[t] + args.gamma * nextvalues * nextnonterminal - values[t]
                advantages[t] = lastgaelam = (
                    delta + args.gamma * args.gae_lambda * nextnonterminal * lastgaelam
                )
            returns = advantages + values

        # flatten the batch
        b_obs = obs.reshape((-1, obs_dim))
        b_logprobs = logprobs.reshape(-1)
        b_moves = moves.reshape((-1, 3))
        b_sites = sites.reshape(-1)
        b_advantages = advantages.reshape(-1)
        b_returns = returns.reshape(-1)
        b_values = values.reshape(-1)

        # Optimizing the policy and value network
        b_inds = np.arange(args.batch_size)
        clipfracs = []
        for epoch in range(args.update_epochs):
            np.random.shuffle(b_inds)
            for start in range(0, args.batch_size, args.minibatch_size):
                mb_inds = b_inds[start : start + args.minibatch_size]

                _, _, newlogprob, entropy, newvalue = agent.get_action_and_value(
                    b_obs[mb_inds], b_moves[mb_inds], b_sites[mb_inds]
                )
                logratio = newlogprob - b_logprobs[mb_inds]
                ratio = logratio.exp()

                with torch.no_grad():
                    # calculate approx_kl http://joschu.net/blog/kl-approx.html
                    old_approx_kl = (-logratio).mean()
                    approx_kl = ((ratio - 1) - logratio).mean()
                    clipfracs += [((ratio - 1.0).abs() > args.clip_coef).float().mean().item()]

                mb_advantages = b_advantages[mb_inds]
                if args.norm_adv:
                    mb_advantages = (mb_advantages - mb_advantages.mean()) / (
                        mb_advantages.std() + 1e-8
                    )

                # Policy loss
                pg_loss1 = -mb_advantages * ratio
                pg_loss2 = -mb_advantages * torch.clamp(
                    ratio, 1 - args.clip_coef, 1 + args.clip_coef
                )
                pg_loss = torch.max(pg_loss1, pg_loss2).mean()

                # Value loss
                newvalue = newvalue.view(-1)
                if args.clip_vloss:
                    v_loss_unclipped = (newvalue - b_returns[mb_inds]) ** 2
                    v_clipped = b_values[mb_inds] + torch.clamp(
                        newvalue - b_values[mb_inds], -args.clip_coef, args.clip_coef
                    )
                    v_loss_clipped = (v_clipped - b_returns[mb_inds]) ** 2
                    v_loss = 0.5 * torch.max(v_loss_unclipped, v_loss_clipped).mean()
                else:
                    v_loss = 0.5 * ((newvalue - b_returns[mb_inds]) ** 2).mean()

                entropy_loss = entropy.mean()
                loss = pg_loss - args.ent_coef * entropy_loss + v_loss * args.vf_coef

                optimizer.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(agent.parameters(), args.max_grad_norm)
                optimizer.step()

            if args.target_kl is not None and approx_kl > args.target_kl:
                break

        y_pred, y_true = b_values.cpu().numpy(), b_returns.cpu().numpy()
        var_y = np.var(y_true)
        explained_var = np.nan if var_y == 0 else 1 - np.var(y_true - y_pred) / var_y

        log(
            f"global_step={global_step} "
            f"charts/episodic_return={np.mean(returns_seen) if returns_seen else float('nan'):.2f} "
            f"charts/success_rate={np.mean(goals_seen) if goals_seen else float('nan'):.3f} "
            f"losses/value_loss={v_loss.item():.3f} losses/policy_loss={pg_loss.item():.4f} "
            f"losses/entropy={entropy_loss.item():.3f} losses/old_approx_kl={old_approx_kl.item():.4f} "
            f"losses/approx_kl={approx_kl.item():.4f} losses/clipfrac={np.mean(clipfracs):.3f} "
            f"losses/explained_variance={explained_var:.3f} "
            f"charts/SPS={int(global_step / (time.time() - start_time))}"
        )

    envs.close()
    return agent


def evaluate(agent: Agent, scenario: dupac.Scenario, split: str = "eval") -> dict:
    """Flies every pair of ``split`` both ways with the deterministic policy: the success rate
    and the mean site regret (best RSRP − chosen site's RSRP, dB, over every MDP step)."""
    env = DupacEnv(scenario, split=split)
    goals, regret_db = [], []
    for pair in range(len(scenario.pairs(split)["id"])):
        for reverse in (False, True):
            obs, _ = env.reset(seed=0, options={"pair": pair, "reversed": reverse})
            while True:
                with torch.no_grad():
                    move, site = agent.act_deterministic(agent.normalize(obs).unsqueeze(0))
                action = to_env(move, site)
                obs, _, terminated, truncated, info = env.step(
                    {"move": action["move"][0], "site": int(action["site"][0])}
                )
                steps = env.last_steps()
                regret_db.extend((steps["best_rsrp_dbm"] - steps["serving_rsrp_dbm"]).tolist())
                if terminated or truncated:
                    goals.append(info["outcome"] == "goal")
                    break
    return {"success_rate": float(np.mean(goals)), "site_regret_db": float(np.mean(regret_db))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    defaults = Args()
    for name, value in vars(defaults).items():
        flag = "--" + name.replace("_", "-")
        if name == "set":
            ap.add_argument(flag, action="append", default=[], help="a.b=v (repeatable)")
        elif isinstance(value, bool):
            ap.add_argument(flag, type=lambda s: s.lower() in ("1", "true", "yes"), default=value)
        elif value is None:
            ap.add_argument(flag, type=float, default=None)
        else:
            ap.add_argument(flag, type=type(value), default=value)
    args = Args(**vars(ap.parse_args()))
    scenario = dupac.Scenario(set=args.set)
    torch.manual_seed(args.seed)
    probe = DupacEnv(scenario)
    untrained = evaluate(Agent(probe.observation_space.shape[0], scenario.num_sites), scenario)
    agent = train(args, scenario)
    trained = evaluate(agent, scenario)
    print(f"held-out pairs, untrained: {untrained}")
    print(f"held-out pairs, trained:   {trained}")


if __name__ == "__main__":
    main()
