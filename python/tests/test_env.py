"""The Python package: PettingZoo's API test, agreement with coevo's own rewards, the batch API."""

import os

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

import coevo

ROOT = os.path.join(os.path.dirname(__file__), "..", "..")
STANDARD = os.path.join(ROOT, "scenes", "standard.ron")


def test_pettingzoo_parallel_api():
    env = coevo.parallel_env(STANDARD, episode_steps=30)
    parallel_api_test(env, num_cycles=80)


def test_agents_spaces_and_truncation():
    env = coevo.parallel_env(STANDARD, seed=3, episode_steps=4, counts={"prey": 5})
    obs, infos = env.reset()
    assert env.agents == ["predator_0", "predator_1", "predator_2"] + [f"prey_{k}" for k in range(5)]
    assert obs["prey_0"].shape == env.observation_space("prey_0").shape
    for t in range(4):
        obs, rew, term, trunc, info = env.step({a: np.zeros(2, np.float32) for a in env.agents})
        assert set(info["prey_0"]) == {"dos", "doa", "catches"}
        assert all(trunc.values()) == (t == 3) and not any(term.values())
    assert env.agents == []
    with pytest.raises(ValueError, match="reset first"):
        env.step({})


def test_the_same_seed_and_actions_give_the_same_episode():
    def run():
        env = coevo.parallel_env(STANDARD, episode_steps=20)
        obs, _ = env.reset(seed=11)
        rng = np.random.default_rng(0)
        total = []
        for _ in range(20):
            act = {a: rng.uniform(-1, 1, 2).astype(np.float32) for a in env.agents}
            obs, rew, *_ = env.step(act)
            total.append([rew[a] for a in sorted(rew)])
        return np.array(total), obs["prey_3"]
    (r1, o1), (r2, o2) = run(), run()
    assert np.array_equal(r1, r2) and np.array_equal(o1, o2)


def test_vecenv_worlds_are_the_single_envs():
    vec = coevo.VecEnv(STANDARD, num_envs=4, seed=5, episode_steps=6)
    assert vec.reset().shape == (4, 13, vec.obs_dim)
    single = [coevo._coevo.Env(STANDARD, 5 + i, None, 6) for i in range(4)]
    for s in single:
        s.reset(None)
    rng = np.random.default_rng(1)
    for t in range(8):
        actions = rng.uniform(-1, 1, (4, 13, 2)).astype(np.float32)
        obs, rewards, truncated = vec.step(actions)
        assert obs.shape == (4, 13, vec.obs_dim) and rewards.shape == (4, 13) and truncated.dtype == bool
        for i, s in enumerate(single):
            o, r, tr, _ = s.step(actions[i])
            assert np.array_equal(rewards[i], r), (t, i)
            assert tr == truncated[i]
            if tr:
                o = s.reset(None)
            assert np.array_equal(obs[i], o), (t, i)


def test_bad_input_is_one_line():
    with pytest.raises(ValueError, match="cannot read"):
        coevo.parallel_env("no-such-scene.ron")
    with pytest.raises(ValueError, match="no species named"):
        coevo.parallel_env(STANDARD, counts={"hawk": 3})
    env = coevo._coevo.Env(STANDARD, None, None, 5)
    env.reset(None)
    with pytest.raises(ValueError, match="actions: expected 26 values"):
        env.step(np.zeros((3, 2), np.float32))


def test_render_gives_the_animation_frame():
    env = coevo.parallel_env(STANDARD, render_mode="rgb_array", render_size=200)
    env.reset()
    image = env.render()
    assert image.dtype == np.uint8 and image.shape == (200 + 38, 200, 3)
    # The prey's and the predators' colours are in it, not only the floor.
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 10
    assert coevo.parallel_env(STANDARD).render() is None
    with pytest.raises(ValueError, match="render_mode"):
        coevo.parallel_env(STANDARD, render_mode="human")
