"""The authors' own learner on coevo's world.

Drives the MADDPG learner of a WindyLab/Gym-PPS checkout (``NJP_algorithm/``: ``algorithms/maddpg.py``,
``utils/buffer.py``, ``utils/agents.py``, ``utils/noise.py``; nothing of it is copied here) on coevo's
Python environment, with the loop of ``NJP_algorithm/main.py`` written out below and only the
environment replaced: coevo's physics, rewards and metrics, observed in the code's layout
(``scenes/gym-pps-code.ron``: own [x, y, v_x, v_y], 2 predator and 5 prey slots, the energy input, own
heading; d_o 35). A run is the first check of coevo's learning *outcomes* against an implementation
coevo did not write.

    python examples/gym_pps_learner.py --gym-pps ~/src/Gym-PPS --seed 1 --out runs/gym-pps-learner/seed1.csv

writes one row per episode: the paper's DoS and DoA of the prey averaged over the episode's steps
(coevo's metric, the one ``metrics.csv`` logs), the catches, the wall time and the process's CPU time
(the cost of a run on a shared machine), to be compared with
coevo's own runs of the same scene (``coevo --train --scene scenes/gym-pps-code.ron``; the "every switch"
variant of ``experiments/authors-code.ron`` is that scene) by ``compare_gym_pps_learner.py``. Beside it,
``OUT.provenance.json`` names what made the run: coevo's commit and a hash of its extension, torch's and
numpy's versions, the checkout (its git commit when it is a git work tree, and a hash of the learner's
files either way), a hash of the scene as the world runs it, the seed, episodes, steps and threads, and
the episodes a run resumed after. The wall and CPU seconds count the work that made the rows: what a kill
lost since the last checkpoint, and the checkpoints' writing, are not in them.

**Resumable.** Rows go to ``OUT.partial`` as episodes finish, and every ``--checkpoint-every`` episodes
(250) the whole learner is saved in ``OUT.checkpoint/``: its agents as the learner saves them
(``get_params``: networks, targets, optimizers), the noise and ε it decays, both replay buffers' sampled
rows and write positions, and numpy's and torch's random states. Run the same command again after a kill and it continues from the last checkpoint,
as if never stopped: each episode's world starts from its own seed (``seed`` for the first, then
``seed + 1000003·episode``), so nothing of the world has to be saved. The finished file is renamed to
``OUT`` and the checkpoint removed. Of each buffer only rows ``[0, filled)`` are saved: the code samples
no other row (``utils/buffer.py``: ``np.arange(self.filled_i)``; the rows it writes beyond ``max_steps``
are never read), so a checkpoint is at most ~0.3 GB per species.

What the adapter does, each the code's behaviour in ``gym/envs/pps/pps.py`` and ``main.py``:

* **Observations** are columns, ``[d_o, agents]``, predators first (``_get_obs``).
* **Actions** come out of the learner as ``[turn, thrust]`` rows in [-1, 1] (``step``: ``a[0]`` turns by
  ``a[0]`` times the largest turn per step, ``a[1]`` maps to [min, max] acceleration); coevo's order is
  ``[thrust, turn]``, so the rows are swapped on the way in.
* **Stored actions** are the rescaled ones, as the code's ``env.step`` rescales the array in place before
  ``main.py`` pushes it (difference 2 of docs/src/results/authors-code.md), while the actors are queried
  at [-1, 1].
* **Rewards** are coevo's for the scene (the ``gym-pps`` preset's values), ``[1, agents]``; nobody is ever
  done.

Needs torch and numpy (``pip install torch``; the package registry's torch carries its CUDA libraries,
~5 GB). The learner's files import ``gym.spaces``; if the checkout's own ``gym`` package does not import
(it needs an old numpy), a stand-in module with gymnasium's spaces is used, as the continuous learner
never touches them. The mapping itself is tested without torch or a checkout
(``python/tests/test_env.py``, ``test_the_gym_pps_adapter_maps_coevos_world_to_the_codes_arrays``).
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import os
import re
import shutil
import sys
import time
import types

import numpy as np

import coevo


def columns(env: coevo.CoevoParallelEnv, observations: dict) -> np.ndarray:
    """Observations as the code holds them: ``[d_o, agents]``, one column per agent, predators first
    (coevo's agents are already in species order: ``predator_0 …``, then ``prey_0 …``)."""
    return np.stack([observations[a] for a in env.possible_agents], axis=1).astype(np.float64)


def to_coevo(env: coevo.CoevoParallelEnv, actions: np.ndarray) -> dict:
    """The learner's ``[2, agents]`` actions (rows: turn, thrust) as coevo's per-agent [thrust, turn]."""
    return {a: np.array([actions[1, i], actions[0, i]], dtype=np.float32) for i, a in enumerate(env.possible_agents)}


def limits(env: coevo.CoevoParallelEnv) -> tuple[np.ndarray, np.ndarray]:
    """Per agent, the largest turn per step (rad: max turn rate × dt) and the largest thrust (N), read from
    the scene the env runs."""
    ron = env.scene_ron()
    dt = float(re.search(r"\bdt: ([0-9.eE+-]+)", ron).group(1))
    species = {}
    for block in re.finditer(r'\(\s*name: "([^"]+)",(.*?)\n\s*\),', ron, re.S):
        fields = dict(re.findall(r"(max_turn_rate|max_thrust): ([0-9.eE+-]+)", block.group(2)))
        if fields:
            species[block.group(1)] = (float(fields["max_turn_rate"]) * dt, float(fields["max_thrust"]))
    per_agent = [species[a.rsplit("_", 1)[0]] for a in env.possible_agents]
    return np.array([t for t, _ in per_agent]), np.array([f for _, f in per_agent])


def rescale_in_place(actions: np.ndarray, turn_max: np.ndarray, thrust_max: np.ndarray) -> None:
    """What the code's ``env.step`` does to the array it is handed (and ``main.py`` then stores): the
    turn times the largest turn per step, the thrust from [-1, 1] to [0, max] (``(max − min)/2·a +
    (max + min)/2`` with min 0)."""
    actions[0] *= turn_max
    actions[1] = thrust_max / 2 * actions[1] + thrust_max / 2


def learner(checkout: str):
    """The checkout's MADDPG and ReplayBuffer classes."""
    sys.path.insert(0, os.path.join(checkout, "NJP_algorithm"))
    try:
        import gym.spaces  # noqa: F401 (the checkout's own gym, when it imports here)
    except Exception:
        from gymnasium import spaces

        stand_in = types.ModuleType("gym")
        stand_in.spaces = spaces
        sys.modules["gym"], sys.modules["gym.spaces"] = stand_in, spaces
    from algorithms.maddpg import MADDPG
    from utils.buffer import ReplayBuffer

    own = not sys.modules["gym"].spaces.__name__.startswith("gymnasium")
    used = "the checkout's own" if own else "gymnasium's (stand-in)"
    print(f"the learner of {checkout}; gym.spaces: {used}", file=sys.stderr)
    return MADDPG, ReplayBuffer


BUFFER_ARRAYS = ("obs_buffs", "ac_buffs", "rew_buffs", "next_obs_buffs", "done_buffs")


def episode_seed(seed: int, episode: int) -> int:
    """The world seed of episode ``episode`` (from 0): each episode starts afresh from its own, so a resumed
    run needs nothing of the world's state."""
    return seed if episode == 0 else seed + 1000003 * episode


def save_checkpoint(path: str, episode: int, elapsed: float, cpu: float, maddpg, buffers) -> None:
    """Everything the learner carries after ``episode`` episodes, written beside and swapped in whole."""
    import torch

    tmp = path + ".tmp"
    shutil.rmtree(tmp, ignore_errors=True)
    os.makedirs(tmp)
    for k, b in enumerate(buffers):
        for name in BUFFER_ARRAYS:
            np.save(os.path.join(tmp, f"buffer{k}-{name}.npy"), getattr(b, name)[: b.filled_i])
    state = {
        "episode": episode,
        "elapsed": elapsed,
        "cpu": cpu,
        # The learner's own way of saving its agents (MADDPG.save: networks, targets and optimizers), and
        # what it changes besides: the noise and ε it decays, its update count.
        "agent_params": [a.get_params() for a in maddpg.agents],
        "noise_epsilon_niter": (maddpg.noise, maddpg.epsilon, maddpg.niter),
        "buffers": [(b.filled_i, b.curr_i) for b in buffers],
        "numpy_random": np.random.get_state(),
        "torch_random": torch.get_rng_state(),
    }
    torch.save(state, os.path.join(tmp, "state.pt"))
    old = path + ".old"
    shutil.rmtree(old, ignore_errors=True)
    if os.path.exists(path):
        os.rename(path, old)
    os.rename(tmp, path)
    shutil.rmtree(old, ignore_errors=True)


def load_checkpoint(path: str, maddpg, buffers):
    """The learner as ``save_checkpoint`` left it, loaded into ``maddpg`` and ``buffers`` in place, the
    random states restored: (episodes done, wall seconds elapsed, CPU seconds used)."""
    import torch

    state = torch.load(os.path.join(path, "state.pt"), weights_only=False)
    for a, params in zip(maddpg.agents, state["agent_params"]):
        a.load_params(params)
    maddpg.noise, maddpg.epsilon, maddpg.niter = state["noise_epsilon_niter"]
    for k, (b, (filled, curr)) in enumerate(zip(buffers, state["buffers"])):
        for name in BUFFER_ARRAYS:
            getattr(b, name)[:filled] = np.load(os.path.join(path, f"buffer{k}-{name}.npy"))
        b.filled_i, b.curr_i = filled, curr
    np.random.set_state(state["numpy_random"])
    torch.set_rng_state(state["torch_random"])
    return state["episode"], state["elapsed"], state["cpu"]


LEARNER_FILES = ("algorithms/maddpg.py", "utils/agents.py", "utils/buffer.py", "utils/networks.py", "utils/misc.py",
                 "utils/noise.py")


def sha256_of(path: str) -> str:
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def checkout_identity(checkout: str) -> dict:
    """Which learner ran: the checkout's git commit when the checkout is itself a git work tree (not one
    inside another repository's), and a SHA-256 of the learner's files (``NJP_algorithm/``) either way,
    so that an exported tree is identified too."""
    import subprocess

    digest = hashlib.sha256()
    for name in LEARNER_FILES:
        with open(os.path.join(checkout, "NJP_algorithm", name), "rb") as f:
            digest.update(name.encode() + b"\0" + f.read())
    git = lambda *a: subprocess.run(["git", "-C", checkout, *a], capture_output=True, text=True, check=True).stdout.strip()  # noqa: E731
    try:
        top = git("rev-parse", "--show-toplevel")
        commit = git("rev-parse", "HEAD") if os.path.realpath(top) == os.path.realpath(checkout) else None
    except (OSError, subprocess.CalledProcessError):
        commit = None
    return {"path": os.path.abspath(checkout), "git_commit": commit, "learner_sha256": digest.hexdigest()}


def same_run(before: dict, now: dict) -> list[str]:
    """What differs between the provenance a run began with and today's, of what decides its numbers (not
    where the files are, how often it checkpoints, or where it was resumed)."""
    decides = lambda p: {  # noqa: E731
        "coevo": p["coevo"], "torch": p["torch"], "numpy": p["numpy"], "python": p["python"],
        "learner": {k: v for k, v in p["checkout"].items() if k != "path"},
        "scene": p["scene"]["sha256"], "seed, episodes, steps or threads": p["run"],
    }
    a, b = decides(before), decides(now)
    return [k for k in b if a.get(k) != b[k]]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--gym-pps", required=True, help="a WindyLab/Gym-PPS checkout")
    parser.add_argument("--scene", default="scenes/gym-pps-code.ron")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--episodes", type=int, default=2000)
    parser.add_argument("--episode-steps", type=int, default=None, help="the scene's (500) unless given")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (the code's default is 6)")
    parser.add_argument("--out", required=True, help="CSV, one row per episode")
    parser.add_argument("--checkpoint-every", type=int, default=250, help="episodes between checkpoints")
    args = parser.parse_args()
    if os.path.exists(args.out):
        sys.exit(f"--out: {args.out} exists (a finished run); give a new file")
    if args.checkpoint_every < 1:
        sys.exit("--checkpoint-every: must be >= 1")
    import torch

    MADDPG, ReplayBuffer = learner(args.gym_pps)
    print(f"torch {torch.__version__}, {args.threads} thread(s); coevo {coevo.__version__} ({coevo.git_commit})", file=sys.stderr)
    torch.manual_seed(args.seed)
    np.random.seed(args.seed)
    torch.set_num_threads(args.threads)
    env = coevo.parallel_env(args.scene, seed=args.seed, episode_steps=args.episode_steps)
    n_p = sum(a.startswith("predator_") for a in env.possible_agents)
    n = len(env.possible_agents)
    d_o = env.observation_space(env.possible_agents[0]).shape[0]
    shim = types.SimpleNamespace(observation_space=types.SimpleNamespace(shape=(d_o, n)),
                                 action_space=types.SimpleNamespace(shape=(2, n)), agent_types=["adversary", "agent"])
    # main.py's defaults (argparse) and MADDPG's (gamma 0.95): the values the gym-pps preset copies.
    maddpg = MADDPG.init_from_env(shim, agent_alg="MADDPG", adversary_alg="MADDPG", tau=0.01, lr_actor=1e-4,
                                  lr_critic=1e-3, epsilon=0.1, noise=0.1, hidden_dim=64)
    ranges = [slice(0, n_p), slice(n_p, n)]
    buffers = [ReplayBuffer(int(5e5), r.stop - r.start, state_dim=d_o, action_dim=2, start_stop_index=r) for r in ranges]
    turn_max, thrust_max = limits(env)
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    partial, checkpoint = args.out + ".partial", args.out + ".checkpoint"
    header = ["episode", "dos", "doa", "catches", "wall_seconds", "cpu_seconds"]
    provenance_path = args.out + ".provenance.json"
    scene_ron = env.scene_ron()
    provenance = {
        "coevo": {"version": coevo.__version__, "git_commit": coevo.git_commit,
                  "extension_sha256": sha256_of(coevo._coevo.__file__)},
        "torch": torch.__version__,
        "numpy": np.__version__,
        "python": sys.version.split()[0],
        "checkout": checkout_identity(args.gym_pps),
        # The scene as the world runs it (the file resolved: preset, seed and episode length applied).
        "scene": {"path": args.scene, "sha256": hashlib.sha256(scene_ron.encode()).hexdigest()},
        "run": {"seed": args.seed, "episodes": args.episodes, "episode_steps": env.episode_steps,
                "threads": args.threads},
        "checkpoint_every": args.checkpoint_every,
        "resumed_after": [],
    }
    done, elapsed, cpu, rows = 0, 0.0, 0.0, []
    if os.path.exists(os.path.join(checkpoint, "state.pt")):
        # A killed run: its learner from the checkpoint, its rows up to it (later ones are played again).
        try:
            with open(provenance_path) as f:
                before = json.load(f)
            changed = same_run(before, provenance)
        except (OSError, ValueError, KeyError) as e:
            sys.exit(f"{provenance_path}: unreadable or of another version of this script ({e!r}); give a new --out")
        if changed:
            sys.exit(f"{provenance_path}: the run began with another {', '.join(changed)}; resume it with what began it, or give a new --out")
        done, elapsed, cpu = load_checkpoint(checkpoint, maddpg, buffers)
        provenance["resumed_after"] = before["resumed_after"] + [done]
        with open(partial, newline="") as f:
            rows = [r for r in csv.reader(f)][1 : done + 1]
        if len(rows) != done:
            sys.exit(f"{partial}: {len(rows)} rows, the checkpoint has {done} episodes; remove both to start again")
        print(f"resumed after episode {done} from {checkpoint}", file=sys.stderr)
    elif os.path.exists(partial):
        sys.exit(f"--out: {partial} exists without a checkpoint to resume from; remove it to start again")
    with open(provenance_path + ".tmp", "w") as f:
        json.dump(provenance, f, indent=1)
    os.replace(provenance_path + ".tmp", provenance_path)
    with open(partial, "w", newline="") as f:
        out = csv.writer(f)
        out.writerow(header)
        out.writerows(rows)
        f.flush()
        start, cpu_start = time.time() - elapsed, time.process_time() - cpu
        for episode in range(done, args.episodes):
            observations, _ = env.reset(seed=episode_seed(args.seed, episode))
            obs = columns(env, observations)
            maddpg.prep_rollouts(device="cpu")
            maddpg.scale_noise(maddpg.noise, maddpg.epsilon)
            maddpg.reset_noise()
            dos, doa, catches = [], [], 0
            for _ in range(env.episode_steps):
                acted = maddpg.step(torch.Tensor(obs).requires_grad_(False), ranges, explore=True)
                actions = np.column_stack([a.data.numpy() for a in acted]).astype(np.float64)
                observations, rewards, _, _, infos = env.step(to_coevo(env, actions))
                rescale_in_place(actions, turn_max, thrust_max)
                next_obs = columns(env, observations)
                reward = np.array([[rewards[a] for a in env.possible_agents]])
                dones = np.zeros((1, n))
                for b in buffers:
                    b.push(obs, actions, reward, next_obs, dones)
                obs = next_obs
                info = infos[env.possible_agents[0]]
                dos.append(info["dos"])
                doa.append(info["doa"])
                catches += info["catches"]
            for _ in range(30):
                maddpg.prep_training(device="cpu")
                for i in range(maddpg.nagents):
                    if len(buffers[i]) >= 256:
                        maddpg.update(*buffers[i].sample(256), i)
                maddpg.update_all_targets()
                maddpg.prep_rollouts(device="cpu")
            maddpg.noise = max(0.05, maddpg.noise - 5e-5)
            maddpg.epsilon = max(0.05, maddpg.epsilon - 5e-5)
            wall, used = time.time() - start, time.process_time() - cpu_start
            out.writerow([episode + 1, float(np.mean(dos)), float(np.mean(doa)), catches, round(wall, 3), round(used, 3)])
            f.flush()
            if (episode + 1) % args.checkpoint_every == 0 and episode + 1 < args.episodes:
                save_checkpoint(checkpoint, episode + 1, wall, used, maddpg, buffers)
    os.replace(partial, args.out)
    shutil.rmtree(checkpoint, ignore_errors=True)


if __name__ == "__main__":
    main()
