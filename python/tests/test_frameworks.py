"""The guide's "Use it from your framework" snippets, run as written but shorter (a few hundred steps, not a
training): Gymnasium's vector API, Stable-Baselines3 through SuperSuit, TorchRL's PettingZoo wrapper.
A snippet whose framework is not installed is skipped with its name; `.ci/run` installs them all."""

import importlib.util
import os
import re

import pytest

ROOT = os.path.join(os.path.dirname(__file__), "..", "..")
GUIDE = os.path.join(ROOT, "docs", "src", "guide", "python.md")


def snippet(marker: str) -> str:
    """The first ```python block after the paragraph that starts with `marker`."""
    text = open(GUIDE, encoding="utf-8").read()
    start = text.index("## Use it from your framework")
    at = text.index(marker, start)
    return re.search(r"```python\n(.*?)```", text[at:], re.S).group(1)


def run(code: str, shorter: dict[str, str], needs: list[str], monkeypatch) -> dict:
    for module in needs:
        if importlib.util.find_spec(module) is None:
            pytest.skip(f"{module} is not installed")
    for long, short in shorter.items():
        assert long in code, f"the guide's snippet no longer has {long!r}"
        code = code.replace(long, short)
    monkeypatch.chdir(ROOT)
    scope: dict = {}
    exec(compile(code, GUIDE, "exec"), scope)
    return scope


def test_the_gymnasium_snippet(monkeypatch, capsys):
    scope = run(snippet("**Gymnasium, CleanRL style**"), {"num_worlds=8": "num_worlds=2",
                "range(600)": "range(30)",
                '"scenes/standard.ron"': '"scenes/standard.ron", episode_steps=10'}, ["gymnasium"], monkeypatch)
    assert scope["obs"].shape == (2 * 13, scope["env"].single_observation_space.shape[0])
    assert len(capsys.readouterr().out.split()) == 2  # one mean return per ended episode: steps 10 and 21


def test_the_stable_baselines3_snippet(monkeypatch):
    scope = run(snippet("**Stable-Baselines3**"), {"episode_steps=500": "episode_steps=20",
                "total_timesteps=1_000_000": "total_timesteps=128 * 40"},
                ["stable_baselines3", "supersuit"], monkeypatch)
    model, copies = scope["model"], scope["vec"].venv.vec_envs
    # One rollout of 128 steps of 4 copies × 10 prey: only the prey are agents, the predators chase by a rule.
    assert model.num_timesteps == 128 * 40 and model.observation_space.shape == scope["vec"].observation_space.shape
    # Seeded beneath SuperSuit's wrapper, the four copies run four different worlds.
    assert len({tuple(copy.par_env.positions()[0]) for copy in copies}) == 4


def test_the_torchrl_snippet(monkeypatch):
    scope = run(snippet("**TorchRL**"), {"episode_steps=500": "episode_steps=50"}, ["torchrl"], monkeypatch)
    rollout = scope["rollout"]
    assert rollout["prey", "observation"].shape[:2] == (50, 10)  # stopped at the time limit, 10 prey
    assert rollout["next", "predator", "reward"].shape[:2] == (50, 3)


def test_ppo_prey_against_predators_that_coevo_keeps_training(tmp_path, monkeypatch):
    """examples/ippo.py with ``--coevolve predator``, shorter: PPO trains the prey while coevo's DDPG keeps
    training the predators in the same worlds; coevo's side of world 0 is saved as a run folder."""
    for module in ("torch", "safetensors"):
        if importlib.util.find_spec(module) is None:
            pytest.skip(f"{module} is not installed")
    import subprocess
    import sys

    out = tmp_path / "run"
    subprocess.run([sys.executable, os.path.join(ROOT, "python", "examples", "ippo.py"), "--seed", "2",
                    "--out", str(out), "--num-envs", "2", "--num-steps", "32", "--total-world-steps", "256",
                    "--coevolve", "predator"], check=True, cwd=ROOT)
    rows = (out / "metrics.csv").read_text().splitlines()
    assert "critic_loss_prey" in rows[0] and "critic_loss_predator" not in rows[0]
    coevo_side = (out / "coevo-world0" / "metrics.csv").read_text().splitlines()
    assert "critic_loss_predator" in coevo_side[0] and len(coevo_side) >= 2


def recipe(tmp_path, script: str, args: list[str], needs: list[str]) -> dict:
    """A recipe of the guide's "Recipes that learn", shorter (a few batches, not a training): it writes
    catches.json with the untrained and trained policies' catches per episode on the evaluation worlds."""
    for module in needs:
        if importlib.util.find_spec(module) is None:
            pytest.skip(f"{module} is not installed")
    import json
    import math
    import subprocess
    import sys

    out = tmp_path / "run"
    subprocess.run([sys.executable, os.path.join(ROOT, "python", "examples", script), "--seed", "2",
                    "--out", str(out), *args], check=True, cwd=ROOT)
    result = json.loads((out / "catches.json").read_text())
    assert math.isfinite(result["catches_untrained"]) and math.isfinite(result["catches_trained"])
    assert result["trained_minus_untrained"] == result["catches_trained"] - result["catches_untrained"]
    return result


def test_the_stable_baselines3_recipe(tmp_path):
    result = recipe(tmp_path, "recipe_sb3.py", ["--world-steps", "600", "--copies", "2"],
                    ["torch", "stable_baselines3", "supersuit"])
    assert result["route"] == "sb3" and (tmp_path / "run" / "sb3-prey.zip").exists()


def test_the_torchrl_recipe(tmp_path):
    result = recipe(tmp_path, "recipe_torchrl.py", ["--world-steps", "1000", "--copies", "2"], ["torch", "torchrl"])
    assert result["route"] == "torchrl" and (tmp_path / "run" / "torchrl-prey.pt").exists()


def test_the_cleanrl_style_recipe(tmp_path):
    result = recipe(tmp_path, "ippo.py", ["--scene", "scenes/prey-vs-chasers.ron", "--num-envs", "2", "--num-steps",
                                          "32", "--total-world-steps", "256", "--catches", "true"],
                    ["torch", "safetensors"])
    assert result["route"] == "cleanrl" and (tmp_path / "run" / "metrics.csv").exists()


def test_the_recipes_seed_their_worlds_apart():
    # SuperSuit seeds copy i with base + i: the bases of neighbouring seeds are far apart, so runs seeded 1 to 5
    # with 8 copies each share no world.
    import sys

    sys.path.insert(0, os.path.join(ROOT, "python", "examples"))
    from recipe_common import training_seed

    worlds = [training_seed(seed) + i for seed in range(1, 6) for i in range(8)]
    assert len(set(worlds)) == len(worlds) and all(0 <= w < 2**64 for w in worlds)


def test_the_committed_recipes_table_is_what_its_runs_give(tmp_path):
    # docs/src/results/recipes/summary.md is recipes_summary.py's output from the committed catches.json:
    # the verdicts, intervals and yardsticks the guide quotes, made again here.
    import shutil
    import subprocess
    import sys

    committed = os.path.join(ROOT, "docs", "src", "results", "recipes")
    copy = tmp_path / "recipes"
    shutil.copytree(committed, copy, ignore=shutil.ignore_patterns("summary.md"))
    subprocess.run([sys.executable, os.path.join(ROOT, "python", "examples", "recipes_summary.py"), str(copy)],
                   check=True, cwd=ROOT, capture_output=True)
    table = (copy / "summary.md").read_text()
    # All but the yardsticks, which simulate afresh: another CPU's libm may round a sine differently and
    # send the worlds elsewhere; the verdicts and intervals come from the committed numbers alone.
    tested = lambda text: [line for line in text.splitlines() if not line.startswith("Yardsticks")]  # noqa: E731
    assert tested(table) == tested(open(os.path.join(committed, "summary.md")).read())
    # The guide shows the same table.
    guide = open(GUIDE, encoding="utf-8").read()
    assert all(row in guide for row in table.split("\n\n")[0].splitlines())
