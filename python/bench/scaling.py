"""World steps per second on one thread as the number of worlds grows (`python python/bench/scaling.py
[SECONDS] [ROUNDS]`): VecEnv of the default scene at 8, 64, 1 024 and 4 096 worlds of 3 + 10, actions
fixed, world steps summed over the worlds. Flat would mean a world's step costs the same however many
worlds there are.

The sizes are timed in turn, round after round (SECONDS each, default 1; ROUNDS rounds, default 5), so a
change in the machine's speed (other work on a shared machine) touches every size alike: each round's
rates are divided by that round's rate at 8 worlds, and the medians over rounds are printed."""

import os
import statistics
import sys

import numpy as np
from timing import rate

import coevo

SCENE = os.path.join(os.path.dirname(__file__), "..", "..", "scenes", "standard.ron")
SECONDS = float(sys.argv[1]) if len(sys.argv) > 1 else 1.0
ROUNDS = int(sys.argv[2]) if len(sys.argv) > 2 else 5
SIZES = (8, 64, 1024, 4096)

worlds = {}
for n in SIZES:
    vec = coevo.VecEnv(SCENE, num_envs=n, seed=1, threads=1)
    vec.reset()
    worlds[n] = (vec, np.full((n, len(vec.agents), 2), 0.5, np.float32))

rates = {n: [] for n in SIZES}
for _ in range(ROUNDS):
    for n, (vec, batch) in worlds.items():
        rates[n].append(n * rate(lambda: vec.step(batch), SECONDS))

for n in SIZES:
    ratios = [r / r8 for r, r8 in zip(rates[n], rates[8])]
    print(f"VecEnv, {n:4d} worlds of 3+10, one thread: median {statistics.median(rates[n]):8.0f} world steps/s "
          f"({min(rates[n]):.0f}–{max(rates[n]):.0f}); of the rate at 8 worlds in the same round: median "
          f"{statistics.median(ratios):.3f} ({min(ratios):.3f}–{max(ratios):.3f})")
