"""TorchRL trains the prey with PPO (independent learners sharing one policy, TorchRL's multi-agent PPO
recipe) through its PettingZoo wrapper, against predators that do not learn
(``scenes/prey-vs-chasers.ron``): the prey are one group, ``("prey", "observation")`` in, ``("prey",
"action")`` out, their rewards ``("prey", "reward")``.

    pip install ./python torch torchrl
    python python/examples/recipe_torchrl.py --seed 1 --out runs/torchrl-seed1

``--copies`` worlds step in a ``SerialEnv``, copy i seeded ``recipe_common.training_seed(S) + i``, so runs
of different seeds share no world. Writes ``OUT/catches.json`` (``recipe_common``) and the policy's
parameters as ``OUT/torchrl-prey.pt``.
"""

from __future__ import annotations

import os
import time

import numpy as np
import torch
from tensordict.nn import NormalParamExtractor, TensorDictModule
from torch import nn
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, ReplayBuffer, SamplerWithoutReplacement
from torchrl.envs import SerialEnv
from torchrl.envs.libs.pettingzoo import PettingZooWrapper
from torchrl.modules import MultiAgentMLP, ProbabilisticActor, TanhNormal
from torchrl.objectives import ClipPPOLoss, ValueEstimators

import coevo
from recipe_common import SCENE, arguments, catches_per_episode, training_seed, write_result

PREY = ("prey", "observation"), ("prey", "action"), ("prey", "reward")


def make_env(seed: int):
    env = coevo.parallel_env(SCENE, seed=seed, episode_steps=500)
    return PettingZooWrapper(env, group_map={"prey": list(env.possible_agents)}, categorical_actions=False)


def main() -> None:
    a = arguments(__doc__.splitlines()[0], "torchrl", copies=4)
    torch.manual_seed(a.seed)
    torch.set_num_threads(1)
    started = time.time()
    base = training_seed(a.seed)
    env = SerialEnv(a.copies, [lambda i=i: make_env(base + i) for i in range(a.copies)])
    n_agents = len(coevo.parallel_env(SCENE).possible_agents)
    obs_dim = env.observation_spec["prey", "observation"].shape[-1]
    mlp = lambda out: MultiAgentMLP(n_agent_inputs=obs_dim, n_agent_outputs=out, n_agents=n_agents,  # noqa: E731
                                    centralised=False, share_params=True, depth=2, num_cells=64,
                                    activation_class=nn.Tanh)
    actor_net = nn.Sequential(mlp(4), NormalParamExtractor())
    policy = ProbabilisticActor(
        TensorDictModule(actor_net, in_keys=[("prey", "observation")], out_keys=[("prey", "loc"), ("prey", "scale")]),
        spec=env.full_action_spec_unbatched["prey", "action"], in_keys=[("prey", "loc"), ("prey", "scale")],
        out_keys=[("prey", "action")], distribution_class=TanhNormal,
        distribution_kwargs={"low": -1.0, "high": 1.0}, return_log_prob=True,
        log_prob_key=("prey", "sample_log_prob"))
    critic = TensorDictModule(mlp(1), in_keys=[("prey", "observation")], out_keys=[("prey", "state_value")])

    def act(obs: np.ndarray) -> np.ndarray:
        # The deterministic policy: the mean's tanh, every prey of every world at once.
        with torch.no_grad():
            loc, _ = actor_net(torch.from_numpy(obs).reshape(-1, n_agents, obs_dim))
        return torch.tanh(loc).reshape(-1, 2).numpy()

    untrained = catches_per_episode(act)
    frames_per_batch = a.copies * 500
    collector = Collector(env, policy, frames_per_batch=frames_per_batch,
                                  total_frames=a.world_steps // frames_per_batch * frames_per_batch,
                          auto_register_policy_transforms=False)
    loss = ClipPPOLoss(actor_network=policy, critic_network=critic, clip_epsilon=0.2, entropy_coeff=0.0,
                       normalize_advantage=False)
    loss.set_keys(reward=("prey", "reward"), action=("prey", "action"), sample_log_prob=("prey", "sample_log_prob"),
                  value=("prey", "state_value"), done=("prey", "done"), terminated=("prey", "terminated"))
    loss.make_value_estimator(ValueEstimators.GAE, gamma=0.99, lmbda=0.95)
    optim = torch.optim.Adam(loss.parameters(), lr=3e-4)
    buffer = ReplayBuffer(storage=LazyTensorStorage(frames_per_batch), sampler=SamplerWithoutReplacement(),
                          batch_size=frames_per_batch // 4)
    for data in collector:
        with torch.no_grad():
            loss.value_estimator(data, params=loss.critic_network_params, target_params=loss.target_critic_network_params)
        buffer.extend(data.reshape(-1))
        for _ in range(4):
            for _ in range(4):
                parts = loss(buffer.sample())
                total = parts["loss_objective"] + parts["loss_critic"] + parts["loss_entropy"]
                optim.zero_grad()
                total.backward()
                nn.utils.clip_grad_norm_(loss.parameters(), 0.5)
                optim.step()
        collector.update_policy_weights_()
    collector.shutdown()
    trained = catches_per_episode(act)
    os.makedirs(a.out, exist_ok=True)
    torch.save(actor_net.state_dict(), os.path.join(a.out, "torchrl-prey.pt"))
    import torchrl

    write_result(a.out, "torchrl", a.seed, untrained, trained, world_steps=a.world_steps, copies=a.copies,
                 seconds=round(time.time() - started, 1), torch=torch.__version__, torchrl=torchrl.__version__)


if __name__ == "__main__":
    main()
