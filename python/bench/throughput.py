"""Throughput of the Python package (`python python/bench/throughput.py [SECONDS]`): env steps per second of the
PettingZoo env (3 + 10 agents, dict in and out) and of VecEnv (64 and 1 024 worlds of 3 + 10, world steps
summed), and of vector_env (64 worlds, Gymnasium's API). VecEnv uses every core unless COEVO_THREADS says
otherwise (`COEVO_THREADS=1 python ...`)."""

import os

import numpy as np
from timing import rate

import coevo

SCENE = os.path.join(os.path.dirname(__file__), "..", "..", "scenes", "standard.ron")

env = coevo.parallel_env(SCENE)
env.reset()
actions = {a: np.full(2, 0.5, np.float32) for a in env.possible_agents}


def pettingzoo_step():
    if not env.agents:
        env.reset()
    env.step(actions)


print(f"PettingZoo parallel_env, 3+10 agents: {rate(pettingzoo_step):10.0f} env steps/s")
threads = os.environ.get("COEVO_THREADS", f"default ({os.cpu_count()} cores)")
for worlds in (64, 1024):
    vec = coevo.VecEnv(SCENE, num_envs=worlds, seed=1)
    vec.reset()
    batch = np.full((vec.num_envs, len(vec.agents), 2), 0.5, np.float32)
    per_second = vec.num_envs * rate(lambda: vec.step(batch))
    print(f"VecEnv, {worlds:4d} worlds of 3+10, threads {threads}: {per_second:10.0f} world steps/s (summed over worlds)")
# The same worlds as a gymnasium.vector.VectorEnv (one row per agent, NEXT_STEP autoreset): its reshape,
# the rewards as float64 and the per-row infos on top of VecEnv's step.
for worlds in (64,):
    gym = coevo.vector_env(SCENE, num_worlds=worlds, seed=1)
    gym.reset()
    rows = np.full((gym.num_envs, 2), 0.5, np.float32)
    per_second = worlds * rate(lambda: gym.step(rows))
    print(f"vector_env, {worlds:4d} worlds of 3+10, threads {threads}: {per_second:10.0f} world steps/s (summed over worlds)")
