"""The Python package: PettingZoo's API test, agreement with coevo's own rewards, the batch API."""

import os

# render_mode="human" draws off-screen in the tests, whatever display the machine has.
os.environ.setdefault("MPLBACKEND", "Agg")

import numpy as np  # noqa: E402
import pytest
from pettingzoo.test import parallel_api_test, parallel_seed_test

import coevo

ROOT = os.path.join(os.path.dirname(__file__), "..", "..")
STANDARD = os.path.join(ROOT, "scenes", "standard.ron")


def test_pettingzoo_parallel_api():
    env = coevo.parallel_env(STANDARD, episode_steps=30)
    parallel_api_test(env, num_cycles=1000)


def test_pettingzoo_parallel_seed():
    parallel_seed_test(lambda: coevo.parallel_env(STANDARD, episode_steps=30))


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
    # World 0 is seed 5 itself, world i > 0 coevo.world_seed(5, i): no world shared with seed 6's.
    seeds = vec.world_seeds
    assert seeds == [coevo.world_seed(5, i) for i in range(4)] and seeds[0] == 5
    assert not set(seeds) & set(coevo.VecEnv(STANDARD, num_envs=4, seed=6, episode_steps=6).world_seeds)
    old = coevo.VecEnv(STANDARD, num_envs=4, seed=5, episode_steps=6, world_seeds="consecutive")
    assert old.world_seeds == [5, 6, 7, 8]
    with pytest.raises(coevo.InputError, match="world_seeds"):
        coevo.VecEnv(STANDARD, num_envs=4, seed=5, world_seeds="sequential")
    single = [coevo._coevo.Env(STANDARD, s, None, 6) for s in seeds]
    # World i's first episode is the first episode of its seed, as parallel_env(seed=that seed) starts.
    first = vec.reset()
    assert first.shape == (4, 13, vec.obs_dim)
    for i, s in enumerate(single):
        assert np.array_equal(first[i], s.reset(seeds[i])), i
    par = coevo.parallel_env(STANDARD, seed=5, episode_steps=6)
    obs, _ = par.reset(seed=5)
    assert np.array_equal(first[0], np.stack([obs[a] for a in par.agents])), "world 0 is parallel_env(seed=5)"
    rng = np.random.default_rng(1)
    for t in range(8):
        actions = rng.uniform(-1, 1, (4, 13, 2)).astype(np.float32)
        obs, rewards, truncated, infos = vec.step(actions)
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
    nan = np.zeros((13, 2), np.float32)
    nan[4, 1] = np.nan
    with pytest.raises(ValueError, match=r"actions\[9\]: NaN is not a finite number"):
        env.step(nan)
    vec = coevo.VecEnv(STANDARD, num_envs=2, episode_steps=5)
    vec.reset()
    with pytest.raises(ValueError, match=r"actions: shape \(2, 12, 2\), expected \(2, 13, 2\)"):
        vec.step(np.zeros((2, 12, 2), np.float32))
    with pytest.raises(ValueError, match="num_envs: must be"):
        coevo.VecEnv(STANDARD, num_envs=0)


def test_each_kind_of_error_has_its_exception(tmp_path):
    """A bad scene, a missing checkpoint and a bad argument raise distinct classes, all CoevoError (a
    ValueError, as every coevo error was before kinds)."""
    with pytest.raises(coevo.SceneError, match="cannot read"):
        coevo.parallel_env("no-such-scene.ron")
    with pytest.raises(coevo.SceneError, match="no species named"):
        coevo.parallel_env(STANDARD, counts={"hawk": 3})
    frozen = tmp_path / "frozen.ron"
    frozen.write_text(f'(species: [(name: "prey", policy: Frozen("{tmp_path / "no-such-run"}"))])')
    with pytest.raises(coevo.CheckpointError, match="no-such-run"):
        coevo.parallel_env(str(frozen))
    with pytest.raises(coevo.InputError, match="control: blind:prey:hawk"):
        coevo.parallel_env(STANDARD, control="blind:prey:hawk")
    with pytest.raises(coevo.InputError, match="num_envs: must be"):
        coevo.VecEnv(STANDARD, num_envs=0)
    env = coevo._coevo.Env(STANDARD, None, None, 5)
    env.reset(None)
    with pytest.raises(coevo.InputError, match="actions: expected 26 values"):
        env.step(np.zeros((3, 2), np.float32))
    for kind in (coevo.SceneError, coevo.CheckpointError, coevo.RunFolderError, coevo.ExperimentError,
                 coevo.InputError, coevo.SimulationError, coevo.CoevoIOError):
        assert issubclass(kind, coevo.CoevoError) and issubclass(kind, ValueError)
    assert not issubclass(coevo.SceneError, coevo.CheckpointError)


def test_render_gives_the_animation_frame():
    env = coevo.parallel_env(STANDARD, render_mode="rgb_array", render_size=200)
    env.reset()
    image = env.render()
    assert image.dtype == np.uint8 and image.shape == (200 + 38, 200, 3)
    # The prey's and the predators' colours are in it, not only the floor.
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 10
    assert coevo.parallel_env(STANDARD).render() is None
    with pytest.raises(ValueError, match="render_mode"):
        coevo.parallel_env(STANDARD, render_mode="ansi")
    # "human": the same frame, shown (off-screen without a display), and None as PettingZoo asks.
    human = coevo.parallel_env(STANDARD, render_mode="human", render_size=200)
    human.reset()
    assert human.render() is None
    shown = np.asarray(human._window[1].get_array())
    assert np.array_equal(shown, image), "the frame shown is the rgb_array frame"
    human.close()
    with pytest.raises(ValueError, match="max_cycles"):
        coevo.parallel_env(STANDARD, max_cycles=4, episode_steps=5)


def test_pettingzoo_render_and_max_cycles_tests_as_shipped(monkeypatch):
    # PettingZoo's own tests, unmodified: render_test builds the AEC env in "human" and then in each of
    # metadata's render modes; max_cycles_test calls the module's parallel_env(max_cycles=...) and
    # env(max_cycles=...) with their default scene (scenes/standard.ron, from the project's folder).
    from pettingzoo.test import max_cycles_test, render_test

    render_test(lambda render_mode=None: coevo.env(STANDARD, render_mode=render_mode, render_size=64))
    monkeypatch.chdir(ROOT)
    max_cycles_test(coevo)


def test_vecenv_infos_and_metrics_rows():
    vec = coevo.VecEnv(STANDARD, num_envs=3, seed=2, episode_steps=5)
    header = vec.metrics_header().split(",")
    assert header[:2] == ["episode", "steps"] and header[-1] == "wall_seconds"
    learner = [c for c in header if c.startswith(("critic_loss_", "actor_loss_", "noise_std_", "epsilon_"))]
    assert len(learner) == 8  # both species learn, four columns each
    vec.reset()
    # The first reset is each world's first episode: the single envs' own first episodes.
    single = [coevo._coevo.Env(STANDARD, s, None, 5) for s in vec.world_seeds]
    actions = np.full((3, 13, 2), 0.3, np.float32)
    rows = []
    for t in range(5):
        _, _, truncated, infos = vec.step(actions)
        assert set(infos) == {"dos", "doa", "catches", "final_obs", "_final_obs"} and infos["doa"].shape == (3,)
        for i, s in enumerate(single):
            _, _, _, info = s.step(actions[i])
            assert infos["doa"][i] == info["doa"] and infos["catches"][i] == info["catches"]
        rows += vec.take_episode_rows()
        assert len(rows) == (3 if t == 4 else 0)
    # One row per finished episode, numbered in the order they finished, with the episode's columns.
    assert [r.split(",")[0] for r in rows] == ["0", "1", "2"]
    assert all(len(r.split(",")) == len(header) - len(learner) - 1 for r in rows)
    assert all(r.split(",")[1] == "5" for r in rows)
    assert vec.take_episode_rows() == []


def test_a_control_alters_exactly_its_block():
    seeing = coevo.parallel_env(STANDARD, seed=7)
    blind = coevo.parallel_env(STANDARD, seed=7, control="blind:prey:prey")
    (o_seeing, _), (o_blind, _) = seeing.reset(), blind.reset()
    for a in seeing.agents:
        if a.startswith("predator"):
            assert np.array_equal(o_seeing[a], o_blind[a]), a  # the predators' view is untouched
        else:
            changed = o_seeing[a] != o_blind[a]
            assert changed.any(), a  # the prey saw other prey, and no longer do
            assert (o_blind[a][changed] == 0).all(), a  # zeroed, nothing else altered
    # The controlled observations are handed out; the world is the same: the same actions move it alike.
    act = {a: np.full(2, 0.5, np.float32) for a in seeing.agents}
    seeing.step(act), blind.step(act)
    assert np.array_equal(seeing.positions(), blind.positions())
    with pytest.raises(ValueError, match="control: blind:prey:hawk"):
        coevo.parallel_env(STANDARD, control="blind:prey:hawk")


def _coevo_binary() -> str:
    for path in (os.environ.get("COEVO_BIN", ""), os.path.join(ROOT, "target", "debug", "coevo"),
                 os.path.join(ROOT, "target", "release", "coevo")):
        if path and os.path.exists(path):
            return path
    pytest.fail("no coevo binary: build it first (cargo build), or set COEVO_BIN")


def _actor(path: str):
    """A coevo actor file as a numpy function: Linear-ReLU ×3, Linear, tanh (PyTorch's layout)."""
    from safetensors.numpy import load_file

    t = load_file(path)
    layers = [(t[f"{i}.weight"], t[f"{i}.bias"]) for i in (0, 2, 4, 6)]

    def act(x: np.ndarray) -> np.ndarray:
        for k, (w, b) in enumerate(layers):
            x = x @ w.T + b
            x = np.maximum(x, 0.0) if k < 3 else np.tanh(x)
        return x

    return act


def test_trained_actors_outside_coevo_retrace_coevos_record(tmp_path):
    """coevo's shipped actors, read from their safetensors files and run in numpy, drive the Python env on
    50 prey along coevo --record's trajectory of the same run and seed (to float rounding)."""
    import shutil
    import subprocess

    run = tmp_path / "run"
    shutil.copytree(os.path.join(ROOT, "assets", "trained-standard"), run)
    out = tmp_path / "record.csv"
    steps = 30
    subprocess.run([_coevo_binary(), "--record", str(out), "--run", str(run), "--prey", "50", "--steps",
                    str(steps), "--seed", "4"], check=True, capture_output=True)
    recorded: dict[int, np.ndarray] = {}
    with open(out) as f:
        next(f)
        for line in f:
            step, agent, _, x, y = line.split(",")[:5]
            recorded.setdefault(int(step), []).append((int(agent), float(x), float(y)))
    folder = coevo.RunFolder(str(run))
    env = coevo.parallel_env(folder.scene, seed=4, counts={"prey": 50})
    actors = {s: _actor(folder.actor(s)) for s in ("predator", "prey")}
    obs, _ = env.reset()
    for t in range(steps + 1):
        want = np.array([p[1:] for p in sorted(recorded[t])])
        assert np.allclose(env.positions(), want, atol=1e-4, rtol=0), f"step {t}"
        if t == steps:
            break
        actions = {a: actors[a.rsplit("_", 1)[0]](obs[a]) for a in env.agents}
        obs, *_ = env.step(actions)


def test_run_folder_names_reads_and_refuses(tmp_path):
    """A run folder as coevo names and reads it: a new one for a run trained outside coevo, its metrics
    read whole (a cut line refused, or dropped with partial=True), a folder in use refused."""
    env = coevo.VecEnv(STANDARD, num_envs=1, seed=2, counts={"prey": 4}, episode_steps=5)
    run = coevo.RunFolder.create(str(tmp_path / "r"), coevo.parallel_env(STANDARD).scene_ron())
    assert os.path.isfile(run.scene) and os.path.isdir(os.path.dirname(run.actor("prey")))
    assert os.path.basename(run.evaluation("blind")) == "eval-blind.csv"
    with pytest.raises(coevo.RunFolderError):
        coevo.RunFolder.create(run.path, "()")  # it holds a run now
    env.reset()
    rows = []
    while len(rows) < 2:
        env.step(np.zeros((1, 7, 2), np.float32))
        rows += env.take_episode_rows()
    learning = [c for c in env.metrics_header().split(",") if c.startswith("critic_loss_")]
    with open(run.metrics, "w") as f:
        f.write(env.metrics_header() + "\n")
        for row in rows:
            f.write(row + ",0,0,0,0" * len(learning) + ",1.5\n")
    metrics = run.read_metrics()
    assert metrics["episode"] == [0.0, 1.0] and metrics["wall_seconds"] == [1.5, 1.5]
    with open(run.metrics, "a") as f:
        f.write("2,0.5")  # a line cut short by a kill
    with pytest.raises(coevo.RunFolderError, match="metrics.csv"):
        run.read_metrics()
    assert run.read_metrics(partial=True)["episode"] == [0.0, 1.0]


def test_statistics_are_coevos():
    """The intervals and tests of coevo's reports: Student t of one group, Welch (df rounded down)."""
    e = coevo.t_estimate([1.0, 2.0, 3.0])
    assert e["mean"] == 2.0 and e["n"] == 3 and e["df"] == 2.0
    assert abs(e["ci"] - 4.302652729911275 / 3**0.5) < 1e-9  # t(0.975, 2) · s/√n, s = 1
    assert abs(e["p"] - 0.07417990022744858) < 1e-9
    w = coevo.welch([1.0, 2.0, 3.0, 4.0], [0.0, 0.0, 1.0])
    assert w["mean"] == 2.5 - 1 / 3
    assert w["df"] == 4.0  # Welch–Satterthwaite 4.35, rounded down
    assert coevo.t_estimate([5.0])["ci"] is None
    assert coevo.t_estimate([]) is None
    # A NaN or an infinity is an InputError naming it (it made statrs panic: a PanicException that
    # `except coevo.CoevoError` did not catch).
    for bad in (float("nan"), float("inf"), -float("inf")):
        with pytest.raises(coevo.InputError, match=r"samples\[1\] is"):
            coevo.t_estimate([1.0, bad, 3.0])
        with pytest.raises(coevo.CoevoError, match=r"b\[0\] is"):
            coevo.welch([1.0, 2.0], [bad, 2.0])
        with pytest.raises(coevo.InputError, match=r"p\[2\] is"):
            coevo.holm([0.01, 0.2, bad])
    # Holm's step-down adjustment, in the order given: 3·0.01, then max(0.03, 2·0.03), then max(0.06, 0.04).
    assert coevo.holm([0.01, 0.04, 0.03]) == pytest.approx([0.03, 0.06, 0.06], abs=1e-15)


def test_curves_made_elsewhere_are_judged_as_coevos_reports_judge_two_variants():
    """compare_curves: the windows, Welch's difference, TOST and Holm of coevo's reports, on curves handed
    over from Python (the authors' learner's runs)."""
    def run(last_doa, last_catches):
        flat = lambda first, last: [first] * 100 + [last] * 100  # noqa: E731
        return {"dos": flat(0.25, 0.2), "doa": flat(0.3, last_doa), "catches": flat(70.0, last_catches)}

    theirs = [run(d, 30.0) for d in (0.80, 0.81, 0.82, 0.80)]
    ours = [run(d, 60.0 + d) for d in (0.80, 0.82, 0.81, 0.81, 0.80)]
    results = coevo.compare_curves(
        "f", theirs, ours, [("DoA the same", "DoaLast", 0.05), ("catches", "CatchesLast", None)]
    )
    w = coevo.welch([0.80, 0.81, 0.82, 0.80], [0.80, 0.82, 0.81, 0.81, 0.80])
    assert abs(results[0]["mean"] - w["mean"]) < 1e-12 and abs(results[0]["ci"] - w["ci"]) < 1e-12
    assert results[0]["verdict"].startswith("equivalent within ±0.05")
    assert results[1]["verdict"].startswith("effect detected: -30.8")
    assert results[0]["p_holm"] >= results[0]["p"]
    with pytest.raises(coevo.InputError, match='quantity of "x"'):
        coevo.compare_curves("f", theirs, ours, [("x", "DoaPeak", None)])
    with pytest.raises(coevo.InputError, match=r'theirs\[0\]: no "catches" curve'):
        coevo.compare_curves("f", [{"dos": [0.1], "doa": [0.5]}], ours, [("x", "DoaLast", None)])


def test_version_is_the_crates():
    import re

    with open(os.path.join(ROOT, "Cargo.toml")) as f:
        version = re.search(r'^version = "([^"]+)"', f.read(), re.M).group(1)
    assert coevo.__version__ == version
    assert coevo.git_commit  # the commit the extension was built from ("unknown" outside git)


def test_unknown_agents_and_misshapen_actions_are_refused():
    env = coevo.parallel_env(STANDARD, seed=3, episode_steps=5)
    env.reset()
    good = {a: np.zeros(2, np.float32) for a in env.agents}
    with pytest.raises(ValueError, match="no agent named 'predatr_0'"):
        env.step({**good, "predatr_0": np.zeros(2, np.float32)})
    for shape in [(1, 2), (2, 1), (3,)]:
        with pytest.raises(ValueError, match=r"expected shape \(2,\)"):
            env.step({**good, env.agents[0]: np.zeros(shape, np.float32)})
    # A refused step changes nothing: the same actions then step as on a fresh env.
    twin = coevo.parallel_env(STANDARD, seed=3, episode_steps=5)
    twin.reset()
    a, b = env.step(good), twin.step(good)
    assert all(np.array_equal(a[0][k], b[0][k]) for k in a[0])


def test_infos_keep_their_meaning_with_one_prey():
    # With one prey, its DoS and DoA are undefined: NaN, never the predators'.
    env = coevo.parallel_env(STANDARD, seed=3, counts={"prey": 1}, episode_steps=5)
    env.reset()
    _, _, _, _, infos = env.step({a: np.zeros(2, np.float32) for a in env.agents})
    info = next(iter(infos.values()))
    assert np.isnan(info["doa"]) and np.isnan(info["dos"]), info


def test_a_refused_vector_step_changes_no_world():
    vec = coevo.VecEnv(STANDARD, num_envs=4, seed=1, episode_steps=5)
    twin = coevo.VecEnv(STANDARD, num_envs=4, seed=1, episode_steps=5)
    vec.reset(), twin.reset()
    good = np.full((4, 13, 2), 0.2, np.float32)
    bad = good.copy()
    bad[2, 10, 0] = np.nan  # world 2, the eighth prey (after 3 predators): prey_7
    with pytest.raises(ValueError, match=r"world 2, prey_7: NaN is not a finite number"):
        vec.step(bad)
    # The same numbers agent-major, or flat: refused by shape, as InputError, not sent to other agents.
    for wrong in (good.transpose(1, 0, 2).copy(), good.reshape(-1)):
        with pytest.raises(coevo.InputError, match=r"actions: shape .* expected \(4, 13, 2\)"):
            vec.step(wrong)
    a, b = vec.step(good), twin.step(good)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1]), "no world stepped on the refused call"


def test_a_truncated_worlds_last_observations_are_returned():
    # Gymnasium 1.x's SAME_STEP autoreset: at the time limit a world's observations are its next episode's
    # first, and infos["final_obs"][i] holds the last ones, those parallel_env(seed=world_seeds[i])
    # returns at the same step of a manual rollout with the same actions (so values can be bootstrapped).
    vec = coevo.VecEnv(STANDARD, num_envs=3, seed=11, episode_steps=4)
    vec.reset()
    manual = [coevo.parallel_env(STANDARD, seed=s, episode_steps=4) for s in vec.world_seeds]
    for par in manual:
        par.reset()
    rng = np.random.default_rng(2)
    for t in range(4):
        actions = rng.uniform(-1, 1, (3, 13, 2)).astype(np.float32)
        obs, _, truncated, infos = vec.step(actions)
        assert infos["final_obs"].shape == (3,) and infos["final_obs"].dtype == object
        assert np.array_equal(infos["_final_obs"], truncated)
        for i, par in enumerate(manual):
            last, _, _, truncations, _ = par.step({a: actions[i][k] for k, a in enumerate(par.agents)})
            last = np.stack(list(last.values()))
            if t < 3:
                assert not truncated[i] and infos["final_obs"][i] is None, (t, i)
                assert np.array_equal(obs[i], last), (t, i)
            else:
                assert truncated[i] and all(truncations.values()), i
                assert np.array_equal(infos["final_obs"][i], last), i
                assert not np.array_equal(obs[i], last), "the next episode's first observations"
                first, _ = par.reset()
                assert np.array_equal(obs[i], np.stack([first[a] for a in par.agents])), i


def test_observation_bounds_come_from_the_layout():
    # Declared from the layout, not ±inf, and every observation of a random rollout lies inside them (the
    # PettingZoo API test checks the same on the standard scene).
    for scene in ["standard.ron", "paper.ron", "confined.ron", "gym-pps-code.ron"]:
        env = coevo.parallel_env(os.path.join(ROOT, "scenes", scene), episode_steps=50)
        obs, _ = env.reset(seed=1)
        space = env.observation_space(env.agents[0])
        assert np.all(np.isfinite(space.high)) and np.all(space.high <= 3.0), scene
        rng = np.random.default_rng(0)
        for _ in range(120):
            if not env.agents:
                obs, _ = env.reset()
            assert all(space.contains(o) for o in obs.values()), scene
            obs, *_ = env.step({a: rng.choice([-1.0, 1.0], 2).astype(np.float32) for a in env.agents})
    vec = coevo.VecEnv(STANDARD, num_envs=2, seed=0)
    single = coevo.parallel_env(STANDARD)
    assert np.array_equal(vec.single_observation_space.high, single.observation_space("prey_0").high)


def test_the_gym_pps_adapter_maps_coevos_world_to_the_codes_arrays():
    # python/examples/gym_pps_learner.py hands coevo's world to the authors' learner;
    # its mapping is checked here without torch or a Gym-PPS checkout.
    import importlib.util

    path = os.path.join(ROOT, "python", "examples", "gym_pps_learner.py")
    spec = importlib.util.spec_from_file_location("gym_pps_learner", path)
    adapter = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(adapter)
    env = coevo.parallel_env(os.path.join(ROOT, "scenes", "gym-pps-code.ron"), episode_steps=20)
    observations, _ = env.reset(seed=3)
    obs = adapter.columns(env, observations)
    # pps.py _get_obs: [d_o = 35, agents], predators first; [x, y, v_x, v_y], 2 predator and 5 prey slots,
    # the energy input (+1: full at the start), own heading (a unit vector).
    assert obs.shape == (35, 13) and env.possible_agents[:3] == ["predator_0", "predator_1", "predator_2"]
    assert np.allclose(obs[0:2].T, env.positions(), atol=1e-6)
    assert np.allclose(obs[2:4], 0.0) and np.allclose(obs[32], 1.0)
    assert np.allclose(np.hypot(obs[33], obs[34]), 1.0, atol=1e-6)
    # Full perception: a predator sees the other two predators, a prey the two nearest, in slots 4..12.
    assert all(np.any(obs[k : k + 4, j] != 0.0) for k in (4, 8) for j in (0, 3)), "both predator slots filled"
    # Actions: the learner's [turn, thrust] rows become coevo's [thrust, turn] ...
    actions = np.array([[0.5] * 13, [-0.25] * 13])
    mapped = adapter.to_coevo(env, actions)
    assert all(np.array_equal(mapped[a], np.float32([-0.25, 0.5])) for a in env.possible_agents)
    # ... and the stored copy is rescaled as pps.py's step() rescales it: turn × 0.5 rad (5 rad/s × 0.1 s),
    # thrust from [-1, 1] to [0, 1] N.
    turn_max, thrust_max = adapter.limits(env)
    assert np.allclose(turn_max, 0.5) and np.allclose(thrust_max, 1.0)
    adapter.rescale_in_place(actions, turn_max, thrust_max)
    assert np.allclose(actions[0], 0.25) and np.allclose(actions[1], 0.375)
    # One step with the mapped actions moves the world as coevo's own [thrust, turn] does.
    twin = coevo.parallel_env(os.path.join(ROOT, "scenes", "gym-pps-code.ron"), episode_steps=20)
    twin.reset(seed=3)
    a, *_ = env.step(mapped)
    b, *_ = twin.step({name: np.float32([-0.25, 0.5]) for name in twin.possible_agents})
    assert all(np.array_equal(a[n], b[n]) for n in env.possible_agents)


def test_the_shipped_scenes_load_outside_the_clone(tmp_path, monkeypatch):
    # An installed wheel has no scenes/ folder beside it: the shipped scenes are built in, by the name a
    # clone gives them (a file of that name in the working folder would win).
    monkeypatch.chdir(tmp_path)
    vec = coevo.VecEnv(num_envs=2, episode_steps=3)
    assert vec.reset().shape[:2] == (2, 13)
    par = coevo.parallel_env("scenes/paper.ron", episode_steps=3)
    par.reset(seed=1)
    with pytest.raises(coevo.SceneError):
        coevo.parallel_env("scenes/no-such-scene.ron")


def test_response_fields_of_the_shipped_run():
    fields = coevo.response_fields(os.path.join(ROOT, "assets", "trained-standard"))
    prey = [f for f in fields if f["species"] == "prey" and f["observed"] == "predator" and f["rel_heading"] == 0.0]
    assert len(prey) == 1
    f = prey[0]
    assert f["turn"].shape == f["thrust"].shape == (len(f["centres"]), len(f["centres"]))
    assert np.all(np.abs(f["turn"][np.isfinite(f["turn"])]) <= 1.0)
    # The trained prey turn away from a predator close beside them (the "Why they swarm" page).
    row = lambda left: int(np.argmin(np.abs(f["centres"] - left)))  # noqa: E731
    ahead = int(np.argmin(np.abs(f["centres"] - 0.0)))
    assert f["turn"][row(0.1), ahead] < 0 < f["turn"][row(-0.1), ahead]
    assert len(f["alone"]) == 2
    # Amid observations of the trained swarm: one field per observed species (a parallel neighbour), the
    # same evasion, and `alone` the mean action on the swarm's own observations.
    swarm = coevo.response_fields(os.path.join(ROOT, "assets", "trained-standard"), swarm=True)
    assert {f["rel_heading"] for f in swarm} == {0.0}
    s = [f for f in swarm if f["species"] == "prey" and f["observed"] == "predator"][0]
    assert s["turn"][row(0.1), ahead] < 0 < s["turn"][row(-0.1), ahead]
    assert s["alone"] != f["alone"]


def test_force_maps_of_a_hand_made_trajectory(tmp_path):
    # A prey at the origin heading east, turning right by 0.01 rad per 0.1 s step, a predator 0.3 m to its
    # left: its map against the nearest predator turns right (−0.1 rad/s) in that bin, and nowhere else.
    lines = ["step,id,species,x,y,vx,vy,theta,thrust,turn_rate,reward"]
    for t in range(21):
        th = -0.01 * t
        hx, hy = np.cos(th), np.sin(th)
        lines.append(f"{t},0,prey,0,0,{0.5 * hx},{0.5 * hy},{th},,,")
        lines.append(f"{t},1,predator,{-0.3 * hy},{0.3 * hx},0,0,{th},,,")
    traj = tmp_path / "hand.csv"
    traj.write_text("\n".join(lines) + "\n")
    maps = coevo.force_maps(str(traj), "scenes/standard.ron")
    m = next(m for m in maps if m["species"] == "prey" and m["observed"] == "predator")
    c = m["centres"]
    r, a = int(np.argmin(np.abs(c - 0.3))), int(np.argmin(np.abs(c)))
    assert m["count"][r, a] == 20 and m["count"].sum() == 20
    assert abs(m["turning"][r, a] + 0.1) < 1e-9
    with pytest.raises(coevo.CoevoError, match="missing.csv"):
        coevo.force_maps(str(traj).replace("hand", "missing"))


def test_a_run_folder_is_made_only_for_a_readable_scene(tmp_path):
    with pytest.raises(coevo.SceneError, match="scene_ron"):
        coevo.RunFolder.create(str(tmp_path / "run"), "((((not a scene")
    assert not (tmp_path / "run").exists(), "nothing made"
    run = coevo.RunFolder.create(str(tmp_path / "run"), coevo.parallel_env(STANDARD).scene_ron())
    assert os.path.exists(run.scene)


def test_envs_pickle_and_copy_as_made_again():
    # SuperSuit's concat_vec_envs_v1 and SB3's subprocess envs pickle the env; a copy is the same env made
    # again from the same arguments, so it steps exactly as a fresh one does.
    import copy
    import pickle

    par = coevo.parallel_env(STANDARD, seed=3, counts={"prey": 5}, episode_steps=4)
    for again in (pickle.loads(pickle.dumps(par)), copy.deepcopy(par)):
        assert again.possible_agents == par.possible_agents
        a, _ = again.reset(seed=3)
        b, _ = coevo.parallel_env(STANDARD, seed=3, counts={"prey": 5}, episode_steps=4).reset(seed=3)
        assert all(np.array_equal(a[k], b[k]) for k in a)
    vec = coevo.VecEnv(STANDARD, num_envs=2, seed=4, episode_steps=3)
    again = pickle.loads(pickle.dumps(vec))
    assert again.world_seeds == vec.world_seeds and np.array_equal(again.reset(), vec.reset())


def test_a_pickled_env_comes_back_with_its_scene_even_after_the_file_changed(tmp_path):
    # The scene's text travels with the pickle: a file edited (or gone) in between changes nothing.
    import pickle

    path = tmp_path / "mine.ron"
    path.write_text(coevo.parallel_env(STANDARD, counts={"prey": 10}).scene_ron())
    made = [coevo.parallel_env(str(path)), coevo.VecEnv(str(path), num_envs=2),
            coevo.vector_env(str(path), num_worlds=2)]
    pickled = [pickle.dumps(e) for e in made]
    path.write_text(coevo.parallel_env(STANDARD, counts={"prey": 4}).scene_ron())
    par, vec, vector = [pickle.loads(p) for p in pickled]
    assert len(par.possible_agents) == len(made[0].possible_agents) == 13
    assert vec.reset().shape == made[1].reset().shape
    assert vector.reset(seed=1)[0].shape == made[2].reset(seed=1)[0].shape
    path.unlink()
    assert len(pickle.loads(pickled[0]).possible_agents) == 13


def test_supersuit_vectorises_it_for_stable_baselines3():
    # PettingZoo's SB3 route: every agent a sub-env (pettingzoo_env_to_vec_env_v1), copies concatenated
    # (concat_vec_envs_v1, which copies the env); runs where SuperSuit is installed.
    ss = pytest.importorskip("supersuit")
    vec = ss.pettingzoo_env_to_vec_env_v1(coevo.parallel_env(STANDARD, episode_steps=5))
    vec = ss.concat_vec_envs_v1(vec, 2, num_cpus=0, base_class="gymnasium")
    obs, _ = vec.reset(seed=1)
    assert obs.shape == (26, vec.observation_space.shape[0])
    for _ in range(6):
        obs, rewards, _, truncated, _ = vec.step(np.stack([vec.action_space.sample() for _ in range(26)]))
    assert rewards.shape == (26,) and np.all(np.isfinite(obs))


def test_the_vector_env_is_gymnasiums():
    # Every learning agent of every world is a row of one gymnasium.vector.VectorEnv (world-major), its
    # arrays VecEnv's reshaped: the same worlds, the same numbers.
    from gymnasium.vector import AutoresetMode, VectorEnv

    assert coevo.vector_env(STANDARD, num_worlds=1).metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    env = coevo.vector_env(STANDARD, num_worlds=3, seed=5, counts={"prey": 4}, episode_steps=3,
                           autoreset_mode=AutoresetMode.SAME_STEP)
    assert isinstance(env, VectorEnv) and env.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    per = len(env.agents)
    assert env.num_envs == 3 * per == env.observation_space.shape[0] == env.action_space.shape[0]
    assert env.single_action_space.shape == (2,) and list(env.species[:per]) == [a.rsplit("_", 1)[0] for a in env.agents]
    assert sorted(np.concatenate(list(env.rows.values()))) == list(range(env.num_envs))
    raw = coevo.VecEnv(STANDARD, num_envs=3, seed=5, counts={"prey": 4}, episode_steps=3)
    obs, infos = env.reset(seed=5)
    assert infos == {} and np.array_equal(obs, raw.reset().reshape(env.num_envs, -1))
    assert env.observation_space.contains(obs)
    rng = np.random.default_rng(1)
    for t in range(4):
        actions = rng.uniform(-1, 1, (env.num_envs, 2)).astype(np.float32)
        obs, rewards, terminations, truncations, infos = env.step(actions)
        r_obs, r_rew, r_trunc, r_infos = raw.step(actions.reshape(3, per, 2))
        assert np.array_equal(obs, r_obs.reshape(env.num_envs, -1))
        assert np.allclose(rewards, r_rew.reshape(-1)) and rewards.shape == (env.num_envs,)
        assert not terminations.any() and np.array_equal(truncations, np.repeat(r_trunc, per))
        assert np.array_equal(infos["doa"], np.repeat(r_infos["doa"], per)) and infos["_doa"].all()
        if t == 2:  # every world truncates at its third step: the rows' last observations are kept
            assert truncations.all() and infos["_final_obs"].all() and infos["_final_info"].all()
            for w in range(3):
                for a in range(per):
                    assert np.array_equal(infos["final_obs"][w * per + a], r_infos["final_obs"][w][a])
        else:
            assert "final_obs" not in infos
    # A seed makes the worlds afresh: the same seed, the same first observations.
    again, _ = env.reset(seed=5)
    first, _ = coevo.vector_env(STANDARD, num_worlds=3, seed=5, counts={"prey": 4}, episode_steps=3,
                                autoreset_mode="SameStep").reset()
    assert np.array_equal(again, first)
    other, _ = env.reset(seed=6)
    assert not np.array_equal(other, first)
    with pytest.raises(coevo.InputError, match=r"actions: shape \(3, 2\), expected \(21, 2\)"):
        env.step(np.zeros((3, 2), np.float32))
    with pytest.raises(coevo.InputError, match="seed: one integer"):
        env.reset(seed=[1, 2])
    env.close()
    assert env.closed
    with pytest.raises(coevo.InputError, match="closed"):
        env.step(np.zeros((env.num_envs, 2), np.float32))


def test_next_step_autoreset_spends_a_step_on_the_reset():
    # Gymnasium's default: the truncating step returns the episode's last observations, the next one the
    # next episode's first (its actions ignored), the same observations SAME_STEP gives at once.
    same = coevo.vector_env(STANDARD, num_worlds=2, seed=7, counts={"prey": 3}, episode_steps=2,
                            autoreset_mode="SameStep")
    nxt = coevo.vector_env(STANDARD, num_worlds=2, seed=7, counts={"prey": 3}, episode_steps=2)
    a, _ = same.reset()
    b, _ = nxt.reset()
    assert np.array_equal(a, b)
    actions = np.full((nxt.num_envs, 2), 0.5, np.float32)
    same.step(actions)
    nxt.step(actions)
    s_obs, s_rew, _, s_trunc, s_infos = same.step(actions)
    n_obs, n_rew, _, n_trunc, n_infos = nxt.step(actions)
    assert s_trunc.all() and n_trunc.all() and np.array_equal(s_rew, n_rew) and "final_obs" not in n_infos
    assert np.array_equal(n_obs, np.stack(list(s_infos["final_obs"])))
    r_obs, r_rew, r_term, r_trunc, r_infos = nxt.step(np.full((nxt.num_envs, 2), 9.0, np.float32))
    assert np.array_equal(r_obs, s_obs) and not r_rew.any() and not r_trunc.any() and not r_term.any()
    # Its infos have every step's keys, masked out: no step was taken.
    assert {"dos", "doa", "catches"} <= set(r_infos) and not any(r_infos["_" + k].any() for k in ("dos", "doa", "catches"))
    assert np.array_equal(nxt.step(actions)[0], same.step(actions)[0])  # the reset step's actions were ignored
    with pytest.raises(coevo.InputError, match="autoreset_mode: NEXT_STEP or SAME_STEP"):
        coevo.vector_env(STANDARD, num_worlds=1, autoreset_mode="disabled")


def test_gymnasiums_vector_wrappers_take_it():
    from gymnasium.wrappers.vector import ClipAction, NormalizeObservation, NormalizeReward, RecordEpisodeStatistics

    env = coevo.vector_env(STANDARD, num_worlds=2, seed=1, counts={"prey": 3}, episode_steps=4)
    env = RecordEpisodeStatistics(NormalizeReward(NormalizeObservation(ClipAction(env))))
    obs, _ = env.reset(seed=1)
    episodes = 0
    for _ in range(9):
        obs, rewards, terminations, truncations, infos = env.step(2.0 * env.action_space.sample())
        assert np.all(np.isfinite(obs)) and np.all(np.isfinite(rewards))
        if "episode" in infos:
            episodes += int(infos["_episode"].sum())
            assert infos["episode"]["l"][infos["_episode"]].tolist() == [4] * int(infos["_episode"].sum())
    assert episodes == 2 * env.num_envs  # two episodes of 4 steps and a reset step in 9, in every row


def test_spaces_have_no_zero_width_dimension():
    # The body frame's wall distances in a periodic world (and its sixth own-state number) are always 0:
    # they get [-1, 1], so rescaling by the range never divides by zero.
    for scene in ["standard.ron", "paper.ron", "confined.ron"]:
        env = coevo.parallel_env(os.path.join(ROOT, "scenes", scene))
        space = env.observation_space(env.possible_agents[0])
        assert np.all(space.high > space.low), scene
        vec = coevo.vector_env(os.path.join(ROOT, "scenes", scene), num_worlds=1)
        assert np.all(vec.single_observation_space.high > vec.single_observation_space.low), scene
    # The same object every call, held by its env (no method cache keeping dropped envs alive).
    assert env.observation_space("prey_0") is env.observation_space("predator_0")


def test_the_global_state_for_centralised_critics():
    env = coevo.parallel_env(STANDARD, seed=2, counts={"prey": 4}, episode_steps=5)
    env.reset()
    state = env.state()
    population = len(env.positions())
    assert state.shape == (population * 6,) == env.state_space.shape and state.dtype == np.float32
    rows = state.reshape(population, 6)
    assert np.allclose(rows[:, :2], env.positions(), atol=1e-4)
    assert np.allclose(np.hypot(rows[:, 4], rows[:, 5]), 1.0, atol=1e-5)  # unit headings
    # Bounded as the state is (positions in the arena, velocities within the top speed, unit headings),
    # and within those bounds as it moves.
    assert np.isfinite(env.state_space.high).all() and env.state_space.contains(state)
    for _ in range(4):
        env.step({a: np.ones(2, np.float32) for a in env.agents})
        assert env.state_space.contains(env.state())
    assert not np.array_equal(env.state(), state)
    vec = coevo.VecEnv(STANDARD, num_envs=2, seed=2, counts={"prey": 4}, episode_steps=5)
    vec.reset()
    assert vec.state().shape == (2, population, 6)
    first = coevo.parallel_env(STANDARD, seed=2, counts={"prey": 4}, episode_steps=5)
    first.reset()
    assert np.array_equal(vec.state()[0].reshape(-1), first.state())


def test_threads_change_no_number():
    a = coevo.VecEnv(STANDARD, num_envs=4, seed=3, episode_steps=6, threads=1)
    b = coevo.VecEnv(STANDARD, num_envs=4, seed=3, episode_steps=6)
    assert np.array_equal(a.reset(), b.reset())
    rng = np.random.default_rng(0)
    for _ in range(8):
        actions = rng.uniform(-1, 1, (4, len(a.agents), 2)).astype(np.float32)
        for x, y in zip(a.step(actions)[:3], b.step(actions)[:3]):
            assert np.array_equal(x, y)
    with pytest.raises(coevo.InputError, match="threads: must be"):
        coevo.VecEnv(STANDARD, num_envs=1, threads=0)


def test_closed_envs_and_integer_actions_are_refused():
    par = coevo.parallel_env(STANDARD, episode_steps=3)
    par.reset()
    par.close()
    with pytest.raises(coevo.InputError, match="closed"):
        par.step({a: np.zeros(2, np.float32) for a in par.possible_agents})
    drawn = coevo.parallel_env(STANDARD, episode_steps=3, render_mode="rgb_array")
    drawn.reset()
    drawn.close()
    with pytest.raises(coevo.InputError, match="render: the env is closed"):
        drawn.render()
    vec = coevo.VecEnv(STANDARD, num_envs=1)
    vec.reset()
    with pytest.raises(coevo.InputError, match="dtype int64, expected floating point"):
        vec.step(np.zeros((1, len(vec.agents), 2), np.int64))
    vec.close()
    with pytest.raises(coevo.InputError, match="closed"):
        vec.reset()


def test_a_partial_reset_is_refused_not_ignored():
    # Gymnasium's partial reset (options={"reset_mask": ...}) is not supported by the vector env: said, and
    # nothing is reset. Other options are ignored, as PettingZoo's and Gymnasium's checks expect.
    env = coevo.vector_env(STANDARD, num_worlds=2, episode_steps=3)
    first, _ = env.reset(seed=1)
    with pytest.raises(coevo.InputError, match="reset_mask: a partial reset is not supported"):
        env.reset(options={"reset_mask": np.array([True, False])})
    again, _ = env.reset(seed=1, options={"other": 1})
    assert np.array_equal(first, again)
    par = coevo.parallel_env(STANDARD, episode_steps=3)
    par.reset(seed=0, options={"options": 1})


def test_a_refused_step_before_the_first_reset_leaves_it_the_first_episode():
    fresh = coevo.VecEnv(STANDARD, num_envs=2, seed=5).reset()
    vec = coevo.VecEnv(STANDARD, num_envs=2, seed=5)
    with pytest.raises(coevo.InputError):
        vec.step(np.full((2, len(vec.agents), 2), np.nan, np.float32))
    assert np.array_equal(vec.reset(), fresh)
    par = coevo.parallel_env(STANDARD, seed=5)
    with pytest.raises(coevo.InputError, match="reset first"):
        par.step({a: np.zeros(2, np.float32) for a in par.possible_agents})


def test_every_env_form_refuses_bad_seeds_and_counts_with_an_input_error():
    # One class for one kind of error in every form, never Python's OverflowError or TypeError from a
    # conversion (an InputError is a CoevoError, a ValueError).
    makers = [lambda **k: coevo.parallel_env(STANDARD, **k), lambda **k: coevo.VecEnv(STANDARD, num_envs=1, **k),
              lambda **k: coevo.vector_env(STANDARD, num_worlds=1, **k)]
    for make in makers:
        for seed in (-1, 2**64, 1.5, True):
            with pytest.raises(coevo.InputError, match="seed: an integer in"):
                make(seed=seed)
        with pytest.raises(coevo.InputError, match=r"counts\['prey'\]: a number of agents"):
            make(counts={"prey": -1})
    par = coevo.parallel_env(STANDARD)
    with pytest.raises(coevo.InputError, match="seed: an integer in"):
        par.reset(seed=-3)


def test_a_record_as_npy_is_read_by_trajectorytools(tmp_path):
    # `coevo --record OUT.npy` in idtracker.ai's and trajectorytools' layout, read back by trajectorytools
    # itself (installed by .ci/run), with the CLI the repository's tests built.
    import subprocess

    tt = pytest.importorskip("trajectorytools")
    built = [os.path.join(ROOT, "target", p, "coevo") for p in ("debug", "release")]
    binary = next((b for b in built if os.path.exists(b)), None)
    if binary is None:
        pytest.skip("no coevo binary built (cargo build)")
    out = tmp_path / "swarm.npy"
    subprocess.run([binary, "--record", str(out), "--scene", STANDARD, "--steps", "30", "--seed", "2"],
                   check=True, capture_output=True)
    positions, species = np.load(out), np.load(tmp_path / "swarm-species.npy")
    assert positions.shape == (31, 13, 2) and list(species).count("prey") == 10
    tr = tt.Trajectories.from_positions(positions)
    assert tr.number_of_individuals == 13 and np.isfinite(tr.speed).all()


def _play(env, episodes):
    """Plays ``episodes`` episodes of a parallel env with the prey turning by a fixed rule of what they see;
    every observation handed out."""
    seen = []
    for e in range(episodes):
        obs, _ = env.reset() if e else env.reset(seed=env._env.seed)
        while env.agents:
            seen.append(np.stack([obs[a] for a in env.agents]))
            actions = {a: np.tanh(np.array([obs[a][0], obs[a][1] - obs[a][2]], np.float32)) for a in env.agents}
            obs, _, _, _, _ = env.step(actions)
    return np.concatenate(seen)


def _quick_scene(tmp_path):
    """The standard scene with learners that update within a few 20-step episodes."""
    import re

    text = coevo.parallel_env("scenes/standard.ron").scene_ron()
    for field, value in (("warmup_transitions", 32), ("batch_size", 16), ("hidden", 16)):
        text, n = re.subn(rf"{field}: \d+", f"{field}: {value}", text)
        assert n == 1, field
    path = tmp_path / "quick.ron"
    path.write_text(text)
    return str(path)


def _quick(scene="scenes/standard.ron", **kw):
    return coevo.parallel_env(scene, seed=5, episode_steps=20, **kw)


def test_coevo_keeps_training_its_predators_while_python_decides_the_prey(tmp_path):
    scene = _quick_scene(tmp_path)
    env = _quick(scene, coevolve=["predator"])
    assert all(a.startswith("prey_") for a in env.possible_agents)
    before = env.coevo_actor("predator")
    seen = _play(env, 4)
    after = env.coevo_actor("predator")
    assert any(not np.array_equal(a, b) for a, b in zip(before, after)), "coevo's predators learned"
    # Reproducible from the seed: the same prey decisions give the same run.
    again = _quick(scene, coevolve="predator")
    np.testing.assert_array_equal(_play(again, 4), seen)
    for a, b in zip(again.coevo_actor("predator"), after):
        np.testing.assert_array_equal(a, b)
    # Held fixed, the predators stay as initialised.
    frozen = _quick(scene, coevolve=["predator"], coevolve_schedule="frozen")
    _play(frozen, 2)
    for a, b in zip(frozen.coevo_actor("predator"), before):
        np.testing.assert_array_equal(a, b)
    # coevo's side saved as a run folder: one metrics row per episode, snapshots for an opponent pool.
    env.reset()
    env.save_run(tmp_path / "predators")
    rows = (tmp_path / "predators" / "metrics.csv").read_text().splitlines()
    assert len(rows) == 1 + 4
    assert any((tmp_path / "predators" / "snapshots").iterdir())


def test_bad_coevolve_arguments_are_input_errors():
    with pytest.raises(coevo.InputError, match="not a learned species"):
        _quick(coevolve=["wolf"])
    with pytest.raises(coevo.InputError, match="none is left"):
        _quick(coevolve=["predator", "prey"])
    with pytest.raises(coevo.InputError, match="coevolve_schedule"):
        _quick(coevolve=["predator"], coevolve_schedule="sometimes")
    with pytest.raises(coevo.InputError, match="coevolve names none"):
        _quick().save_run("unused")
    vec = coevo.VecEnv("scenes/standard.ron", num_envs=2, seed=3, episode_steps=20, coevolve=["predator"],
                       coevolve_schedule="alternate:2")
    assert vec.agents[0].startswith("prey_")
    with pytest.raises(coevo.InputError):
        vec.coevo_actor(5, "predator")


def test_positions_collected_in_python_save_in_records_layout(tmp_path):
    # An outside learner's run kept as coevo --record OUT.npy keeps one: [frames, individuals, 2] float64 and
    # the species beside it, each individual by coevo's agent id; trajectorytools reads it where installed.
    env = coevo.parallel_env(STANDARD, seed=2, episode_steps=30)
    obs, _ = env.reset()
    frames = [env.positions()]
    while env.agents:
        obs, _, _, _, _ = env.step({a: np.array([0.5, 0.1], np.float32) for a in env.agents})
        frames.append(env.positions())
    out = tmp_path / "mine.npy"
    coevo.save_trajectories(out, frames, env.individual_species())
    positions, species = np.load(out), np.load(tmp_path / "mine-species.npy")
    assert positions.shape == (31, 13, 2) and positions.dtype == np.float64
    np.testing.assert_array_equal(positions, np.stack(frames))
    assert list(species).count("prey") == 10 and list(species).count("predator") == 3
    with pytest.raises(coevo.InputError, match="exists"):
        coevo.save_trajectories(out, frames, env.individual_species())
    with pytest.raises(coevo.InputError, match="names for"):
        coevo.save_trajectories(tmp_path / "other.npy", frames, ["prey"])
    assert not (tmp_path / "other.npy").exists()
    # The same layout as the CLI's: species stored alike.
    built = [os.path.join(ROOT, "target", p, "coevo") for p in ("debug", "release")]
    binary = next((b for b in built if os.path.exists(b)), None)
    if binary is not None:
        import subprocess

        cli = tmp_path / "cli.npy"
        subprocess.run([binary, "--record", str(cli), "--scene", STANDARD, "--steps", "30", "--seed", "2"],
                       check=True, capture_output=True)
        assert np.load(cli).shape == positions.shape
        assert np.load(tmp_path / "cli-species.npy").dtype.kind == species.dtype.kind
        np.testing.assert_array_equal(np.load(tmp_path / "cli-species.npy"), species)
    tt = pytest.importorskip("trajectorytools")
    assert tt.Trajectories.from_positions(positions).number_of_individuals == 13


def _movement_dataset(path):
    # A `movement` poses dataset as movement's own netCDF loader opens one (its napari widget):
    # xarray.open_dataset, then movement's validator where movement is installed (.ci/run installs it). The
    # file has movement 0.17's dimension names; an older movement (the last for Python 3.11) checks the same
    # dataset under its plural names.
    xr = pytest.importorskip("xarray")
    if not {"scipy", "netcdf4"} & set(xr.backends.list_engines()):
        pytest.skip("xarray has no netCDF engine here (scipy or netCDF4)")
    ds = xr.open_dataset(path)
    try:
        from movement.validators.datasets import ValidPosesInputs
    except ImportError:
        return ds
    ValidPosesInputs.validate(_in_installed_movement_names(ds))
    return ds


def _in_installed_movement_names(ds):
    # movement before 0.17 names the dimensions `keypoints` and `individuals`.
    from movement.validators.datasets import ValidPosesInputs

    if "keypoints" in ValidPosesInputs.DIM_NAMES:
        return ds.rename({"keypoint": "keypoints", "individual": "individuals"})
    return ds


def test_a_record_as_netcdf_is_a_movement_poses_dataset(tmp_path):
    # `coevo --record OUT.nc` holds `--record OUT.npy`'s positions for the same seed, in movement's layout:
    # position (time, space, keypoint, individual), individuals named by species, time in seconds.
    import subprocess

    built = [os.path.join(ROOT, "target", p, "coevo") for p in ("debug", "release")]
    binary = next((b for b in built if os.path.exists(b)), None)
    if binary is None:
        pytest.skip("no coevo binary built (cargo build)")
    for name in ("movement.nc", "swarm.npy"):
        subprocess.run([binary, "--record", str(tmp_path / name), "--scene", STANDARD, "--steps", "30", "--seed", "2"],
                       check=True, capture_output=True)
    ds = _movement_dataset(tmp_path / "movement.nc")
    assert ds.position.dims == ("time", "space", "keypoint", "individual")
    assert ds.attrs["ds_type"] == "poses" and ds.attrs["source_software"] == "coevo"
    assert ds.attrs["time_unit"] == "seconds"
    np.testing.assert_allclose(ds.time.values * ds.attrs["fps"], np.arange(31), rtol=0, atol=1e-9)
    positions = np.load(tmp_path / "swarm.npy")
    # movement's [time, space, keypoint 0, individuals] is the npy's [frames, individuals, 2] transposed.
    np.testing.assert_array_equal(ds.position.values[:, :, 0, :].transpose(0, 2, 1), positions)
    np.testing.assert_array_equal(ds.species.values.astype(str), np.load(tmp_path / "swarm-species.npy"))
    assert list(ds.individual.values.astype(str)[:4]) == ["predator_0", "predator_1", "predator_2", "prey_0"]
    assert list(ds.space.values.astype(str)) == ["x", "y"] and (ds.confidence.values == 1).all()
    try:
        from movement.kinematics import compute_speed
    except ImportError:
        return
    # movement's own kinematics on it: speeds as the positions give them (frames 1/fps apart).
    speed = compute_speed(_in_installed_movement_names(ds).position).values[:, 0, :]
    assert np.isfinite(speed).all() and (speed < 100).all()


def test_positions_collected_in_python_save_as_a_movement_dataset(tmp_path):
    # save_trajectories("OUT.nc", ...) writes what `coevo --record OUT.nc` writes, from positions collected
    # in Python, with the env's time step; it refuses what the npy form refuses, writing nothing.
    env = coevo.parallel_env(STANDARD, seed=2, episode_steps=30)
    env.reset()
    frames = [env.positions()]
    while env.agents:
        env.step({a: np.array([0.5, 0.1], np.float32) for a in env.agents})
        frames.append(env.positions())
    out = tmp_path / "mine.nc"
    coevo.save_trajectories(out, frames, env.individual_species(), fps=1 / env.dt)
    ds = _movement_dataset(out)
    np.testing.assert_array_equal(ds.position.values[:, :, 0, :].transpose(0, 2, 1), np.stack(frames))
    assert ds.attrs["fps"] == 1 / env.dt
    assert list(ds.species.values.astype(str)) == env.individual_species()
    with pytest.raises(coevo.InputError, match="exists"):
        coevo.save_trajectories(out, frames, env.individual_species())
    for bad, match in (({"species": ["prey"]}, "names for"), ({"fps": 0.0}, "fps 0"),
                       ({"fps": float("nan")}, "fps NaN")):
        args = {"species": env.individual_species(), **bad}
        with pytest.raises(coevo.InputError, match=match):
            coevo.save_trajectories(tmp_path / "other.nc", frames, **args)
    with pytest.raises(coevo.InputError, match="fps is for .nc"):
        coevo.save_trajectories(tmp_path / "other.npy", frames, env.individual_species(), fps=10.0)
    with pytest.raises(coevo.CoevoIOError):
        coevo.save_trajectories(tmp_path / "no-such-folder" / "x.nc", frames, env.individual_species())
    with pytest.raises(coevo.InputError, match="neither"):
        coevo.save_trajectories(tmp_path / "other.h5", frames, env.individual_species())
    assert not (tmp_path / "other.nc").exists() and not (tmp_path / "other.h5").exists()
    assert not (tmp_path / "other.npy").exists()
    # Without fps, time counts frames.
    coevo.save_trajectories(tmp_path / "frames.nc", frames, env.individual_species())
    ds = _movement_dataset(tmp_path / "frames.nc")
    assert ds.attrs["time_unit"] == "frames" and list(ds.time.values[:3]) == [0, 1, 2]


def test_a_seeded_reset_of_vector_env_holds_one_set_of_worlds(tmp_path):
    # reset(seed=) reseeds the worlds in place, one at a time, so the process's peak memory does not double
    # (500 worlds; measured in a fresh process by its peak resident set).
    import subprocess
    import sys

    script = tmp_path / "peak.py"
    script.write_text(
        "import resource, coevo\n"
        f"env = coevo.vector_env({STANDARD!r}, num_worlds=500)\n"
        "env.reset(seed=1)\n"
        "made = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
        "for seed in (2, 3):\n"
        "    env.reset(seed=seed)\n"
        "print(made, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)\n"
    )
    made, after = map(int, subprocess.run([sys.executable, str(script)], check=True, capture_output=True,
                                          text=True).stdout.split())
    assert after < 1.3 * made, f"peak {after} kB after seeded resets, {made} kB once made"
    with pytest.raises(coevo.InputError, match="outside"):
        coevo.vector_env(STANDARD, num_worlds=2).reset(seed=2**64)


def test_a_seeded_reset_of_vector_env_is_one_made_with_that_seed():
    # In place, after steps and an episode's end: the same observations, rewards and world seeds, step by
    # step, as a vector_env made with the new seed.
    env = coevo.vector_env(STANDARD, num_worlds=3, seed=5, episode_steps=3)
    env.reset(seed=5)
    actions = np.tile(np.float32([0.3, -0.2]), (env.num_envs, 1))
    for _ in range(4):
        env.step(actions)
    fresh = coevo.vector_env(STANDARD, num_worlds=3, seed=8, episode_steps=3)
    a, _ = env.reset(seed=8)
    b, _ = fresh.reset()  # a fresh env's first reset: its seed's first episodes
    assert np.array_equal(a, b)
    assert env._worlds.world_seeds == fresh._worlds.world_seeds
    for _ in range(5):
        a, b = env.step(actions), fresh.step(actions)
        assert all(np.array_equal(x, y) for x, y in zip(a[:4], b[:4]))


def test_a_reseeded_vecenv_names_its_new_worlds_and_is_copied_with_them():
    import copy

    vec = coevo.VecEnv(STANDARD, num_envs=3, seed=2, episode_steps=3)
    vec.reset()
    vec.step(np.full((3, len(vec.agents), 2), 0.1, np.float32))
    vec.reseed(9)
    made = coevo.VecEnv(STANDARD, num_envs=3, seed=9, episode_steps=3)
    assert vec.world_seeds == made.world_seeds
    assert np.array_equal(vec.reset(), made.reset())
    assert copy.deepcopy(vec).world_seeds == made.world_seeds
    with pytest.raises(coevo.InputError, match="seed"):
        vec.reseed(None)
