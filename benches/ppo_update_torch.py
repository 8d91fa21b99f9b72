#!/usr/bin/env python3
"""The PyTorch peer of `cargo bench --bench learner -- ppo_update_default`: one PPO update of
today's default network and batch on the CPU, same shapes, same loss, same optimiser.

Network (docs/training.md): actor and critic MLPs 108 -> 256 -> 256 (tanh) over the observation's
trunk, the actor's head 3 move means with a state-independent log-std; the permutation-equivariant
site head: an embedding tanh(E h) (256 -> 16) of the actor's last hidden activation and an MLP
(11 + 16) -> 32 (tanh) -> 1 shared by the 30 sites, scored on one step's site features per
decision (the learner's `SITE_STEP_ROWS`, 1), its first layer split as DUPAC's is. Loss: clipped surrogate
of the move, clipped value loss (0.5), the all-sites expected site loss (coefficient 1);
Adam (eps 1e-5), global grad-norm clip 0.5. 4 096 samples, 4 epochs x 8 minibatches of 512.

Usage: python3 benches/ppo_update_torch.py [--threads N] [--repeats R]
Prints samples/s of the whole update (the median of R repeats) and torch's version and threads.
"""

import argparse
import statistics
import time

import torch
import torch.nn as nn

TRUNK, HIDDEN, SITES, FEATS, EMBED, SITE_HIDDEN = 108, 256, 30, 11, 16, 32
N, MINIBATCHES, EPOCHS = 4096, 8, 4


def mlp(n_in, n_out):
    return nn.Sequential(
        nn.Linear(n_in, HIDDEN), nn.Tanh(), nn.Linear(HIDDEN, HIDDEN), nn.Tanh(), nn.Linear(HIDDEN, n_out)
    )


class ActorCritic(nn.Module):
    def __init__(self):
        super().__init__()
        self.actor_body = nn.Sequential(nn.Linear(TRUNK, HIDDEN), nn.Tanh(), nn.Linear(HIDDEN, HIDDEN), nn.Tanh())
        self.actor_mean = nn.Linear(HIDDEN, 3)
        self.critic = mlp(TRUNK, 1)
        self.log_std = nn.Parameter(torch.zeros(3))
        self.embed = nn.Linear(HIDDEN, EMBED)
        self.site1 = nn.Linear(FEATS + EMBED, SITE_HIDDEN)
        self.site2 = nn.Linear(SITE_HIDDEN, 1)

    def forward(self, obs, feats):
        h = self.actor_body(obs)
        mean = self.actor_mean(h)
        value = self.critic(obs).squeeze(1)
        emb = torch.tanh(self.embed(h))
        w = self.site1.weight  # [SITE_HIDDEN, FEATS + EMBED]
        state = emb @ w[:, FEATS:].T + self.site1.bias  # [B, SITE_HIDDEN]
        pairs = feats.reshape(-1, SITES, FEATS) @ w[:, :FEATS].T  # [B, SITES, SITE_HIDDEN]
        logits = self.site2(torch.tanh(pairs + state.unsqueeze(1))).squeeze(2)
        return mean, value, torch.log_softmax(logits, 1)


def update(model, opt, data, gen):
    obs, feats, moves, oldlp, adv, ret, oldv, site_adv = data
    for _ in range(EPOCHS):
        order = torch.randperm(N, generator=gen)
        for mb in order.split(N // MINIBATCHES):
            mean, value, site_logp = model(obs[mb], feats[mb])
            std = model.log_std.exp()
            lp = (-0.5 * ((moves[mb] - mean) / std) ** 2).sum(1) - model.log_std.sum() - 1.5 * 1.8378770664093453
            a = adv[mb]
            a = (a - a.mean()) / (a.std() + 1e-8)
            ratio = (lp - oldlp[mb]).exp()
            pg = torch.max(-a * ratio, -a * ratio.clamp(0.8, 1.2)).mean()
            v_clipped = oldv[mb] + (value - oldv[mb]).clamp(-0.2, 0.2)
            v_loss = 0.5 * torch.max((value - ret[mb]) ** 2, (v_clipped - ret[mb]) ** 2).mean()
            sa = site_adv[mb]
            sa = sa / (sa.pow(2).mean().sqrt() + 1e-8)
            site_loss = -(site_logp.exp() * sa).sum(1).mean()
            loss = pg + 0.5 * v_loss + site_loss
            opt.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(model.parameters(), 0.5)
            opt.step()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    gen = torch.Generator().manual_seed(1)
    model = ActorCritic()
    opt = torch.optim.Adam(model.parameters(), lr=3e-4, eps=1e-5)
    r = lambda *s: torch.rand(*s, generator=gen) * 4 - 2  # noqa: E731
    site_adv = -torch.rand(N, SITES, generator=gen)
    data = (r(N, TRUNK), r(N, SITES * FEATS), r(N, 3), r(N) - 6, r(N), r(N), r(N), site_adv)
    update(model, opt, data, gen)  # warm-up
    times = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        update(model, opt, data, gen)
        times.append(time.perf_counter() - t0)
    med = statistics.median(times)
    print(
        f"torch {torch.__version__}, {torch.get_num_threads()} thread(s): update of {N} samples "
        f"{med * 1e3:.0f} ms (median of {args.repeats}) = {N / med:.0f} samples/s"
    )


if __name__ == "__main__":
    main()
