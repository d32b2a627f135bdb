"""Judges whether each documented framework route learned, from its runs' ``catches.json``
(``recipe_common.py``), and writes the table ``results/recipes/summary.md``.

The hypothesis, fixed here before the runs it judges (this file's first commit precedes the first
committed ``catches.json``):

- **Quantity**, per run: catches per episode of the prey's trained deterministic policy minus that of its
  untrained (initial) policy, on the same evaluation worlds (``recipe_common``: 8 worlds of a fixed seed
  no training uses, 2 whole episodes each), in ``scenes/prey-vs-chasers.ron``.
- **Runs**: three routes (``sb3``: Stable-Baselines3 PPO through SuperSuit; ``torchrl``: TorchRL's
  multi-agent PPO through its PettingZoo wrapper; ``cleanrl``: ``ippo.py``, CleanRL-style), seeds 1 to 5
  each, 100 000 world steps each (200 episodes of 500 steps, summed over the worlds stepped together).
- **Test**: per route, the mean of the five per-run differences, its 95 % Student-t interval and the
  two-sided t test against 0 (``coevo.t_estimate``); Holm over the three routes at 0.05 (``coevo.holm``).
- **Verdict**: *learned* when the Holm-adjusted p is under 0.05 and the mean is negative (fewer catches);
  *detected the other way* when it is under 0.05 and positive; *not shown* otherwise.

    python python/examples/recipes_summary.py results/recipes
"""

from __future__ import annotations

import json
import os
import sys

import coevo

ROUTES = {
    "sb3": "Stable-Baselines3 PPO through SuperSuit (`recipe_sb3.py`)",
    "torchrl": "TorchRL multi-agent PPO (`recipe_torchrl.py`)",
    "cleanrl": "CleanRL-style PPO (`ippo.py --catches true`)",
}
SEEDS = [1, 2, 3, 4, 5]
ALPHA = 0.05


def main(folder: str) -> None:
    runs = {route: [] for route in ROUTES}
    for route in ROUTES:
        for seed in SEEDS:
            path = os.path.join(folder, f"{route}-seed{seed}", "catches.json")
            if not os.path.exists(path):
                raise SystemExit(f"{path}: missing; the table needs every registered run")
            with open(path) as f:
                runs[route].append(json.load(f))
    estimates = {r: coevo.t_estimate([x["trained_minus_untrained"] for x in runs[r]]) for r in ROUTES}
    adjusted = dict(zip(ROUTES, coevo.holm([estimates[r]["p"] for r in ROUTES])))
    lines = [
        "| route | untrained, catches per episode | trained | trained minus untrained (95 % interval) | p (Holm) | verdict |",
        "|---|---|---|---|---|---|",
    ]
    for r, what in ROUTES.items():
        e, p = estimates[r], adjusted[r]
        mean = lambda key: sum(x[key] for x in runs[r]) / len(runs[r])  # noqa: E731
        verdict = "not shown" if p >= ALPHA else ("learned" if e["mean"] < 0 else "detected the other way")
        lines.append(f"| {what} | {mean('catches_untrained'):.1f} | {mean('catches_trained'):.1f} | "
                     f"{e['mean']:+.1f} ± {e['ci']:.1f} | {p:.2g} | {verdict} |")
    lines += ["", "Per run (catches per episode, untrained → trained; the world steps asked for; seconds of the whole "
              "run, two runs at a time on two cores):", ""]
    for r in ROUTES:
        commits = {x["coevo_commit"] for x in runs[r]}
        if len(commits) != 1:
            raise SystemExit(f"{r}: runs made by different builds of coevo ({', '.join(sorted(commits))})")
        cells = [f"seed {x['seed']}: {x['catches_untrained']:.1f} → {x['catches_trained']:.1f} "
                 f"({x['world_steps']} world steps, {x['seconds']:.0f} s)" for x in runs[r]]
        lines.append(f"- `{r}`: " + "; ".join(cells) + f" (coevo {commits.pop()})")
    # Descriptive, not part of the test, and added to this file after the runs: fixed actions on the same
    # evaluation worlds, as yardsticks.
    import numpy as np

    from recipe_common import catches_per_episode

    rng = np.random.default_rng(1)
    references = {
        "uniform random actions (seeded)": lambda o: rng.uniform(-1.0, 1.0, (o.shape[0], 2)),
        "action (0, 0) always": lambda o: np.zeros((o.shape[0], 2)),
        "action (1, 0) always (full thrust, no turn)": lambda o: np.tile([1.0, 0.0], (o.shape[0], 1)),
    }
    lines += ["", "Yardsticks on the same evaluation worlds (descriptive, not tested): catches per episode of "
              + "; ".join(f"{name} {catches_per_episode(act):.1f}" for name, act in references.items()) + "."]
    out = os.path.join(folder, "summary.md")
    with open(out + ".tmp", "w") as f:
        f.write("\n".join(lines) + "\n")
    os.replace(out + ".tmp", out)
    print("\n".join(lines))


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "results/recipes")
