"""Stable-Baselines3 PPO trains the prey through SuperSuit, PettingZoo's route, against predators that do
not learn (``scenes/prey-vs-chasers.ron``): every prey is a sub-environment of one vector env, and one
policy (the prey's) acts for all of them.

    pip install ./python torch stable-baselines3 supersuit
    python python/examples/recipe_sb3.py --seed 1 --out runs/sb3-seed1

Seeding: SuperSuit seeds copy i of the env with base + i, so runs seeded S and S + 1 with a plain base S
would share copies; the base is ``recipe_common.training_seed(S)``, a mixed 63-bit number, so runs of
different seeds share no world. The copies are seeded beneath SuperSuit's SB3 wrapper (``vec.venv``),
whose own ``seed()`` fails in SuperSuit 3.11. Writes ``OUT/catches.json`` (``recipe_common``) and the
trained policy as ``OUT/sb3-prey.zip``.
"""

from __future__ import annotations

import os
import time

import supersuit as ss
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.utils import set_random_seed

import coevo
from recipe_common import SCENE, arguments, catches_per_episode, training_seed, write_result


def main() -> None:
    a = arguments(__doc__.splitlines()[0], "sb3", copies=8)
    torch.set_num_threads(1)
    started = time.time()
    env = coevo.parallel_env(SCENE, episode_steps=500)
    prey = len(env.possible_agents)  # only the prey learn: they are the whole batch
    vec = ss.pettingzoo_env_to_vec_env_v1(env)
    vec = ss.concat_vec_envs_v1(vec, a.copies, num_cpus=0, base_class="stable_baselines3")
    vec.venv.reset(seed=training_seed(a.seed))  # copy i from base + i
    set_random_seed(a.seed)  # the policy's initialisation and sampling
    model = PPO("MlpPolicy", vec, n_steps=128, batch_size=1024, learning_rate=3e-4, gamma=0.99, verbose=0)
    act = lambda obs: model.predict(obs, deterministic=True)[0]  # noqa: E731
    untrained = catches_per_episode(act)
    model.learn(total_timesteps=a.world_steps * prey)
    trained = catches_per_episode(act)
    os.makedirs(a.out, exist_ok=True)
    model.save(os.path.join(a.out, "sb3-prey.zip"))
    # SB3 stops at the end of a rollout: the world steps taken, not those asked for.
    write_result(a.out, "sb3", a.seed, untrained, trained, world_steps=model.num_timesteps // prey, copies=a.copies,
                 seconds=round(time.time() - started, 1), torch=torch.__version__,
                 stable_baselines3=__import__("stable_baselines3").__version__, supersuit=ss.__version__)


if __name__ == "__main__":
    main()
