"""PyTorch peer of host-train's learner benchmark: the same networks (paper sizes, ELU,
torch's default init), batch, losses and optimizer steps as `benches/learner.rs`, on the
CPU with a given thread count. Prints median step times as JSON.

The discriminator's gradient penalty uses autograd's double backward
(`torch.autograd.grad(create_graph=True)`), as AMP_for_hardware does.
"""
import argparse
import json
import time

import torch
from torch import nn


def mlp(sizes):
    layers = []
    for i in range(len(sizes) - 1):
        layers.append(nn.Linear(sizes[i], sizes[i + 1]))
        if i < len(sizes) - 2:
            layers.append(nn.ELU())
    return nn.Sequential(*layers)


class ActorCritic(nn.Module):
    def __init__(self):
        super().__init__()
        self.estimator = mlp([210, 64, 32, 3])
        self.memory = mlp([210, 512, 256, 128, 16])
        self.actor = mlp([63 + 3 + 16, 256, 128, 64, 18])
        self.log_std = nn.Parameter(torch.zeros(18))
        self.privileged_encoder = mlp([42, 64, 32, 8])
        self.terrain_encoder = mlp([187, 256, 128, 16])
        self.critic = mlp([63 + 8 + 16, 512, 256, 128, 1])
        for name, dim in [("actor_obs", 63), ("history", 210), ("privileged", 42), ("heights", 187)]:
            self.register_buffer(f"{name}_mean", torch.zeros(dim))
            self.register_buffer(f"{name}_std", torch.ones(dim))

    def norm(self, name, x):
        return (x - getattr(self, f"{name}_mean")) / getattr(self, f"{name}_std")

    def policy(self, actor_obs, history):
        a = self.norm("actor_obs", actor_obs)
        h = self.norm("history", history)
        v_hat = self.estimator(h)
        latent = self.memory(h)
        mean = self.actor(torch.cat([a, v_hat.detach(), latent], dim=1))
        return mean, v_hat

    def value(self, actor_obs, privileged, heights):
        a = self.norm("actor_obs", actor_obs)
        lp = self.privileged_encoder(self.norm("privileged", privileged))
        le = self.terrain_encoder(self.norm("heights", heights))
        return self.critic(torch.cat([a, lp, le], dim=1)).squeeze(1)


def ppo_step(ac, opt, mb, old_log_std, clip=0.2):
    mean, v_hat = ac.policy(mb["actor"], mb["history"])
    with torch.no_grad():
        std, old_std = ac.log_std.exp(), old_log_std.exp()
        kl = torch.sum(
            torch.log(std / old_std) + (old_std.pow(2) + (mb["old_mean"] - mean).pow(2)) / (2.0 * std.pow(2)) - 0.5,
            dim=-1,
        ).mean()
    dist = torch.distributions.Normal(mean, ac.log_std.exp())
    logp = dist.log_prob(mb["actions"]).sum(dim=-1)
    entropy = dist.entropy().sum(dim=-1)
    values = ac.value(mb["actor"], mb["privileged"], mb["heights"])
    ratio = torch.exp(logp - mb["old_log_probs"])
    adv = mb["advantages"]
    surrogate = torch.max(-adv * ratio, -adv * torch.clamp(ratio, 1 - clip, 1 + clip)).mean()
    v_clipped = mb["old_values"] + (values - mb["old_values"]).clamp(-clip, clip)
    value_loss = torch.max((values - mb["returns"]).pow(2), (v_clipped - mb["returns"]).pow(2)).mean()
    est_loss = (v_hat - mb["privileged"][:, 0:3]).pow(2).mean()
    loss = surrogate + value_loss - 0.01 * entropy.mean() + est_loss
    opt.zero_grad()
    loss.backward()
    nn.utils.clip_grad_norm_(ac.parameters(), 1.0)
    opt.step()
    return float(loss.item()) + float(kl.item()) * 0.0


def disc_step(disc, opt, prior, policy, alpha_gp=10.0):
    prior = prior.clone().requires_grad_(True)
    d_prior = disc(prior)
    d_policy = disc(policy)
    ls = 0.5 * ((d_prior - 1).pow(2).mean() + (d_policy + 1).pow(2).mean())
    grad = torch.autograd.grad(d_prior.sum(), prior, create_graph=True)[0]
    penalty = 0.5 * alpha_gp * grad.pow(2).sum(dim=1).mean()
    loss = ls + penalty
    opt.zero_grad()
    loss.backward()
    opt.step()
    return float(loss.item())


def timed(reps, f):
    f()
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    times.sort()
    return times[len(times) // 2]


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--batch", type=int, default=24576)
    p.add_argument("--reps", type=int, default=5)
    p.add_argument("--threads", type=int, default=2)
    args = p.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    b = args.batch

    def r(*shape):
        return torch.rand(*shape) * 2 - 1

    ac = ActorCritic()
    opt = torch.optim.Adam(ac.parameters(), lr=1e-3)
    mb = {
        "actor": r(b, 63), "history": r(b, 210), "privileged": r(b, 42), "heights": r(b, 187),
        "actions": r(b, 18), "old_mean": r(b, 18), "old_log_probs": r(b), "advantages": r(b),
        "old_values": r(b), "returns": r(b),
    }
    old_log_std = ac.log_std.detach().clone()
    ppo_s = timed(args.reps, lambda: ppo_step(ac, opt, mb, old_log_std))

    disc = mlp([122, 1024, 512, 1])
    dopt = torch.optim.Adam(disc.parameters(), lr=1e-4)
    prior, policy = r(b, 122), r(b, 122)
    disc_s = timed(args.reps, lambda: disc_step(disc, dopt, prior, policy))
    print(json.dumps({"ppo_step_s": ppo_s, "disc_step_s": disc_s, "threads": torch.get_num_threads(),
                      "torch": torch.__version__}))


if __name__ == "__main__":
    main()
