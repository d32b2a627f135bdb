"""World steps per second on one thread as the number of worlds grows (`python python/bench/scaling.py
[SECONDS]`): VecEnv of the default scene at 8, 64, 1 024 and 4 096 worlds of 3 + 10, actions fixed, world
steps summed over the worlds. Flat would mean a world's step costs the same however many worlds there are."""

import os

import numpy as np
from timing import rate

import coevo

SCENE = os.path.join(os.path.dirname(__file__), "..", "..", "scenes", "standard.ron")

for worlds in (8, 64, 1024, 4096):
    vec = coevo.VecEnv(SCENE, num_envs=worlds, seed=1, threads=1)
    vec.reset()
    batch = np.full((worlds, len(vec.agents), 2), 0.5, np.float32)
    print(f"VecEnv, {worlds:4d} worlds of 3+10, one thread: {worlds * rate(lambda: vec.step(batch)):10.0f} world steps/s")
    vec.close()
