"""coevo from Python: predators and prey that learn together, on coevo's Rust core.

``parallel_env(...)`` is a PettingZoo ``ParallelEnv``: one agent per individual of every species the
scene trains (``Learned``), named ``predator_0 ... prey_9``, each observing coevo's observation vector
(the scene's frame and layout) and acting with two numbers in [-1, 1] (thrust, turn: thrust =
(u0 + 1) / 2 * max_thrust, turn rate = u1 * max_turn_rate), rewarded exactly as coevo's learners are.
Species with another policy (rule-based, a frozen run, a plugin) keep acting inside Rust. Episodes are
truncated at the scene's ``episode_steps``; nobody terminates early (caught prey stay in the world).

``VecEnv(...)`` steps many worlds per call on numpy arrays ``[num_envs, agents, d_o]`` / ``[num_envs,
agents, 2]``, on all cores, each world starting its next episode by itself (world i from ``world_seed(seed, i)``).

``control="blind:prey:prey"`` (or a list of such forms, as ``coevo --eval --control``) hands out the
observations altered exactly as coevo alters what its own actors see in the flocking/herding controls.

``coevolve=["predator"]`` keeps the named learning species coevo's: trained inside the world by coevo's own
Algorithm 1 (exploration, replay, updates, as ``coevo --train``) while Python decides the others, with
``coevolve_schedule="learning"`` (every episode), ``"frozen"`` (held as initialised) or ``"alternate:K"``
(learning K episodes, held K, in turn). ``save_run(path)`` writes coevo's side as a run folder (metrics,
snapshots, checkpoint), whose actor other scenes can load as a ``Frozen`` opponent.

Both step the very schedule ``coevo --train`` steps: no second implementation.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv as _VectorEnv
from gymnasium.vector.utils import batch_space
from pettingzoo import ParallelEnv as _ParallelEnv

from ._coevo import Env as _Env
from ._coevo import VecEnv as _VecEnv
from ._coevo import save_movement as _save_movement
from ._coevo import scene_text as _read_scene_text
from ._coevo import RunFolder, __version__, compare_curves, force_maps, git_commit, holm, response_fields, t_estimate, welch, world_seed
from ._coevo import (  # one exception class per kind of error, all subclasses of CoevoError (a ValueError)
    CheckpointError,
    CoevoError,
    CoevoIOError,
    ExperimentError,
    InputError,
    RunFolderError,
    SceneError,
    SimulationError,
)

__all__ = [
    "parallel_env",
    "env",
    "CoevoParallelEnv",
    "VecEnv",
    "vector_env",
    "CoevoVectorEnv",
    "__version__",
    "git_commit",
    "RunFolder",
    "compare_curves",
    "t_estimate",
    "welch",
    "holm",
    "world_seed",
    "response_fields",
    "force_maps",
    "save_trajectories",
    "CoevoError",
    "SceneError",
    "CheckpointError",
    "RunFolderError",
    "ExperimentError",
    "InputError",
    "SimulationError",
    "CoevoIOError",
]


def _counts(counts: dict[str, int] | None) -> list[tuple[str, int]] | None:
    if counts is None:
        return None
    for name, n in counts.items():
        if not isinstance(n, (int, np.integer)) or isinstance(n, bool) or n < 0:
            raise InputError(f"counts[{name!r}]: a number of agents, an integer ≥ 0 (got {n!r})")
    return [(str(k), int(v)) for k, v in counts.items()]


def _seed(seed, what: str = "seed"):
    """A seed as coevo takes it, an integer in [0, 2⁶⁴) (None passes), or an InputError naming ``what``:
    never Python's OverflowError or TypeError from the conversion."""
    if seed is None:
        return None
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or not 0 <= seed < 2**64:
        raise InputError(f"{what}: an integer in [0, 2^64) (got {seed!r})")
    return int(seed)


def _control(control: str | list[str] | None) -> list[str] | None:
    return [control] if isinstance(control, str) else control


def _made_again(cls, made_with: dict):
    return cls(**made_with)


def _observation_space(high: np.ndarray) -> spaces.Box:
    """One agent's observation space, bounds from the observation's layout: positions in the arena, speeds
    within the clip, unit headings, displacements within the minimum image, heading differences within 2.
    A dimension the scene keeps constant at 0 (the body frame's wall distances in a periodic world, its
    sixth own-state number) gets [-1, 1], not [0, 0]: anything that rescales by the range would divide by
    zero."""
    high = np.where(high > 0, high, 1.0).astype(np.float32)
    return spaces.Box(-high, high, (len(high),), np.float32)


def _action_space() -> spaces.Box:
    """(thrust, turn) in [-1, 1]; a new object per env, so seeding one env's space seeds no other's."""
    return spaces.Box(-1.0, 1.0, (2,), np.float32)

# Numbers per agent in ``state()``: x, y, v_x, v_y, h_x, h_y (m, m/s, unit heading), world frame.
STATE_DIM = 6



def _no_partial_reset(options: dict | None) -> None:
    """Refuses Gymnasium's partial reset (``options={"reset_mask": ...}``), which coevo's vector env does not
    support: ignored, it would reset every world while the caller believes some kept going. Other options
    are ignored, as Gymnasium and PettingZoo expect of an env that takes none."""
    if options and "reset_mask" in options:
        raise InputError("options: reset_mask: a partial reset is not supported (a reset resets every world); "
                         "nothing was reset")

def _species_list(species: str | list[str] | None) -> list[str] | None:
    """``coevolve``: one species name or a list of them."""
    if species is None:
        return None
    if isinstance(species, str):
        return [species]
    return list(species)


class CoevoParallelEnv(_ParallelEnv):
    """A coevo scene as a PettingZoo ``ParallelEnv`` (see the module's docstring).

    Pickling or copying it (``copy.deepcopy``, ``pickle``, the process pools of SuperSuit's
    ``concat_vec_envs_v1`` and Stable-Baselines3) gives the same environment made again from the same
    arguments and the same scene (its text, as read when the env was made, whatever the file holds by
    then): it starts from the same seed, and an episode in progress is not carried over."""

    def __reduce__(self):
        return (_made_again, (CoevoParallelEnv, self._made_with))

    metadata = {"name": "coevo_v0", "render_modes": ["rgb_array", "human"], "is_parallelizable": True,
                "render_fps": 30}

    def __init__(self, scene: str = "scenes/standard.ron", seed: int | None = None,
                 counts: dict[str, int] | None = None, episode_steps: int | None = None,
                 render_mode: str | None = None, render_size: int = 480,
                 control: str | list[str] | None = None, max_cycles: int | None = None,
                 coevolve: list[str] | None = None, coevolve_schedule: str = "learning",
                 _scene_text: str | None = None):
        if render_mode not in (None, "rgb_array", "human"):
            raise InputError(f"render_mode: {render_mode!r} is not one of None, 'rgb_array', 'human'")
        # PettingZoo's name for the episode length (its max_cycles_test), the same as episode_steps.
        if max_cycles is not None and episode_steps is not None and max_cycles != episode_steps:
            raise InputError(f"max_cycles: {max_cycles} differs from episode_steps: {episode_steps}; give one")
        seed = _seed(seed)
        episode_steps = max_cycles if max_cycles is not None else episode_steps
        # What made it: a pickled or copied env is this one made again ([`__reduce__`]), from the scene's
        # text as read now, not from the file again.
        text = _read_scene_text(scene) if _scene_text is None else _scene_text
        self._made_with = dict(scene=scene, seed=seed, counts=counts, episode_steps=episode_steps,
                               render_mode=render_mode, render_size=render_size, control=control,
                               coevolve=coevolve, coevolve_schedule=coevolve_schedule, _scene_text=text)
        self._window = None
        if render_mode == "human":
            try:
                import matplotlib.pyplot  # noqa: F401 (the window of render_mode="human")
            except ImportError as e:
                raise ImportError("render_mode='human' shows frames with matplotlib: pip install matplotlib") from e
        self._env = _Env(scene, seed, _counts(counts), episode_steps, _control(control), text,
                         _species_list(coevolve), coevolve_schedule)
        self.possible_agents = list(self._env.agents())
        # One space object for every agent (all observe the same layout), held by this env only: a
        # method cache would keep every env ever made alive.
        self._observation_space = _observation_space(self._env.observation_high())
        self._action_space = _action_space()
        # Bounded as the state is: positions in the arena, velocities within the top speed, unit headings.
        state_high = self._env.state_high()
        self.state_space = spaces.Box(-state_high, state_high, (len(state_high),), np.float32)
        self._closed = False
        self.agents: list[str] = []
        self._seeded = False
        self.render_mode = render_mode
        self._render_size = render_size

    def observation_space(self, agent: str) -> spaces.Box:
        return self._observation_space

    def action_space(self, agent: str) -> spaces.Box:
        return self._action_space

    def state(self) -> np.ndarray:
        """The global state for a centralised critic: per agent of every species (learned or not), by agent
        id, x, y, v_x, v_y, h_x, h_y (m, m/s, unit heading) in the world frame, flat ``[agents × 6]``."""
        return self._env.state()

    @property
    def episode_steps(self) -> int:
        return self._env.episode_steps

    @property
    def dt(self) -> float:
        """The time step (s): ``positions()`` after successive steps are ``1 / dt`` frames per second apart."""
        return self._env.dt

    def positions(self) -> np.ndarray:
        """Every agent's position ``[agents of all species, 2]`` (m), by coevo's agent id (the ``id``
        column of ``coevo --record``), rule-based species included."""
        return self._env.positions()

    def individual_species(self) -> list[str]:
        """Every agent's species, by coevo's agent id, as ``positions()`` orders them (rule-based included)."""
        return self._env.individual_species()

    def scene_ron(self) -> str:
        """The scene as this env runs it (counts, episode length applied): a loadable scene file."""
        return self._env.scene_ron()

    def save_run(self, path: str) -> None:
        """Saves coevo's side (``coevolve``) into the new folder ``path``, written as ``coevo --train`` writes a
        run: ``metrics.csv``, its actors' snapshots (an opponent pool) and the checkpoint, whose actors load
        as ``Frozen(path)`` opponents. Between episodes (after the reset that follows a truncation); refused
        once a reset has cut an episode short. ``reset(seed=...)`` starts coevo's side afresh."""
        self._env.save_run(str(path))

    def coevo_actor(self, species: str) -> list[np.ndarray]:
        """The parameters of coevo's actor of ``species`` (``coevolve``) as they are now, layer by layer."""
        return self._env.coevo_actor(species)

    def reset(self, seed: int | None = None, options: dict | None = None):
        if self._closed:
            raise InputError("reset: the env is closed; make a new one")
        seed = _seed(seed)
        # The first reset starts from the scene's seed (as `coevo --train` does); a seed starts afresh.
        if seed is None and not self._seeded:
            seed = self._env.seed
        obs = self._env.reset(seed)
        self._seeded = True
        self.agents = list(self.possible_agents)
        observations = {a: obs[i] for i, a in enumerate(self.agents)}
        return observations, {a: {} for a in self.agents}

    def step(self, actions: dict[str, np.ndarray]):
        if self._closed:
            raise InputError("step: the env is closed; make a new one")
        if not self.agents:
            raise InputError("step: no episode is running (before the first reset, or after one ended); reset first")
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise InputError(f"actions: no action for {missing[0]} ({len(missing)} agents missing)")
        unknown = [a for a in actions if a not in self.agents]
        if unknown:
            raise InputError(f"actions: no agent named {unknown[0]!r} (agents: {self.agents[0]} … {self.agents[-1]})")
        rows = []
        for a in self.agents:
            row = np.asarray(actions[a], dtype=np.float32)
            # One action is exactly two numbers, (thrust, turn): a (1, 2) or (2, 1) array is refused rather
            # than flattened, as it most likely comes from a batch mixed up with one agent's action.
            if row.shape != (2,):
                raise InputError(f"actions[{a!r}]: expected shape (2,), got {row.shape}")
            rows.append(row)
        batch = np.stack(rows)
        obs, rewards, truncated, info = self._env.step(batch)
        agents = self.agents
        observations = {a: obs[i] for i, a in enumerate(agents)}
        reward = {a: float(rewards[i]) for i, a in enumerate(agents)}
        terminations = {a: False for a in agents}
        truncations = {a: bool(truncated) for a in agents}
        infos = {a: dict(info) for a in agents}
        if truncated:
            self.agents = []
        return observations, reward, terminations, truncations, infos

    def render(self):
        """The current state drawn as ``coevo --animate`` draws it: an RGB array ``[height, width, 3]``
        with ``render_mode="rgb_array"``; with ``"human"``, shown in a matplotlib window (redrawn in place,
        paced at ``metadata["render_fps"]``; off-screen where matplotlib has no display) and None, as
        PettingZoo's convention asks; None without a render mode."""
        if self._closed:
            raise InputError("render: the env is closed; make a new one")
        if self.render_mode == "rgb_array":
            return self._env.render(self._render_size)
        if self.render_mode == "human":
            import matplotlib
            import matplotlib.pyplot as plt

            frame = self._env.render(self._render_size)
            if self._window is None:
                figure, axes = plt.subplots(figsize=(5, 5))
                axes.set_axis_off()
                self._window = (figure, axes.imshow(frame))
            else:
                self._window[1].set_data(frame)
            try:  # matplotlib ≥ 3.9 lists its backends; older ones name the non-interactive ones in rcsetup
                from matplotlib.backends import BackendFilter, backend_registry

                offscreen = backend_registry.list_builtin(BackendFilter.NON_INTERACTIVE)
            except ImportError:
                from matplotlib import rcsetup

                offscreen = getattr(rcsetup, "non_interactive_bk", ["agg"])
            if matplotlib.get_backend().lower() in offscreen:
                self._window[0].canvas.draw()  # no display (agg, pdf, svg, ...): drawn off-screen
            else:
                plt.pause(1.0 / self.metadata["render_fps"])
        return None

    def close(self):
        self._closed = True
        self.agents = []
        if self._window is not None:
            import matplotlib.pyplot as plt

            plt.close(self._window[0])
            self._window = None


def save_trajectories(path: str, positions, species: list[str], fps: float | None = None) -> None:
    """Writes positions collected from an env (``positions()`` after each step, stacked: ``[frames,
    individuals, 2]``, metres) with each individual's species (``individual_species()``), by the path's
    ending, as ``coevo --record`` does:

    - ``OUT.npy``: the layout of idtracker.ai and trajectorytools, ``path`` (float64) and
      ``PATH-species.npy`` beside it naming each individual's species;
      ``trajectorytools.Trajectories.from_positions(np.load(path))`` reads it;
    - ``OUT.nc``: a ``movement`` poses dataset in netCDF (``position``, ``confidence``, ``species``,
      individuals named ``predator_0``, ...), time in seconds with ``fps`` (``1 / env.dt``), in
      frames without; ``xarray.open_dataset(path)`` reads it.

    Refuses, writing nothing, a wrong shape, a non-finite position, a species list of another length, a
    non-positive fps (or any fps for ``.npy``), another ending, or a path that exists."""
    import os

    positions = np.asarray(positions, dtype=np.float64)
    if positions.ndim != 3 or positions.shape[2] != 2:
        raise InputError(f"positions: shape {positions.shape}, expected [frames, individuals, 2]")
    if not np.isfinite(positions).all():
        raise InputError("positions: holds a non-finite number")
    if len(species) != positions.shape[1]:
        raise InputError(f"species: {len(species)} names for {positions.shape[1]} individuals")
    path = os.fspath(path)
    if path.endswith(".nc"):
        if os.path.exists(path):
            raise InputError(f"{path}: exists; not overwritten")
        _save_movement(path, np.ascontiguousarray(positions), [str(s) for s in species],
                       None if fps is None else float(fps))
        return
    if not path.endswith(".npy"):
        raise InputError(f"path: {path!r} ends in neither .npy nor .nc")
    if fps is not None:
        raise InputError("fps: the .npy layout holds no time; fps is for .nc")
    species_path = path[: -len(".npy")] + "-species.npy"
    for p in (path, species_path):
        if os.path.exists(p):
            raise InputError(f"{p}: exists; not overwritten")
    names = np.array(species, dtype=np.str_)
    # Each written whole under a temporary name, then renamed: never a half-written file under its name.
    for p, array in ((species_path, names), (path, positions)):
        with open(p + ".tmp", "wb") as f:
            np.save(f, array)
        os.replace(p + ".tmp", p)


def parallel_env(scene: str = "scenes/standard.ron", seed: int | None = None, **overrides) -> CoevoParallelEnv:
    """A scene file as a PettingZoo ``ParallelEnv``; ``counts={"prey": 50}``, ``episode_steps=N`` (or
    PettingZoo's ``max_cycles=N``), ``control="blind:prey:prey"``, ``render_mode="rgb_array"`` or
    ``"human"``."""
    return CoevoParallelEnv(scene, seed, **overrides)


def env(scene: str = "scenes/standard.ron", seed: int | None = None, **overrides):
    """The same as a PettingZoo AEC environment (``parallel_to_aec`` of :func:`parallel_env`): agents act
    one after another, and the world steps once all have acted."""
    from pettingzoo.utils import parallel_to_aec

    return parallel_to_aec(parallel_env(scene, seed, **overrides))


class VecEnv:
    """Many worlds of one scene on arrays (see the module's docstring). Pickled or copied, it is made again
    from the same arguments (its worlds' episodes in progress are not carried over)."""

    def __reduce__(self):
        return (_made_again, (VecEnv, self._made_with))

    def __init__(self, scene: str = "scenes/standard.ron", num_envs: int = 64, seed: int = 0,
                 counts: dict[str, int] | None = None, episode_steps: int | None = None,
                 control: str | list[str] | None = None, world_seeds: str = "independent",
                 threads: int | None = None, coevolve: list[str] | None = None,
                 coevolve_schedule: str = "learning", _scene_text: str | None = None):
        """``threads``: step the worlds on at most this many threads (None: every core, or
        ``COEVO_THREADS``); it changes only the speed, never a number. ``coevolve``: the learning species
        coevo trains inside every world (each world's learners learn from that world alone)."""
        text = _read_scene_text(scene) if _scene_text is None else _scene_text
        self._made_with = dict(scene=scene, num_envs=num_envs, seed=seed, counts=counts,
                               episode_steps=episode_steps, control=control, world_seeds=world_seeds,
                               threads=threads, coevolve=coevolve, coevolve_schedule=coevolve_schedule,
                               _scene_text=text)
        self._env = _VecEnv(scene, num_envs, _seed(seed), _counts(counts), episode_steps, _control(control),
                            world_seeds, threads, text, _species_list(coevolve), coevolve_schedule)
        # World i's seed: `seed` for world 0, `world_seed(seed, i)` for the others (independent of the
        # worlds of neighbouring seeds); seed + i with world_seeds="consecutive", as VecEnvs seeded
        # them before (runs with seeds 1 and 2 then shared 31 of 32 worlds' episode starts).
        self.world_seeds = list(self._env.world_seeds())
        self.num_envs = self._env.num_envs
        self.agents = list(self._env.agents())
        self.obs_dim = self._env.obs_dim
        # One agent's observation space (every agent's the same size): bounds from the layout.
        self.single_observation_space = _observation_space(self._env.observation_high())
        self.single_action_space = _action_space()
        self._closed = False

    def _open(self, what: str):
        if self._closed:
            raise InputError(f"{what}: the VecEnv is closed; make a new one")
        return self._env

    def reset(self) -> np.ndarray:
        """The next episode in every world (the first call: world i's first episode, that of its seed, as
        ``parallel_env(seed=world_seeds[i])`` starts): observations ``[num_envs, agents, d_o]``."""
        return self._open("reset").reset()

    def reseed(self, seed: int):
        """Every world starts afresh from ``seed``, in place (one world at a time, the old state freed as
        the new one takes its place): afterwards this VecEnv is one made with ``seed``, and ``reset()``
        hands out each world's first episode (episodes finished and not yet taken are dropped). Should it
        fail part way, the VecEnv is closed: some worlds would be reseeded and others not."""
        env, seed = self._open("reseed"), _seed(seed)
        if seed is None:
            raise InputError("seed: an integer in [0, 2^64) (got None); nothing was reseeded")
        try:
            env.reseed(seed)
        except BaseException:
            self.close()
            raise
        self._made_with["seed"] = seed
        self.world_seeds = list(env.world_seeds())

    def state(self) -> np.ndarray:
        """Every world's global state ``[num_envs, agents of all species, 6]``: x, y, v_x, v_y, h_x, h_y per
        agent (m, m/s, unit heading), by agent id, in the world frame, for centralised critics."""
        return self._open("state").state()

    def close(self):
        """Frees the worlds; stepping afterwards is refused."""
        self._closed = True
        self._env = None

    def step(self, actions: np.ndarray):
        """(observations, rewards ``[num_envs, agents]``, truncated ``[num_envs]``, infos): infos holds the
        step's ``dos``, ``doa`` (headline species) and ``catches``, each ``[num_envs]``.

        Autoreset as Gymnasium 1.x's ``AutoresetMode.SAME_STEP``: a truncated world's observations are
        already its next episode's first, and its last observations (of the state its episode ended in,
        ``[agents, d_o]``, to bootstrap values at the time limit) are ``infos["final_obs"][i]``, an object
        array of ``num_envs`` entries (None where the world did not end), with the mask
        ``infos["_final_obs"]``."""
        actions = np.asarray(actions)
        expected = (self.num_envs, len(self.agents), 2)
        # The shape, not only the count: agent-major `[agents, num_envs, 2]` holds as many numbers and would
        # send each action to another agent.
        if actions.shape != expected:
            raise InputError(f"actions: shape {tuple(actions.shape)}, expected {expected} (num_envs, agents, "
                             "[thrust, turn]); nothing was stepped")
        env = self._open("step")
        if not np.issubdtype(actions.dtype, np.floating):
            raise InputError(f"actions: dtype {actions.dtype}, expected floating point (float32 is stepped "
                             "without a copy); nothing was stepped")
        obs, rewards, truncated, infos = env.step(np.ascontiguousarray(actions, dtype=np.float32))
        final = np.empty(self.num_envs, dtype=object)
        for i, last in enumerate(infos.pop("final_obs")):
            final[i] = last
        infos["final_obs"] = final
        infos["_final_obs"] = np.asarray(truncated, dtype=bool).copy()
        return obs, rewards, truncated, infos

    def save_run(self, world: int, path: str) -> None:
        """Saves world ``world``'s run of coevo's side (``coevolve``) into the new folder ``path``: right after
        a step that ended that world's episode (refused once a ``reset()`` has cut episodes short)."""
        self._open("save_run").save_run(world, str(path))

    def coevo_actor(self, world: int, species: str) -> list[np.ndarray]:
        """World ``world``'s coevo actor of ``species``, layer by layer."""
        return self._open("coevo_actor").coevo_actor(world, species)

    def metrics_header(self) -> str:
        """``metrics.csv``'s header (as ``coevo --train`` writes it) with the Python-decided species as the
        learning ones: the episode's columns, then per learning species ``critic_loss``, ``actor_loss``,
        ``noise_std``, ``epsilon``, then ``wall_seconds``."""
        return self._open("metrics_header").metrics_header()

    def take_episode_rows(self) -> list[str]:
        """The episodes finished since the last call as the first cells of ``metrics.csv`` rows (up to the
        returns), numbered in the order they finished; append your learner's cells and the wall time."""
        return self._open("take_episode_rows").take_episode_rows()


class CoevoVectorEnv(_VectorEnv):
    """Every learning agent of ``num_worlds`` worlds as one ``gymnasium.vector.VectorEnv``: its batch row
    ``w * len(agents) + a`` is agent ``agents[a]`` of world ``w``, so ``num_envs = num_worlds *
    len(agents)``. It is the layout of parameter sharing (one policy for every row, as SuperSuit's
    ``pettingzoo_env_to_vec_env`` and CleanRL's PettingZoo scripts batch agents); for two teams, split the
    rows with ``rows["predator"]`` / ``rows["prey"]`` (``species[i]`` names row i's). A scene whose
    predators follow a rule or a frozen run (not ``Learned``) leaves only the prey in the batch.

    The arrays are :class:`VecEnv`'s, reshaped without a copy; the worlds step in Rust on all cores.
    Gymnasium's API: ``reset(seed=, options=)`` gives ``(observations, infos)`` (a seed makes the worlds
    afresh, world i from ``world_seed(seed, i)``; without one, the next episode of every world), ``step``
    gives ``(observations, rewards, terminations, truncations, infos)``. Nobody terminates (caught prey stay
    in the world); every world's episode is truncated at ``episode_steps``, all worlds at the same step
    (they start together and last as long). ``infos`` holds, for every row, its world's ``dos``, ``doa``
    (headline species) and ``catches`` at that step.

    Autoreset, as ``autoreset_mode`` says (``metadata["autoreset_mode"]``):

    - ``AutoresetMode.NEXT_STEP`` (the default, Gymnasium's, which all its vector wrappers accept): the step
      that truncates returns the episode's last observations; the next step starts the next episode,
      ignores its actions and returns its first observations, rewards 0 and no truncation.
    - ``AutoresetMode.SAME_STEP`` (no step spent on resets, as :class:`VecEnv`): a truncated row's
      observation is already its next episode's first, its last one is ``infos["final_obs"][i]`` (mask
      ``infos["_final_obs"]``), and ``infos["final_info"]`` holds that step's ``dos``, ``doa``, ``catches``.
      Gymnasium's observation wrappers refuse this mode (they would not transform ``final_obs``)."""

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __reduce__(self):
        return (_made_again, (CoevoVectorEnv, self._made_with))

    def __init__(self, scene: str = "scenes/standard.ron", num_worlds: int = 8, seed: int = 0,
                 counts: dict[str, int] | None = None, episode_steps: int | None = None,
                 control: str | list[str] | None = None, threads: int | None = None,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP, _scene_text: str | None = None):
        try:
            mode = AutoresetMode(autoreset_mode)
        except ValueError:
            mode = None
        if mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
            raise InputError(f"autoreset_mode: NEXT_STEP or SAME_STEP (got {autoreset_mode!r})")
        # The scene's text as read now: a reset with a seed, a copy or a pickle makes its worlds from it.
        text = _read_scene_text(scene) if _scene_text is None else _scene_text
        self._made_with = dict(scene=scene, num_worlds=num_worlds, seed=seed, counts=counts,
                               episode_steps=episode_steps, control=control, threads=threads,
                               autoreset_mode=mode, _scene_text=text)
        self.metadata = dict(type(self).metadata, autoreset_mode=mode)
        self._worlds = self._make(seed)
        self.num_worlds = num_worlds
        self.agents = list(self._worlds.agents)
        self.num_envs = num_worlds * len(self.agents)
        self.single_observation_space = self._worlds.single_observation_space
        self.single_action_space = _action_space()
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.species = np.array([a.rsplit("_", 1)[0] for a in self.agents] * num_worlds)
        self.rows = {name: np.flatnonzero(self.species == name) for name in dict.fromkeys(self.species)}
        self.render_mode = None
        # NEXT_STEP: the next episodes' first observations, returned by the step after the truncation.
        self._next_first = None

    def _make(self, seed: int) -> VecEnv:
        made = self._made_with
        return VecEnv(made["scene"], made["num_worlds"], seed, made["counts"], made["episode_steps"],
                      made["control"], threads=made["threads"], _scene_text=made["_scene_text"])

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        if self.closed:
            raise InputError("reset: the env is closed; make a new one")
        _no_partial_reset(options)
        if seed is not None:
            if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool):
                raise InputError(f"seed: one integer seeds every world (world i from world_seed(seed, i)); "
                                 f"got {type(seed).__name__}")
            seed = int(seed)
            if not 0 <= seed < 2**64:
                raise InputError(f"seed: {seed} is outside [0, 2^64); nothing was reset")
            # In place, one world at a time: memory holds the worlds and one more, never two sets.
            try:
                self._worlds.reseed(seed)
            except CoevoError:
                # The worlds, some reseeded and others not, were closed: they are made anew.
                self._worlds.close()
                self._worlds = self._make(seed)
            obs = self._worlds.reset()
        elif self._next_first is not None:
            obs = self._next_first  # the episodes that ended have begun their successors already
        else:
            obs = self._worlds.reset()
        self._next_first = None
        return obs.reshape(self.num_envs, -1), {}

    def step(self, actions):
        if self.closed:
            raise InputError("step: the env is closed; make a new one")
        actions = np.asarray(actions)
        if actions.shape != (self.num_envs, 2):
            raise InputError(f"actions: shape {tuple(actions.shape)}, expected ({self.num_envs}, 2) "
                             f"(num_worlds × agents rows, [thrust, turn]); nothing was stepped")
        if self._next_first is not None:
            # NEXT_STEP's reset step: the actions are ignored, as Gymnasium's autoreset ignores them. Its
            # infos have every step's keys, masked out (no step was taken: no dos, doa or catches of one).
            obs, self._next_first = self._next_first, None
            nothing = np.zeros(self.num_envs, dtype=bool)
            infos = {}
            for key in ("dos", "doa", "catches"):
                infos[key] = np.zeros(self.num_envs)
                infos["_" + key] = nothing.copy()
            return obs.reshape(self.num_envs, -1), np.zeros(self.num_envs), nothing, nothing.copy(), infos
        per = len(self.agents)
        obs, rewards, truncated, infos = self._worlds.step(actions.reshape(self.num_worlds, per, 2))
        truncated = np.asarray(truncated, dtype=bool)
        truncations = np.repeat(truncated, per)
        terminations = np.zeros(self.num_envs, dtype=bool)
        every = np.ones(self.num_envs, dtype=bool)
        out = {}
        for key in ("dos", "doa", "catches"):
            out[key] = np.repeat(infos[key], per)
            out["_" + key] = every
        if truncated.any() and self.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP:
            if not truncated.all():
                raise SimulationError("worlds ended their episodes at different steps; NEXT_STEP autoreset "
                                      "needs them together (use autoreset_mode=SAME_STEP)")
            self._next_first = obs
            obs = np.stack([infos["final_obs"][w] for w in range(self.num_worlds)])
        elif truncated.any():
            final_obs = np.full(self.num_envs, None, dtype=object)
            for w in np.flatnonzero(truncated):
                for a in range(per):
                    final_obs[w * per + a] = infos["final_obs"][w][a]
            out["final_obs"] = final_obs
            out["_final_obs"] = truncations.copy()
            out["final_info"] = {key: out[key] for key in ("dos", "doa", "catches")}
            out["final_info"].update({"_" + key: truncations.copy() for key in ("dos", "doa", "catches")})
            out["_final_info"] = truncations.copy()
        return (obs.reshape(self.num_envs, -1), rewards.reshape(self.num_envs).astype(np.float64),
                terminations, truncations, out)

    def state(self) -> np.ndarray:
        """Every world's global state ``[num_worlds, agents of all species, 6]`` (:meth:`VecEnv.state`)."""
        return self._worlds.state()

    def close_extras(self, **kwargs):
        self._worlds.close()


def vector_env(scene: str = "scenes/standard.ron", num_worlds: int = 8, seed: int = 0, **overrides) -> CoevoVectorEnv:
    """A scene's learning agents in ``num_worlds`` worlds as one ``gymnasium.vector.VectorEnv``
    (:class:`CoevoVectorEnv`): ``counts=``, ``episode_steps=``, ``control=``, ``threads=`` as
    :class:`VecEnv`, ``autoreset_mode=`` (``NEXT_STEP``, the default, or ``SAME_STEP``)."""
    return CoevoVectorEnv(scene, num_worlds, seed, **overrides)
