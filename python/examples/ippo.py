"""IPPO on coevo: predators and prey trained by a second algorithm, in one file (CleanRL style).

Independent PPO with parameters shared within a species (every prey acts with the prey network, every
predator with the predator network), on ``coevo.VecEnv``: the very worlds ``coevo --train`` trains in.
The question it answers: does swarming also emerge when the learning algorithm is not DDPG?

The policy's mean is a coevo-shaped actor (d_o -> 64 -> 64 -> 64 -> 2, ReLU, tanh on the output) with a
state-independent log standard deviation; the critic is d_o -> 64 -> 64 -> 64 -> 1. The run folder holds
what ``coevo --train`` writes and coevo's tools read:

    RUN/scene.ron                             the scene as trained
    RUN/metrics.csv                           one row per finished episode, coevo's columns (critic_loss =
                                              value loss, actor_loss = clipped policy loss, noise_std = the
                                              policy's mean standard deviation, epsilon = 0)
    RUN/checkpoint/<species>-actor.safetensors  the policy mean, in coevo's (PyTorch's) layout
    RUN/ippo.json                             provenance: these arguments, coevo's version and commit,
                                              the SHA-256 of the coevo extension that ran it, torch's version

so ``coevo --plot RUN`` draws its training curves and ``coevo --eval RUN --prey 50 --control
blind:prey:prey`` evaluates its deterministic policies (the mean) under coevo's controls, exactly as for a
DDPG run. Choices the paper does not make are named below. Episodes end by truncation at episode_steps,
not by a terminal state: the value of the state the episode was cut in (``infos["final_obs"]``) is added,
discounted, to the last reward (as Stable-Baselines3 does on timeouts), so the time limit is not taught as
death; ``--bootstrap-truncation false`` treats it as terminal, as the documented runs of
docs/src/guide/python.md were made (and CleanRL's PPO does).

    pip install ./python torch safetensors
    python python/examples/ippo.py --seed 1 --out runs/ippo-seed1
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import time
from dataclasses import asdict, dataclass

import numpy as np
import torch
import torch.nn as nn
from safetensors.torch import save_file

import coevo


@dataclass
class Args:
    scene: str = "scenes/standard.ron"
    seed: int = 1
    out: str = "runs/ippo-seed1"
    counts: str = ""  # species counts for training, e.g. "predator=0" (the control without predators)
    num_envs: int = 32  # worlds stepped together (world 0 from the seed, world i from coevo.world_seed(seed, i))
    # "consecutive" (world i from seed + i) reproduces the runs of docs/src/results/ippo/, made before
    # VecEnv seeded its worlds independently: their seeds 1, 2 and 3 shared 30 of 32 worlds' episode starts.
    world_seeds: str = "independent"
    # Bootstrap from the value of the last state at the time limit (False: the limit is terminal, as the
    # documented runs were made).
    bootstrap_truncation: bool = True
    num_steps: int = 128  # rollout length per world and update
    total_world_steps: int = 2_000_000  # summed over worlds: 4000 episodes of 500 steps (DDPG: 2000)
    learning_rate: float = 3e-4
    anneal_lr: bool = True
    gamma: float = 0.99
    gae_lambda: float = 0.95
    update_epochs: int = 4
    num_minibatches: int = 4  # per species and epoch
    clip_coef: float = 0.2
    ent_coef: float = 0.0
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    hidden: int = 64  # coevo's actor width (Appendix B: three hidden layers of 64)
    init_log_std: float = -0.5
    torch_threads: int = 1
    threads: int = 0  # threads stepping the worlds (0: every core, or COEVO_THREADS)
    # Species coevo keeps training with its own DDPG (Algorithm 1) in the same worlds while PPO trains the rest,
    # e.g. "predator": PPO prey against predators that keep learning. Each world's predators learn from that
    # world alone; world 0's are saved as a run folder, OUT/coevo-world0, at the end. OUT's checkpoint then
    # holds the PPO species' actors only: evaluate them in a scene whose predators are
    # Frozen("OUT/coevo-world0") (`coevo --eval OUT` would look for a predator actor in OUT).
    coevolve: str = ""
    # or "frozen", or "alternate:K": coevo's side learns K episodes, then is held K; PPO learns throughout.
    coevolve_schedule: str = "learning"
    # Measure the prey's learning as the recipes do (recipe_common.py): catches per episode of the
    # deterministic policy on fixed evaluation worlds, as initialised and as trained, into OUT/catches.json.
    # For a scene where only the prey learn (scenes/prey-vs-chasers.ron).
    catches: bool = False


def mlp(d_in: int, hidden: int, d_out: int, tanh_out: bool) -> nn.Sequential:
    """coevo's network shape; the indices 0, 2, 4, 6 of the linear layers are the safetensors names."""
    layers: list[nn.Module] = [nn.Linear(d_in, hidden), nn.ReLU(), nn.Linear(hidden, hidden), nn.ReLU(),
                               nn.Linear(hidden, hidden), nn.ReLU(), nn.Linear(hidden, d_out)]
    if tanh_out:
        layers.append(nn.Tanh())
    return nn.Sequential(*layers)


class Agent(nn.Module):
    """One species' shared policy and value function."""

    def __init__(self, obs_dim: int, args: Args):
        super().__init__()
        self.actor_mean = mlp(obs_dim, args.hidden, 2, tanh_out=True)
        self.actor_log_std = nn.Parameter(torch.full((2,), args.init_log_std))
        self.critic = mlp(obs_dim, args.hidden, 1, tanh_out=False)

    def value(self, obs: torch.Tensor) -> torch.Tensor:
        return self.critic(obs).squeeze(-1)

    def act(self, obs: torch.Tensor, action: torch.Tensor | None = None):
        mean = self.actor_mean(obs)
        dist = torch.distributions.Normal(mean, self.actor_log_std.exp().expand_as(mean))
        if action is None:
            action = dist.sample()
        return action, dist.log_prob(action).sum(-1), dist.entropy().sum(-1), self.value(obs)


def save_actor(agent: Agent, path: str) -> None:
    """The policy mean as coevo's actor file (tensor names 0.weight … 6.bias, as coevo writes them)."""
    tensors = {k: v.detach().contiguous() for k, v in agent.actor_mean.state_dict().items()}
    tmp = path + ".tmp"
    save_file(tensors, tmp)
    os.replace(tmp, path)


def main(args: Args) -> None:
    torch.manual_seed(args.seed)
    torch.set_num_threads(args.torch_threads)
    rng = np.random.default_rng(args.seed)
    counts = {k: int(v) for k, v in (c.split("=") for c in args.counts.split(",") if c)}
    coevolve = [c for c in args.coevolve.split(",") if c] or None
    env = coevo.VecEnv(args.scene, num_envs=args.num_envs, seed=args.seed, counts=counts, world_seeds=args.world_seeds,
                       threads=args.threads or None, coevolve=coevolve, coevolve_schedule=args.coevolve_schedule)
    # coevo names the run folder's files (scene.ron, metrics.csv, the checkpoint's actors); a folder that
    # holds anything is refused.
    run = coevo.RunFolder.create(args.out, coevo.parallel_env(args.scene, seed=args.seed, counts=counts).scene_ron())
    with open(coevo._coevo.__file__, "rb") as f:
        extension = hashlib.sha256(f.read()).hexdigest()[:16]
    with open(os.path.join(run.path, "ippo.json"), "w") as f:
        json.dump({"algorithm": "ippo", "args": asdict(args), "coevo_version": coevo.__version__,
                   "coevo_git_commit": coevo.git_commit, "coevo_extension_sha256": extension,
                   "torch": torch.__version__}, f, indent=1)
    # The learning species in metrics.csv's order (a species may have no agents: "predator=0").
    header = env.metrics_header()
    learning = [c[len("critic_loss_"):] for c in header.split(",") if c.startswith("critic_loss_")]
    species = [s for s in learning if any(a.rsplit("_", 1)[0] == s for a in env.agents)]
    rows_of = {s: np.array([i for i, a in enumerate(env.agents) if a.rsplit("_", 1)[0] == s]) for s in species}
    agents = {s: Agent(env.obs_dim, args) for s in learning}  # one without agents stays as initialised
    optims = {s: torch.optim.Adam(agents[s].parameters(), lr=args.learning_rate, eps=1e-5) for s in species}

    n_agents, d = len(env.agents), env.obs_dim
    shape = (args.num_steps, args.num_envs, n_agents)
    obs_buf = np.zeros(shape + (d,), np.float32)
    act_buf = np.zeros(shape + (2,), np.float32)
    logp_buf, rew_buf, val_buf = (np.zeros(shape, np.float32) for _ in range(3))
    done_buf = np.zeros(shape[:2], np.float32)

    metrics = open(run.metrics, "w")
    metrics.write(header + "\n")
    losses = {s: ("", "", "") for s in learning}  # value loss, policy loss, std of the latest update
    started = time.time()

    if args.catches:
        import recipe_common

        if species != ["prey"]:
            raise SystemExit(f"--catches: the prey must be the only species PPO trains, not {species}")

        def deterministic(obs: np.ndarray) -> np.ndarray:
            with torch.no_grad():
                return agents["prey"].actor_mean(torch.from_numpy(obs)).numpy()

        untrained = recipe_common.catches_per_episode(deterministic, args.scene)
    obs = env.reset()
    done = np.zeros(args.num_envs, np.float32)
    iterations = args.total_world_steps // (args.num_envs * args.num_steps)
    for it in range(iterations):
        if args.anneal_lr:
            for o in optims.values():
                o.param_groups[0]["lr"] = (1.0 - it / iterations) * args.learning_rate
        # Rollout: every agent of every world acts with its species' network.
        for t in range(args.num_steps):
            obs_buf[t], done_buf[t] = obs, done
            actions = np.zeros((args.num_envs, n_agents, 2), np.float32)
            with torch.no_grad():
                for s in species:
                    o = torch.from_numpy(obs[:, rows_of[s]])
                    a, logp, _, v = agents[s].act(o)
                    actions[:, rows_of[s]] = a.numpy()
                    logp_buf[t][:, rows_of[s]], val_buf[t][:, rows_of[s]] = logp.numpy(), v.numpy()
            act_buf[t] = actions
            obs, rewards, truncated, infos = env.step(np.clip(actions, -1.0, 1.0))
            if args.bootstrap_truncation and truncated.any():
                # The episode was cut, not ended: its last state's value, discounted, stands in for the
                # return after it (the GAE below stops at the boundary either way).
                with torch.no_grad():
                    for w in np.flatnonzero(truncated):
                        last = infos["final_obs"][w]
                        for s in species:
                            v = agents[s].value(torch.from_numpy(last[rows_of[s]])).numpy()
                            rewards[w, rows_of[s]] += args.gamma * v
            rew_buf[t], done = rewards, truncated.astype(np.float32)
            for row in env.take_episode_rows():
                cells = [row]
                for s in learning:
                    v_loss, p_loss, std = losses[s]
                    cells.append(f"{v_loss},{p_loss},{std},0")
                metrics.write(",".join(cells) + f",{time.time() - started:.3f}\n")
        metrics.flush()
        # GAE per agent, then a PPO update per species on its agents' samples.
        with torch.no_grad():
            next_val = np.zeros((args.num_envs, n_agents), np.float32)
            for s in species:
                next_val[:, rows_of[s]] = agents[s].value(torch.from_numpy(obs[:, rows_of[s]])).numpy()
        adv = np.zeros(shape, np.float32)
        last = np.zeros((args.num_envs, n_agents), np.float32)
        for t in reversed(range(args.num_steps)):
            not_done = 1.0 - (done if t == args.num_steps - 1 else done_buf[t + 1])[:, None]
            nv = next_val if t == args.num_steps - 1 else val_buf[t + 1]
            delta = rew_buf[t] + args.gamma * nv * not_done - val_buf[t]
            last = delta + args.gamma * args.gae_lambda * not_done * last
            adv[t] = last
        ret = adv + val_buf
        for s in species:
            cols = rows_of[s]
            b_obs = torch.from_numpy(obs_buf[:, :, cols].reshape(-1, d))
            b_act = torch.from_numpy(act_buf[:, :, cols].reshape(-1, 2))
            b_logp = torch.from_numpy(logp_buf[:, :, cols].reshape(-1))
            b_adv = torch.from_numpy(adv[:, :, cols].reshape(-1))
            b_ret = torch.from_numpy(ret[:, :, cols].reshape(-1))
            n = b_obs.shape[0]
            mb = n // args.num_minibatches
            for _ in range(args.update_epochs):
                order = rng.permutation(n)
                for start in range(0, n, mb):
                    idx = torch.from_numpy(order[start:start + mb])
                    _, logp, entropy, value = agents[s].act(b_obs[idx], b_act[idx])
                    ratio = (logp - b_logp[idx]).exp()
                    a = b_adv[idx]
                    a = (a - a.mean()) / (a.std() + 1e-8)
                    pg_loss = torch.max(-a * ratio, -a * ratio.clamp(1 - args.clip_coef, 1 + args.clip_coef)).mean()
                    v_loss = 0.5 * ((value - b_ret[idx]) ** 2).mean()
                    loss = pg_loss - args.ent_coef * entropy.mean() + args.vf_coef * v_loss
                    optims[s].zero_grad()
                    loss.backward()
                    nn.utils.clip_grad_norm_(agents[s].parameters(), args.max_grad_norm)
                    optims[s].step()
            losses[s] = (f"{v_loss.item()}", f"{pg_loss.item()}", f"{agents[s].actor_log_std.exp().mean().item()}")
        if (it + 1) % 50 == 0 or it + 1 == iterations:
            for s in learning:
                save_actor(agents[s], run.actor(s))
            print(f"iteration {it + 1}/{iterations}, {(it + 1) * args.num_envs * args.num_steps} world steps, "
                  f"{time.time() - started:.0f} s", flush=True)
    metrics.close()
    if args.catches:
        recipe_common.write_result(args.out, "cleanrl", args.seed, untrained,
                                   recipe_common.catches_per_episode(deterministic, args.scene),
                                   world_steps=iterations * args.num_envs * args.num_steps, copies=args.num_envs,
                                   seconds=round(time.time() - started, 1), torch=torch.__version__)
    if coevolve:
        # coevo's side of world 0, saved between episodes: the policies play on until its episode ends.
        while True:
            actions = np.zeros((args.num_envs, n_agents, 2), np.float32)
            with torch.no_grad():
                for s in species:
                    actions[:, rows_of[s]] = agents[s].act(torch.from_numpy(obs[:, rows_of[s]]))[0].numpy()
            obs, _, truncated, _ = env.step(np.clip(actions, -1.0, 1.0))
            if truncated[0]:
                break
        env.save_run(0, os.path.join(run.path, "coevo-world0"))


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    for field, default in Args.__dataclass_fields__.items():
        kind = type(default.default)
        if kind is bool:
            parser.add_argument(f"--{field.replace('_', '-')}", type=lambda x: x.lower() in ("1", "true", "yes"),
                                default=default.default)
        else:
            parser.add_argument(f"--{field.replace('_', '-')}", type=kind, default=default.default)
    main(Args(**vars(parser.parse_args())))
