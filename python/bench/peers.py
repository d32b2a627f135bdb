"""The peers coevo's Python package is compared with on the benchmarks page, on this machine:
`python python/bench/peers.py [SECONDS]` in an environment with `pip install mpe2 vmas` (VMAS brings PyTorch).

Both with 3 predators (adversaries) and 10 prey (good agents), as coevo's standard scene, random continuous
actions, no obstacles or landmarks. PettingZoo MPE `simple_tag_v3` (from `mpe2`, where MPE now lives): one
env, dicts in and out, env steps per second. VMAS `simple_tag` on the CPU: 64 and 1 024 worlds stepped as
one batch, world steps per second summed over worlds. Torch's own thread count is its default (every core).
"""

from mpe2 import simple_tag_v3
from timing import rate

mpe = simple_tag_v3.parallel_env(num_good=10, num_adversaries=3, num_obstacles=0, max_cycles=500, continuous_actions=True)
mpe.reset(seed=1)


def mpe_step():
    if not mpe.agents:
        mpe.reset()
    mpe.step({a: mpe.action_space(a).sample() for a in mpe.agents})


print(f"PettingZoo MPE simple_tag_v3, 3+10 agents:  {rate(mpe_step):10.0f} env steps/s")

import torch  # noqa: E402
import vmas  # noqa: E402

for worlds in (64, 1024):
    env = vmas.make_env("simple_tag", num_envs=worlds, device="cpu", continuous_actions=True, seed=1,
                        num_good_agents=10, num_adversaries=3, num_landmarks=0)
    env.reset()
    actions = [torch.rand(worlds, 2) * 2 - 1 for _ in env.agents]
    print(f"VMAS simple_tag (CPU), {worlds:4d} worlds of 3+10: {worlds * rate(lambda: env.step(actions)):10.0f} world steps/s")
