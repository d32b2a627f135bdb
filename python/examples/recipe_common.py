"""What the three recipes (recipe_sb3.py, recipe_torchrl.py, ippo.py --catches) share: the scene they train
prey in, and the one number by which each shows that it learned.

The scene is ``scenes/prey-vs-chasers.ron``: the default scene with predators that do not learn (each
steers for the nearest prey it sees), so only the prey are in the batch and one policy is the prey's.

**The measure.** Catches per episode of the prey's deterministic policy (the mean action, no sampling) on
the same evaluation worlds for every run: ``EVAL_WORLDS`` worlds of a VecEnv seeded ``EVAL_SEED`` (a seed
no training run uses), ``EVAL_EPISODES`` whole episodes each. Each run measures its policy twice on them,
as initialised and as trained: *trained minus untrained* is its learning, in catches per episode.
``recipes_summary.py`` judges it over the seeds of each route (``docs/src/guide/python.md``).
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

import coevo

HERE = os.path.dirname(os.path.abspath(__file__))
SCENE = os.path.join(HERE, "..", "..", "scenes", "prey-vs-chasers.ron")
EVAL_SEED = 777_000_001
EVAL_WORLDS = 8
EVAL_EPISODES = 2


def arguments(description: str, route: str, copies: int) -> argparse.Namespace:
    """A recipe's flags: ``--seed``, ``--out`` (default ``runs/ROUTE-seedS``), ``--world-steps`` (summed over
    the worlds stepped together) and ``--copies`` (those worlds)."""
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--out", default=None, help=f"the run's folder (default runs/{route}-seed<seed>)")
    p.add_argument("--world-steps", type=int, default=100_000, help="world steps summed over the copies")
    p.add_argument("--copies", type=int, default=copies, help="worlds stepped together")
    a = p.parse_args()
    a.out = a.out or f"runs/{route}-seed{a.seed}"
    return a


def training_seed(seed: int) -> int:
    """The base seed a route gives its worlds for the run seeded ``seed``: SplitMix64-mixed
    (``coevo.world_seed``), so that routes that seed copy i with base + i (SuperSuit) share no world
    between runs of neighbouring seeds; kept under 2⁶³ so that base + i stays a seed."""
    return coevo.world_seed(seed, 1) % (1 << 63)


def catches_per_episode(act, scene: str = SCENE, worlds: int = EVAL_WORLDS, episodes: int = EVAL_EPISODES) -> float:
    """Mean catches per episode when ``act`` (observations ``[rows, d_o]`` float32 -> actions ``[rows, 2]``)
    decides every prey of the evaluation worlds, over ``episodes`` whole episodes of each."""
    env = coevo.VecEnv(scene, num_envs=worlds, seed=EVAL_SEED, threads=1)
    column = env.metrics_header().split(",").index("catches")
    obs = env.reset()
    catches = []
    while len(catches) < worlds * episodes:
        actions = np.asarray(act(obs.reshape(-1, obs.shape[-1])), dtype=np.float32).reshape(obs.shape[0], obs.shape[1], 2)
        obs, _, _, _ = env.step(np.clip(actions, -1.0, 1.0))
        catches += [float(row.split(",")[column]) for row in env.take_episode_rows()]
    env.close()
    return float(np.mean(catches[: worlds * episodes]))


def write_result(out: str, route: str, seed: int, untrained: float, trained: float, **extra) -> None:
    """``OUT/catches.json``: the run's route, seed, catches per episode untrained and trained, and what made it."""
    os.makedirs(out, exist_ok=True)
    result = {
        "route": route,
        "seed": seed,
        "catches_untrained": untrained,
        "catches_trained": trained,
        "trained_minus_untrained": trained - untrained,
        "eval": {"seed": EVAL_SEED, "worlds": EVAL_WORLDS, "episodes": EVAL_EPISODES, "scene": "scenes/prey-vs-chasers.ron"},
        "coevo": coevo.__version__,
        "coevo_commit": coevo.git_commit,
        "written": time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime()),
        **extra,
    }
    path = os.path.join(out, "catches.json")
    with open(path + ".tmp", "w") as f:
        json.dump(result, f, indent=1)
        f.write("\n")
    os.replace(path + ".tmp", path)
    print(f"{route} seed {seed}: catches per episode {untrained:.1f} untrained -> {trained:.1f} trained")
