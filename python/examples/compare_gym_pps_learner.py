"""The authors' learner on coevo's world against coevo's own learner under the same switches.

    python examples/compare_gym_pps_learner.py results/authors-learner/seed*.csv \\
        --coevo results/authors-code/gym-pps/every-switch

reads the runs of ``gym_pps_learner.py`` (the MADDPG of a WindyLab/Gym-PPS checkout driving coevo's
world in the code's layout, ``scenes/gym-pps-code.ron``) and coevo's own runs of that scene (the "every
switch" variant of ``experiments/authors-code.ron``), and prints, as Markdown, the pre-registered
comparisons below, judged as coevo's reports judge two variants (``coevo.compare_curves``: Welch's
difference, the authors' learner minus coevo; TOST within each margin; Holm over the family; the
reports' own verdict words), then what each run took and with what it ran.

**Pre-registered** (this file's first commit, before any full-length run of the adapter): the question is
whether two implementations of the same algorithm on the same world learn the same thing, so each
comparison is a claim of equivalence, "the same within ±m", over the first 100 and the last 100 episodes
of training. The margins, from the seed-to-seed spread of coevo's `gym-pps` runs in
``results/standard`` (another binary's runs, already published; nothing of the runs compared here was
looked at): DoA ±0.05 (herding-equivalence's primary margin), DoS ±0.02 (a tenth of its level there,
0.18-0.21; its seed-to-seed SD is about 0.016), catches per episode ±10 (a third of the trained level
there, 28.6; SD about 8). The authors' learner runs seeds 1-3 (the three planned), coevo seeds 1-10 (all
of "every switch"; the script refuses fewer, so that nothing of authors-code, which is judged only when
complete, is looked at before then). Power, said before any result: if the learner's seeds spread as
coevo's do, 3 against 10 leaves Welch about 3 degrees of freedom, and even with no true difference the
(1 - 2α) interval at Holm's last step is wider than every margin (DoA about ±0.1, DoS ±0.025, catches
±13): these margins cannot be shown at this size, and a verdict of "inconclusive" will say how wide a
margin the data do support. What the comparison can show is a difference beyond a margin, a
"documented difference" between the two implementations.
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import os
import re
import sys

import coevo

FAMILY = "the authors' learner minus coevo, the code's switches on"
# coevo's side: every seed of the "every switch" variant of experiments/authors-code.ron.
COEVO_SEEDS = list(range(1, 11))
# (claim, quantity as experiment files write it, equivalence margin)
COMPARISONS = [
    ("DoA over the first 100 episodes: the same within ±0.05", "DoaFirst", 0.05),
    ("DoA over the last 100 episodes: the same within ±0.05", "DoaLast", 0.05),
    ("DoS over the first 100 episodes: the same within ±0.02", "DosFirst", 0.02),
    ("DoS over the last 100 episodes: the same within ±0.02", "DosLast", 0.02),
    ("catches per episode over the first 100 episodes: the same within ±10", "CatchesFirst", 10.0),
    ("catches per episode over the last 100 episodes: the same within ±10", "CatchesLast", 10.0),
]


# A resolved scene's own seed line (``Scene`` writes it first, indented once): runs of one scene differ in it.
SEED_LINE = re.compile(r"^    seed: \d+,$", re.M)


def without_seed(ron: str) -> str:
    return SEED_LINE.sub("    seed: _,", ron, count=1)


def learner_run(path: str) -> tuple[dict, dict]:
    """A finished run of ``gym_pps_learner.py``: its curves, and its provenance with its wall and CPU
    seconds and its scene (rebuilt from the file it names, refused unless that gives the hash the run
    recorded). Refused, naming the file, unless whole (episodes 1..N in order, numbers throughout)."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows or [int(r["episode"]) for r in rows] != list(range(1, len(rows) + 1)):
        sys.exit(f"{path}: not a finished run of gym_pps_learner.py (episodes 1..N in order)")
    curves = {name: [float(r[name]) for r in rows] for name in ("dos", "doa", "catches")}
    with open(path + ".provenance.json") as f:
        provenance = json.load(f)
    run = provenance["run"]
    env = coevo.parallel_env(provenance["scene"]["path"], seed=run["seed"], episode_steps=run["episode_steps"])
    provenance["scene_ron"] = env.scene_ron()
    if hashlib.sha256(provenance["scene_ron"].encode()).hexdigest() != provenance["scene"]["sha256"]:
        sys.exit(f"{path}: {provenance['scene']['path']} is no longer the scene the run trained on (its hash differs)")
    provenance["wall_seconds"] = float(rows[-1]["wall_seconds"])
    provenance["cpu_seconds"] = float(rows[-1]["cpu_seconds"])
    return curves, provenance


def coevo_run(folder: str, scene: str, episodes: int) -> tuple[dict, float]:
    """A finished coevo run's curves of the headline species (prey) and its wall seconds; refused while
    it trains (``metrics.csv`` read whole, ``episodes`` rows) or when its scene, but for the seed, is not
    ``scene``."""
    run = coevo.RunFolder(folder)
    metrics = run.read_metrics()
    with open(run.scene) as f:
        ron = f.read()
    if without_seed(ron) != without_seed(scene):
        sys.exit(f"{run.scene}: another scene than the learner's runs (beyond the seed)")
    if len(metrics["episode"]) != episodes:
        sys.exit(f"{folder}: {len(metrics['episode'])} episodes, the learner's runs {episodes}: not finished yet")
    curves = {"dos": metrics["dos_prey"], "doa": metrics["doa_prey"], "catches": metrics["catches"]}
    return curves, metrics["wall_seconds"][-1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("learner", nargs="+", help="CSV files written by gym_pps_learner.py")
    parser.add_argument("--coevo", required=True, help="a variant's folder of coevo runs (seed*/)")
    args = parser.parse_args()
    theirs = [learner_run(p) for p in args.learner]
    decides = lambda p: json.dumps([p["coevo"], p["torch"], p["checkout"]["learner_sha256"],  # noqa: E731
                                    without_seed(p["scene_ron"]), p["run"]["episodes"], p["run"]["episode_steps"]])
    seeds = [p["run"]["seed"] for _, p in theirs]
    if len(set(seeds)) != len(seeds):
        sys.exit(f"the learner's runs repeat a seed ({seeds}): each must be its own")
    if len({decides(p) for _, p in theirs}) != 1:
        sys.exit("the learner's runs differ in coevo, torch, the learner, the scene, episodes or steps: not one sample")
    for (curves, p), path in zip(theirs, args.learner):
        if len(curves["doa"]) != p["run"]["episodes"]:
            sys.exit(f"{path}: {len(curves['doa'])} episodes of the {p['run']['episodes']} it was started for")
    folders = [os.path.join(args.coevo, f"seed{k}") for k in COEVO_SEEDS]
    missing = [f for f in folders if not os.path.isdir(f)]
    if missing:
        sys.exit(f"--coevo: {len(missing)} of its {len(folders)} seeds are not there yet ({', '.join(missing)}); "
                 "the comparison waits for all of them")
    ours = [coevo_run(f, theirs[0][1]["scene_ron"], theirs[0][1]["run"]["episodes"]) for f in folders]
    lengths = {len(c["doa"]) for c, _ in theirs + ours}
    if len(lengths) != 1:
        sys.exit(f"the runs trained for different numbers of episodes ({sorted(lengths)}): their windows differ")
    results = coevo.compare_curves(FAMILY, [c for c, _ in theirs], [c for c, _ in ours], COMPARISONS)

    mean = lambda xs: sum(xs) / len(xs)  # noqa: E731
    print(f"**{FAMILY}**: {len(theirs)} runs of the authors' learner, {len(ours)} of coevo's, "
          f"{lengths.pop()} episodes each.\n")
    print("| claim | authors' learner − coevo (Welch's 95 % interval; the verdict's is Holm's) | verdict |")
    print("|---|---|---|")
    for r in results:
        ci = "" if r["ci"] is None else f" ± {r['ci']:.3f}"
        print(f"| {r['text']} | {r['mean']:+.3f}{ci} | {r['verdict']} |")
    print()
    for (curves, p), path in zip(theirs, args.learner):
        print(f"- `{path}`: torch {p['torch']}, coevo {p['coevo']['git_commit']}, learner "
              f"{p['checkout']['git_commit'] or p['checkout']['learner_sha256'][:16]}, "
              f"{p['run']['threads']} torch thread(s): {p['wall_seconds'] / 60:.0f} min wall, "
              f"{p['cpu_seconds'] / 60:.0f} min CPU" + (f", resumed after {p['resumed_after']}" if p["resumed_after"] else ""))
    print(f"- coevo's runs ({args.coevo}): {mean([w for _, w in ours]) / 60:.1f} min wall on average")


if __name__ == "__main__":
    main()
