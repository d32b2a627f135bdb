"""The flocking/herding controls on any runs coevo can evaluate (e.g. IPPO runs of ``ippo.py``).

For each run: ``coevo --eval`` on 50 prey (noise off) seeing, with the prey blind to / shuffled among each
other, with the predators hidden from the prey, with the predators removed (and the prey also blind to
each other then: what alignment without predators owes to seeing each other); the DoA and C_nn settled
over each episode's last 50 steps. Across runs: mean ± 95 % t interval of each level and of each
"seeing minus control" difference (computed run by run), with a two-sided one-sample t test of the
difference (no correction for multiple comparisons: the p-values are per row). ``--versus RUN...`` adds
a second group (e.g. runs trained without predators) and its Welch difference from the first. Each
evaluation is written into its run folder as ``eval-<name>.csv`` (so a shipped run under ``assets/``, which
coevo keeps as committed, is given as a copy: ``mkdir -p runs && cp -r assets/trained-standard runs/``).

    python python/examples/controls.py runs/ippo-seed1 runs/ippo-seed2 runs/ippo-seed3 \\
        --versus runs/ippo-nopred-seed1 runs/ippo-nopred-seed2 runs/ippo-nopred-seed3
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess

import numpy as np

import coevo

EVALUATIONS = {  # name: extra coevo --eval flags
    "seeing": [],
    "prey blind to prey": ["--control", "blind:prey:prey"],
    "prey shuffled": ["--control", "shuffled:prey:prey"],
    "predators hidden from prey": ["--control", "blind:prey:predator"],
    "predators removed": ["--predators", "0"],
    "predators removed, prey blind to prey": ["--predators", "0", "--control", "blind:prey:prey"],
}


def settled(run: coevo.RunFolder, path: str, column: str, last: int = 50) -> float:
    """The mean over episodes of each episode's last `last` steps (the per-step CSV read whole by coevo)."""
    table = run.read_evaluation(path)
    per_episode: dict[int, list[float]] = {}
    for episode, value in zip(table["episode"], table[column]):
        if not math.isnan(value):
            per_episode.setdefault(int(episode), []).append(value)
    return float(np.mean([np.mean(v[-last:]) for v in per_episode.values()]))


def window(run: coevo.RunFolder, column: str, first: bool, n: int = 100) -> float:
    """The mean of the first or last `n` episodes of training; NaN for a run without `metrics.csv`."""
    if not os.path.exists(run.metrics):
        return math.nan
    values = [v for v in run.read_metrics()[column] if not math.isnan(v)]
    return float(np.mean(values[:n] if first else values[-n:]))


def evaluate(coevo_bin: str, path: str, episodes: int, steps: int) -> dict[str, dict[str, float]]:
    run = coevo.RunFolder(path)
    out = {}
    for name, flags in EVALUATIONS.items():
        file = run.evaluation(name.replace(", ", "-").replace(" ", "-"))
        if not os.path.exists(file):
            done = subprocess.run([coevo_bin, "--eval", path, "--prey", "50", "--episodes", str(episodes), "--steps",
                                   str(steps), "--eval-out", os.path.basename(file), *flags],
                                  capture_output=True, text=True)
            if done.returncode != 0:  # e.g. a run shipped under assets/, which coevo keeps as committed
                raise SystemExit(done.stderr.strip() or f"coevo --eval {path}: exit {done.returncode}")
        out[name] = {"doa": settled(run, file, "doa_prey"), "nn_correlation": settled(run, file, "nn_correlation_prey")}
    out["training"] = {"doa_first": window(run, "doa_prey", True), "doa_last": window(run, "doa_prey", False),
                       "catches_last": window(run, "catches", False)}
    return out


def interval(x: list[float]) -> tuple[float, float, float]:
    """Mean, 95 % t half-width, two-sided p of mean 0, as coevo's reports compute them."""
    e = coevo.t_estimate(x)
    nan = lambda v: math.nan if v is None else v  # noqa: E731
    return e["mean"], nan(e["ci"]), nan(e["p"])


def show(label: str, x: list[float], against: float | None = 0.0) -> None:
    """One row: mean ± 95 % t half-width, and the t test against `against` (None: a level, not tested).
    Never prints NaN: runs without the value are left out, and one run or no spread says so instead."""
    runs = len(x)
    x = [v for v in x if not math.isnan(v)]
    left_out = f"   ({runs - len(x)} of {runs} runs have no value)" if len(x) < runs else ""
    if not x:
        print(f"  {label:52s} –   (no run has a value, e.g. no metrics.csv)")
        return
    m, h, p = interval([v - (against or 0.0) for v in x])
    if len(x) < 2:
        print(f"  {label:52s} {m + (against or 0.0):+.3f}   (one run: no interval, no test){left_out}")
        return
    text = f"{m + (against or 0.0):+.3f} ± {h:.3f}"
    if against is not None:
        text += f"   p = {p:.3g} against {against:+.3f}" if not math.isnan(p) else "   p: – (no spread)"
    print(f"  {label:52s} {text}{left_out}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("runs", nargs="+")
    ap.add_argument("--versus", nargs="*", default=[])
    ap.add_argument("--episodes", type=int, default=20)
    ap.add_argument("--steps", type=int, default=500)
    ap.add_argument("--coevo", default=os.environ.get("COEVO_BIN", "target/release/coevo"))
    a = ap.parse_args()
    chance = 2 / math.pi
    groups = {"runs": a.runs, "versus": a.versus}
    results = {g: [evaluate(a.coevo, r, a.episodes, a.steps) for r in runs] for g, runs in groups.items() if runs}
    for g, res in results.items():
        print(f"{g}: {len(res)} runs, 50 prey, {a.episodes} episodes × {a.steps} steps, last 50 steps; mean ± 95 % t CI")
        show("training: DoA first 100 episodes", [r["training"]["doa_first"] for r in res], None)
        show("training: DoA last 100 episodes", [r["training"]["doa_last"] for r in res], None)
        show("training: catches per episode, last 100", [r["training"]["catches_last"] for r in res], None)
        show("training: DoA change, last minus first 100",
             [r["training"]["doa_last"] - r["training"]["doa_first"] for r in res])
        show("DoA seeing (against chance 2/π)", [r["seeing"]["doa"] for r in res], chance)
        show("C_nn seeing", [r["seeing"]["nn_correlation"] for r in res])
        for name in list(EVALUATIONS)[1:5]:
            show(f"DoA seeing minus {name}", [r["seeing"]["doa"] - r[name]["doa"] for r in res])
        show("DoA predators removed (against chance 2/π)", [r["predators removed"]["doa"] for r in res], chance)
        show("DoA predators removed minus also blind to prey",
             [r["predators removed"]["doa"] - r["predators removed, prey blind to prey"]["doa"] for r in res])
        for name in list(EVALUATIONS)[1:3]:
            show(f"C_nn seeing minus {name}",
                 [r["seeing"]["nn_correlation"] - r[name]["nn_correlation"] for r in res])
    if "versus" in results:
        x = [r["seeing"]["doa"] for r in results["runs"]]
        y = [r["seeing"]["doa"] for r in results["versus"]]
        if min(len(x), len(y)) < 2 or np.std(x) + np.std(y) == 0:
            print(f"runs minus versus, DoA seeing: {np.mean(x) - np.mean(y):+.3f} "
                  "(no Welch test: it needs two runs a side and some spread)")
            return
        w = coevo.welch(x, y)  # coevo's Welch test: degrees of freedom rounded down, as its reports
        print(f"runs minus versus, DoA seeing (Welch): {w['mean']:+.3f} "
              f"[{w['mean'] - w['ci']:+.3f}, {w['mean'] + w['ci']:+.3f}] (p = {w['p']:.3g})")


if __name__ == "__main__":
    main()
