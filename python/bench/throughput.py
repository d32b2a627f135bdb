"""Throughput of the Python package (`python python/bench/throughput.py`): env steps per second of the PettingZoo
env (3 + 10 agents, dict in and out) and of VecEnv (64 worlds of 3 + 10, world steps summed)."""

import os
import sys
import time

import numpy as np

import coevo

SCENE = os.path.join(os.path.dirname(__file__), "..", "..", "scenes", "standard.ron")
SECONDS = float(sys.argv[1]) if len(sys.argv) > 1 else 3.0


def rate(step, seconds=SECONDS):
    n, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        step()
        n += 1
    return n / (time.perf_counter() - start)


env = coevo.parallel_env(SCENE)
env.reset()
actions = {a: np.full(2, 0.5, np.float32) for a in env.possible_agents}


def pettingzoo_step():
    if not env.agents:
        env.reset()
    env.step(actions)


print(f"PettingZoo parallel_env, 3+10 agents: {rate(pettingzoo_step):10.0f} env steps/s")
vec = coevo.VecEnv(SCENE, num_envs=64, seed=1)
vec.reset()
batch = np.full((vec.num_envs, len(vec.agents), 2), 0.5, np.float32)
print(f"VecEnv, 64 worlds of 3+10:            {vec.num_envs * rate(lambda: vec.step(batch)):10.0f} env steps/s (summed over worlds)")
