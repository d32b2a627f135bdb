"""A coevo run's actors in PyTorch, driven through the Python env on 50 prey, against ``coevo --eval``.

The actor files are safetensors in PyTorch's layout (``0.weight`` … ``6.bias``): ``nn.Sequential`` of
Linear-ReLU ×3, Linear, Tanh loads them as they are. Each episode's DoA (mean over its last 50 steps, as
coevo's evaluations settle it) is compared with coevo's own evaluation of the same run, seed and episodes;
the two start from the same state and differ only by float rounding in the products (PyTorch's and coevo's
kernels sum in different orders), which chaos amplifies over an episode: the agreement to expect is
within sampling error, not bit for bit (``python/tests`` checks the early steps to 1e-4).

    pip install ./python torch
    python python/examples/roundtrip.py assets/trained-standard --episodes 20
"""

from __future__ import annotations

import argparse
import csv
import os
import shutil
import subprocess
import tempfile

import numpy as np
import torch
import torch.nn as nn
from safetensors.torch import load_file

import coevo


def actor(path: str, obs_dim: int, hidden: int = 64) -> nn.Sequential:
    net = nn.Sequential(nn.Linear(obs_dim, hidden), nn.ReLU(), nn.Linear(hidden, hidden), nn.ReLU(),
                        nn.Linear(hidden, hidden), nn.ReLU(), nn.Linear(hidden, 2), nn.Tanh())
    net.load_state_dict(load_file(path))
    return net.eval()


def settled(doa: list[float], last: int = 50) -> float:
    return float(np.mean(doa[-last:]))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("run")
    p.add_argument("--episodes", type=int, default=20)
    p.add_argument("--steps", type=int, default=500)
    p.add_argument("--prey", type=int, default=50)
    p.add_argument("--coevo", default=os.environ.get("COEVO_BIN", "target/release/coevo"))
    a = p.parse_args()

    env = coevo.parallel_env(os.path.join(a.run, "scene.ron"), counts={"prey": a.prey}, episode_steps=a.steps)
    d = env.observation_space(env.possible_agents[0]).shape[0]
    species = sorted({x.rsplit("_", 1)[0] for x in env.possible_agents})
    nets = {s: actor(os.path.join(a.run, "checkpoint", f"{s}-actor.safetensors"), d) for s in species}
    python_doa = []
    for episode in range(a.episodes):
        obs, _ = env.reset()  # the first from the scene's seed, then the same stream, as --eval does
        doa = []
        while env.agents:
            with torch.no_grad():
                actions = {x: nets[x.rsplit("_", 1)[0]](torch.from_numpy(obs[x])).numpy() for x in env.agents}
            obs, _, _, _, infos = env.step(actions)
            doa.append(next(iter(infos.values()))["doa"])
        python_doa.append(settled(doa))

    with tempfile.TemporaryDirectory() as tmp:
        run = os.path.join(tmp, "run")
        shutil.copytree(a.run, run)
        subprocess.run([a.coevo, "--eval", run, "--prey", str(a.prey), "--episodes", str(a.episodes), "--steps",
                        str(a.steps)], check=True, capture_output=True)
        per_episode: dict[int, list[float]] = {}
        with open(os.path.join(run, "eval.csv")) as f:
            for row in csv.DictReader(f):
                per_episode.setdefault(int(row["episode"]), []).append(float(row["doa_prey"]))
        coevo_doa = [settled(per_episode[e]) for e in sorted(per_episode)]

    def ci(x: list[float]) -> str:
        x = np.asarray(x)
        return f"{x.mean():.4f} ± {1.96 * x.std(ddof=1) / np.sqrt(len(x)):.4f}"

    diff = np.asarray(python_doa) - np.asarray(coevo_doa)
    print(f"DoA on {a.prey} prey, last 50 of {a.steps} steps, {a.episodes} episodes (mean ± 1.96 SE):")
    print(f"  PyTorch through the Python env: {ci(python_doa)}")
    print(f"  coevo --eval:                   {ci(coevo_doa)}")
    print(f"  paired difference:              {ci(list(diff))}  (max |difference| {np.abs(diff).max():.4f})")


if __name__ == "__main__":
    main()
