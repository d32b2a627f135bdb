//! `coevo._coevo`: the Rust core behind the Python package (`python/coevo/__init__.py` wraps it as a
//! PettingZoo `ParallelEnv`). Nothing is simulated here: `Env` and `VecEnv` hold coevo's own
//! [`coevo::run::env`] worlds, which step the very schedule `coevo --train` steps.

use coevo::analysis::stats::{self, Estimate};
use coevo::learning::control::ObservationControl;
use coevo::scene::{Overrides, Scene};
use coevo::store::schema::Table;
use coevo::store::RunDir;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::Path;

// coevo's error kinds as Python exceptions, all subclasses of `CoevoError` (itself a `ValueError`, which
// every coevo error was before kinds): `except coevo.SceneError` tells a bad scene from a damaged
// checkpoint (`coevo::error::Kind`).
create_exception!(
    _coevo,
    CoevoError,
    PyValueError,
    "An error of coevo: one line naming the file or flag, the line and the field."
);
create_exception!(_coevo, SceneError, CoevoError, "A scene file or value: unreadable, invalid, unstable or too large.");
create_exception!(
    _coevo,
    CheckpointError,
    CoevoError,
    "A checkpoint or snapshot: missing, damaged, or of another run, scene or species."
);
create_exception!(
    _coevo,
    RunFolderError,
    CoevoError,
    "A run folder: in use, of another scene, not a run, shipped, or with incomplete data."
);
create_exception!(_coevo, ExperimentError, CoevoError, "An experiment file or its results.");
create_exception!(_coevo, InputError, CoevoError, "An argument given to coevo (a control, a count, a file name).");
create_exception!(
    _coevo,
    SimulationError,
    CoevoError,
    "The simulation left the physically possible (a NaN, an escaped body)."
);
create_exception!(_coevo, CoevoIOError, CoevoError, "Reading or writing a file failed.");

/// A coevo error as the Python exception of its kind.
fn err(e: coevo::error::Error) -> PyErr {
    use coevo::error::Kind;
    let message = e.to_string();
    match e.kind {
        Kind::Scene => SceneError::new_err(message),
        Kind::Checkpoint => CheckpointError::new_err(message),
        Kind::RunFolder => RunFolderError::new_err(message),
        Kind::Experiment => ExperimentError::new_err(message),
        Kind::Input => InputError::new_err(message),
        Kind::Simulation => SimulationError::new_err(message),
        Kind::Io => CoevoIOError::new_err(message),
        Kind::Other => CoevoError::new_err(message),
    }
}

/// A scene file with the counts, seed and episode length given from Python, validated. With `text`, the
/// scene is that text (what `path` held when the env was first made, [`scene_text`]): a pickled env is
/// made again from the scene it was made from, whatever the file says now.
fn scene(
    path: &str,
    text: Option<&str>,
    seed: Option<u64>,
    counts: Option<Vec<(String, usize)>>,
    steps: Option<usize>,
) -> PyResult<Scene> {
    let overrides = Overrides { counts: counts.unwrap_or_default(), seed, episode_steps: steps, ..Default::default() };
    let Some(text) = text else {
        // The shipped scenes (`scenes/standard.ron`, …) are built in: an installed wheel runs them anywhere.
        return coevo::run::args::load_scene(Path::new(path), &overrides).map_err(err);
    };
    coevo::run::args::scene_from_text(text, Path::new(path), &overrides).map_err(err)
}

/// The scene file at `path` as a loadable scene text (the built-in copy of a shipped scene), which an env
/// keeps so that a copy or a pickle of it is made from the same scene.
#[pyfunction]
fn scene_text(path: &str) -> PyResult<String> {
    Ok(coevo::run::args::load_scene(Path::new(path), &Overrides::default()).map_err(err)?.to_ron())
}

/// A matrix of f64 rows as a 2-D array.
fn grid<'py>(py: Python<'py>, rows: &[Vec<f64>]) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let (n, m) = (rows.len(), rows.first().map_or(0, Vec::len));
    rows.iter().flatten().copied().collect::<Vec<f64>>().into_pyarray(py).reshape([n, m])
}

/// The response fields of a run's species (`coevo --response`): per focal species, observed species and
/// relative heading, a dict with `species`, `observed`, `rel_heading`, `centres` (metres), `thrust` and
/// `turn` (`[left, ahead]` arrays, NaN where unobserved) and `alone` (thrust, turn with no one in view).
/// With `swarm=True`, the fields amid observations of the trained swarm (a parallel neighbour only),
/// averaged over them, `alone` then the mean action on those observations (`coevo --response`'s
/// `response-swarm.csv`).
#[pyfunction]
#[pyo3(signature = (run, swarm = false))]
fn response_fields<'py>(py: Python<'py>, run: &str, swarm: bool) -> PyResult<Bound<'py, PyList>> {
    let background = match swarm {
        false => coevo::analysis::response::Background::Empty,
        true => coevo::analysis::response::Background::Swarm,
    };
    let (_, fields) = coevo::analysis::response::of_run(Path::new(run), background).map_err(err)?;
    let out = PyList::empty(py);
    for f in fields {
        let d = PyDict::new(py);
        d.set_item("species", &f.species)?;
        d.set_item("observed", &f.observed)?;
        d.set_item("rel_heading", f.rel_heading)?;
        d.set_item("centres", f.centres.clone().into_pyarray(py))?;
        d.set_item("thrust", grid(py, &f.thrust)?)?;
        d.set_item("turn", grid(py, &f.turn)?)?;
        d.set_item("alone", (f.alone[0], f.alone[1]))?;
        out.append(d)?;
    }
    Ok(out)
}

/// The force maps of a recorded trajectory (`coevo --force-map`, a `--record` CSV) in the arena of
/// `scene`: per focal and nearest species, a dict with `species`, `observed`, `centres` (metres), `count`,
/// `turning` (rad/s) and `speeding` (m/s²) as `[left, ahead]` arrays (NaN in bins under 20 samples).
#[pyfunction]
#[pyo3(signature = (trajectory, scene_path="scenes/standard.ron"))]
fn force_maps<'py>(py: Python<'py>, trajectory: &str, scene_path: &str) -> PyResult<Bound<'py, PyList>> {
    use coevo::analysis::force_map;
    let scene = scene(scene_path, None, None, None, None)?;
    let names: Vec<String> = scene.species.iter().map(|d| d.name.clone()).collect();
    let steps = force_map::read(Path::new(trajectory), &names).map_err(err)?;
    let arena = coevo::sim::space::Arena { edge: scene.world.arena_edge, boundary: scene.world.boundary };
    let out = PyList::empty(py);
    for m in force_map::maps(&steps, &names, &arena, scene.world.dt, arena.half()) {
        let d = PyDict::new(py);
        d.set_item("species", &m.species)?;
        d.set_item("observed", &m.observed)?;
        d.set_item("centres", m.centres.clone().into_pyarray(py))?;
        let count: Vec<Vec<f64>> = m.count.iter().map(|r| r.iter().map(|&c| c as f64).collect()).collect();
        d.set_item("count", grid(py, &count)?)?;
        d.set_item("turning", grid(py, &m.turning)?)?;
        d.set_item("speeding", grid(py, &m.speeding)?)?;
        out.append(d)?;
    }
    Ok(out)
}

/// `--control`'s forms (`"blind:prey:prey"`, …; none: everything seen).
fn control(forms: Option<Vec<String>>) -> PyResult<ObservationControl> {
    ObservationControl::parse(&forms.unwrap_or_default()).map_err(|e| InputError::new_err(format!("control: {e}")))
}

/// The species coevo keeps training inside the worlds (none: every learning species is Python's), and
/// when: `"learning"`, `"frozen"` or `"alternate:K"`.
fn coevolve(species: Option<Vec<String>>, schedule: &str) -> PyResult<coevo::run::env::Coevolve> {
    let schedule = schedule.parse().map_err(|e| InputError::new_err(format!("coevolve_schedule: {e}")))?;
    Ok(coevo::run::env::Coevolve { species: species.unwrap_or_default(), schedule })
}

/// One world whose learning species are decided from Python.
#[pyclass(module = "coevo._coevo")]
struct Env {
    inner: coevo::run::env::Env,
}

#[pymethods]
impl Env {
    #[new]
    #[pyo3(signature = (scene_path, seed=None, counts=None, episode_steps=None, control=None, scene_text=None, coevolve=None, coevolve_schedule="learning"))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        scene_path: &str,
        seed: Option<u64>,
        counts: Option<Vec<(String, usize)>>,
        episode_steps: Option<usize>,
        control: Option<Vec<String>>,
        scene_text: Option<&str>,
        coevolve: Option<Vec<String>>,
        coevolve_schedule: &str,
    ) -> PyResult<Self> {
        let scene = scene(scene_path, scene_text, seed, counts, episode_steps)?;
        let coevolve = self::coevolve(coevolve, coevolve_schedule)?;
        Ok(Env { inner: coevo::run::env::Env::with_options(scene, self::control(control)?, coevolve).map_err(err)? })
    }

    /// Saves coevo's side of the run (`coevolve`) into the new folder `path` as `coevo --train` leaves a
    /// run: metrics.csv, its actors' snapshots, the checkpoint. Between episodes (after a reset).
    fn save_run(&mut self, path: &str) -> PyResult<()> {
        self.inner.save_run(Path::new(path)).map_err(err)
    }

    /// The parameters of coevo's actor of `species` (`coevolve`), layer by layer, as they are now.
    fn coevo_actor<'py>(&self, py: Python<'py>, species: &str) -> PyResult<Vec<Bound<'py, PyArray1<f32>>>> {
        let layers = self
            .inner
            .coevo_actor(species)
            .ok_or_else(|| InputError::new_err(format!("coevo_actor: coevo trains no species {species:?} here")))?;
        Ok(layers.into_iter().map(|l| l.into_pyarray(py)).collect())
    }

    /// The scene as the world runs it (counts and episode length applied), as a loadable scene file.
    fn scene_ron(&self) -> String {
        self.inner.scene().to_ron()
    }

    /// The agents' names, `<species>_<k>`, in the order of every array.
    fn agents(&self) -> Vec<String> {
        self.inner.agents()
    }

    #[getter]
    fn obs_dim(&self) -> usize {
        self.inner.obs_dim()
    }

    /// Every observation lies in [−high, high] (`[d_o]`, from the observation's layout and the scene).
    fn observation_high<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f32>> {
        self.inner.observation_high().into_pyarray(py)
    }

    /// The global state (`state`) lies in [−high, high] (`[agents × 6]`, from each agent's species).
    fn state_high<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f32>> {
        self.inner.state_high().into_pyarray(py)
    }

    #[getter]
    fn episode_steps(&self) -> usize {
        self.inner.episode_steps()
    }

    /// The time step (s): `positions()` after successive steps are `1 / dt` frames per second apart.
    #[getter]
    fn dt(&self) -> f64 {
        self.inner.scene().world.dt
    }

    #[getter]
    fn seed(&self) -> u64 {
        self.inner.scene().seed
    }

    /// A new episode (from `seed` afresh, else the next of the same stream): observations `[agents, d_o]`.
    #[pyo3(signature = (seed=None))]
    fn reset<'py>(&mut self, py: Python<'py>, seed: Option<u64>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let obs = self.inner.reset(seed).map_err(err)?;
        let shape = [self.inner.agents().len(), self.inner.obs_dim()];
        obs.into_pyarray(py).reshape(shape)
    }

    /// Every agent's species, ordered by coevo's agent id as `positions` (`--record`'s `OUT-species.npy`).
    fn individual_species(&self) -> Vec<String> {
        self.inner.individual_species()
    }

    /// Every agent's position `[agents of all species, 2]` (m), ordered by coevo's agent id (the `id`
    /// column of `coevo --record`).
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let flat: Vec<f64> = self.inner.positions().into_iter().flatten().collect();
        let n = flat.len() / 2;
        flat.into_pyarray(py).reshape([n, 2])
    }

    /// The global state `[agents of all species × 6]` (x, y, v_x, v_y, h_x, h_y per agent, by agent id,
    /// world frame): what a centralised critic reads.
    fn state<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f32>> {
        self.inner.state().into_pyarray(py)
    }

    /// The current state as an RGB image `[height, width, 3]` (uint8), drawn as `coevo --animate` draws.
    #[pyo3(signature = (size=480))]
    fn render<'py>(&mut self, py: Python<'py>, size: u32) -> PyResult<Bound<'py, PyArray3<u8>>> {
        let (w, h, rgba) = self.inner.render(size).map_err(err)?;
        let rgb: Vec<u8> = rgba.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
        rgb.into_pyarray(py).reshape([h as usize, w as usize, 3])
    }

    /// One step with `actions` `[agents, 2]` in [−1, 1]: (observations `[agents, d_o]`, rewards `[agents]`,
    /// truncated, {"dos", "doa", "catches"}).
    #[allow(clippy::type_complexity)]
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        actions: PyReadonlyArray2<'py, f32>,
    ) -> PyResult<(Bound<'py, PyArray2<f32>>, Bound<'py, PyArray1<f32>>, bool, Bound<'py, PyDict>)> {
        let flat: Vec<f32> = actions.as_array().iter().copied().collect();
        let r = self.inner.step(&flat).map_err(err)?;
        let shape = [self.inner.agents().len(), self.inner.obs_dim()];
        let info = PyDict::new(py);
        info.set_item("dos", r.dos)?;
        info.set_item("doa", r.doa)?;
        info.set_item("catches", r.catches)?;
        Ok((r.observations.into_pyarray(py).reshape(shape)?, r.rewards.into_pyarray(py), r.truncated, info))
    }
}

/// Many worlds of one scene (world 0 from the seed, world i from `coevo.world_seed(seed, i)`; or seed + i
/// with `world_seeds="consecutive"`) stepped together on arrays, on all cores, each starting its next
/// episode by itself.
#[pyclass(module = "coevo._coevo")]
struct VecEnv {
    inner: coevo::run::env::VecEnv,
}

#[pymethods]
impl VecEnv {
    #[new]
    #[pyo3(signature = (scene_path, num_envs, seed=0, counts=None, episode_steps=None, control=None, world_seeds="independent", threads=None, scene_text=None, coevolve=None, coevolve_schedule="learning"))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        scene_path: &str,
        num_envs: usize,
        seed: u64,
        counts: Option<Vec<(String, usize)>>,
        episode_steps: Option<usize>,
        control: Option<Vec<String>>,
        world_seeds: &str,
        threads: Option<usize>,
        scene_text: Option<&str>,
        coevolve: Option<Vec<String>>,
        coevolve_schedule: &str,
    ) -> PyResult<Self> {
        if threads == Some(0) {
            return Err(InputError::new_err("threads: must be ≥ 1 (None: every core, or COEVO_THREADS)"));
        }
        use coevo::run::env::WorldSeeds;
        let scene = scene(scene_path, scene_text, None, counts, episode_steps)?;
        let control = self::control(control)?;
        let seeds = match world_seeds {
            "independent" => WorldSeeds::Independent,
            "consecutive" => WorldSeeds::Consecutive,
            other => {
                return Err(err(coevo::error::Error::from(format!(
                    "world_seeds: \"independent\" or \"consecutive\" (got {other:?})"
                ))
                .of_kind(coevo::error::Kind::Input)))
            }
        };
        let coevolve = self::coevolve(coevolve, coevolve_schedule)?;
        let mut inner =
            coevo::run::env::VecEnv::coevolving(scene, num_envs, seed, control, seeds, coevolve).map_err(err)?;
        if let Some(n) = threads {
            inner.set_max_threads(n);
        }
        Ok(VecEnv { inner })
    }

    /// Saves world `world`'s run of coevo's side (`coevolve`) into the new folder `path`, as a single env's
    /// `save_run`; right after a step that ended that world's episode.
    fn save_run(&mut self, world: usize, path: &str) -> PyResult<()> {
        self.inner.save_run(world, Path::new(path)).map_err(err)
    }

    /// World `world`'s coevo actor of `species`, layer by layer (as a single env's `coevo_actor`).
    fn coevo_actor<'py>(
        &mut self,
        py: Python<'py>,
        world: usize,
        species: &str,
    ) -> PyResult<Vec<Bound<'py, PyArray1<f32>>>> {
        let layers = self.inner.coevo_actor(world, species).ok_or_else(|| {
            InputError::new_err(format!("coevo_actor: no world {world}, or coevo trains no species {species:?} here"))
        })?;
        Ok(layers.into_iter().map(|l| l.into_pyarray(py)).collect())
    }

    /// Every world's global state `[num_envs, agents of all species, 6]` (x, y, v_x, v_y, h_x, h_y per
    /// agent, by agent id, world frame).
    fn state<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let shape = [self.inner.worlds(), self.inner.population(), coevo::run::env::STATE_DIM];
        self.inner.state().into_pyarray(py).reshape(shape)
    }

    /// Each world's seed, in order.
    fn world_seeds(&self) -> Vec<u64> {
        self.inner.world_seeds()
    }

    /// `metrics.csv`'s header, with the species decided from Python as the learning ones.
    fn metrics_header(&self) -> String {
        self.inner.metrics_header()
    }

    /// The episodes finished since the last call, as the first cells of `metrics.csv` rows (up to the
    /// returns), numbered in the order they finished.
    fn take_episode_rows(&mut self) -> Vec<String> {
        self.inner.take_episode_rows()
    }

    #[getter]
    fn num_envs(&self) -> usize {
        self.inner.worlds()
    }

    #[getter]
    fn obs_dim(&self) -> usize {
        self.inner.obs_dim()
    }

    /// Every observation lies in [−high, high] (`[d_o]`, from the observation's layout and the scene).
    fn observation_high<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f32>> {
        self.inner.observation_high().into_pyarray(py)
    }

    fn agents(&self) -> Vec<String> {
        self.inner.agent_names()
    }

    fn shape(&self) -> [usize; 3] {
        [self.inner.worlds(), self.inner.agents(), self.inner.obs_dim()]
    }

    /// Every world starts afresh from `seed` (world i from `world_seed(seed, i)`, or `seed + i` with
    /// `world_seeds="consecutive"`), in place: one world at a time, the old state freed as the new takes
    /// its place; the next `reset()` hands out each world's first episode, as a VecEnv made with `seed`
    /// would.
    fn reseed(&mut self, py: Python<'_>, seed: u64) -> PyResult<()> {
        let inner = &mut self.inner;
        py.allow_threads(|| inner.reseed(seed)).map_err(err)
    }

    /// The next episode in every world: observations `[num_envs, agents, d_o]`.
    fn reset<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let obs = self.inner.reset().map_err(err)?;
        obs.into_pyarray(py).reshape(self.shape())
    }

    /// One step of every world with `actions` `[num_envs, agents, 2]`: (observations, rewards
    /// `[num_envs, agents]`, truncated `[num_envs]`, {"dos", "doa", "catches"} each `[num_envs]`, and
    /// "final_obs", a list of `num_envs`); a truncated world's observations are its next episode's first,
    /// and its last ones are its entry of "final_obs" (None for the other worlds).
    #[allow(clippy::type_complexity)]
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        actions: PyReadonlyArray3<'py, f32>,
    ) -> PyResult<(Bound<'py, PyArray3<f32>>, Bound<'py, PyArray2<f32>>, Bound<'py, PyArray1<bool>>, Bound<'py, PyDict>)>
    {
        let flat: Vec<f32> = actions.as_array().iter().copied().collect();
        let inner = &mut self.inner;
        let r = py.allow_threads(|| inner.step(&flat)).map_err(err)?;
        let [n, a, _] = self.shape();
        let info = PyDict::new(py);
        info.set_item("dos", r.dos.into_pyarray(py))?;
        info.set_item("doa", r.doa.into_pyarray(py))?;
        info.set_item("catches", r.catches.into_pyarray(py))?;
        // Gymnasium's same-step autoreset: a truncated world's last observations, None for the others.
        let [_, agents, dim] = self.shape();
        let last = PyList::empty(py);
        for o in r.final_observations {
            match o {
                Some(o) => last.append(o.into_pyarray(py).reshape([agents, dim])?)?,
                None => last.append(py.None())?,
            }
        }
        info.set_item("final_obs", last)?;
        Ok((
            r.observations.into_pyarray(py).reshape(self.shape())?,
            r.rewards.into_pyarray(py).reshape([n, a])?,
            r.truncated.into_pyarray(py),
            info,
        ))
    }
}

/// A run folder as coevo names its files: for programs that train outside coevo (`examples/ippo.py`)
/// or read runs (`examples/controls.py`), so they spell no file name of their own.
#[pyclass(module = "coevo._coevo")]
struct RunFolder {
    dir: RunDir,
}

#[pymethods]
impl RunFolder {
    #[new]
    fn new(path: &str) -> Self {
        RunFolder { dir: RunDir::new(path) }
    }

    /// A new run folder for a run trained outside coevo: refused unless `path` is new or empty; writes
    /// `scene_ron` as its scene and makes its checkpoint folder.
    #[staticmethod]
    fn create(path: &str, scene_ron: &str) -> PyResult<Self> {
        let dir = RunDir::new(path);
        // The scene first: a folder is made only for a scene coevo can read back (its --eval, --plot).
        Scene::parse(scene_ron, "scene_ron").map_err(err)?;
        dir.check_new(false).map_err(err)?;
        let made =
            |p: &Path| std::fs::create_dir_all(p).map_err(|e| CoevoIOError::new_err(format!("{}: {e}", p.display())));
        made(&dir.checkpoint())?;
        coevo::io::write_file(&dir.scene(), coevo::io::Existing::Refuse, scene_ron.as_bytes()).map_err(err)?;
        Ok(RunFolder { dir })
    }

    #[getter]
    fn path(&self) -> String {
        self.dir.path().display().to_string()
    }

    /// `scene.ron`: the scene as trained.
    #[getter]
    fn scene(&self) -> String {
        self.dir.scene().display().to_string()
    }

    /// `metrics.csv`: one row per finished episode.
    #[getter]
    fn metrics(&self) -> String {
        self.dir.metrics().display().to_string()
    }

    /// A species' trained actor (`checkpoint/<species>-actor.safetensors`).
    fn actor(&self, species: &str) -> String {
        self.dir.actor(species).display().to_string()
    }

    /// The per-step CSV of an evaluation named `slug` (`eval-<slug>.csv`; give its file name to
    /// `coevo --eval RUN --eval-out`).
    fn evaluation(&self, slug: &str) -> String {
        self.dir.evaluation(slug).display().to_string()
    }

    /// `metrics.csv` as columns (name: one float per episode; NaN where blank), refused unless whole
    /// (with `partial`, a last line cut short is dropped).
    #[pyo3(signature = (partial=false))]
    fn read_metrics(&self, py: Python<'_>, partial: bool) -> PyResult<Py<PyDict>> {
        let path = self.dir.metrics();
        let text = coevo::io::read_text(&path, coevo::io::MAX_TEXT_BYTES).map_err(err)?;
        columns(py, &Table::metrics_of(&text, &path, partial).map_err(err)?)
    }

    /// An evaluation's per-step CSV (a file of this run, e.g. `evaluation(slug)`) as columns, refused
    /// unless whole.
    fn read_evaluation(&self, py: Python<'_>, path: &str) -> PyResult<Py<PyDict>> {
        columns(py, &Table::read_eval(Path::new(path)).map_err(err)?)
    }
}

/// A table's columns as a dict of float lists.
fn columns(py: Python<'_>, table: &Table) -> PyResult<Py<PyDict>> {
    let out = PyDict::new(py);
    for (i, name) in table.header.iter().enumerate() {
        out.set_item(name, table.rows.iter().map(|r| r[i]).collect::<Vec<f64>>())?;
    }
    Ok(out.unbind())
}

/// An estimate as coevo's reports print it: mean, 95 % half-width, two-sided p of zero, samples, degrees
/// of freedom (None where one sample allows no interval).
fn estimate_dict(py: Python<'_>, e: Option<Estimate>) -> PyResult<Option<Py<PyDict>>> {
    let Some(e) = e else { return Ok(None) };
    let out = PyDict::new(py);
    out.set_item("mean", e.mean)?;
    out.set_item("ci", e.ci)?;
    out.set_item("p", e.p_value())?;
    out.set_item("n", e.n)?;
    out.set_item("df", e.df)?;
    Ok(Some(out.unbind()))
}

/// The mean of independent samples with its Student-t 95 % interval and the two-sided t test of zero,
/// exactly as coevo's experiment reports compute them (`coevo::analysis::stats::estimate`); None
/// without samples.
#[pyfunction]
fn t_estimate(py: Python<'_>, samples: Vec<f64>) -> PyResult<Option<Py<PyDict>>> {
    finite("samples", &samples)?;
    estimate_dict(py, stats::estimate(&samples))
}

/// A sample with a NaN or an infinity is an `InputError` naming it, before any statistic is computed
/// (a non-finite value made the t distribution panic inside statrs).
fn finite(name: &str, samples: &[f64]) -> PyResult<()> {
    match samples.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(err(coevo::error::Error::from(format!(
            "{name}[{i}] is {}: the statistics take finite values only",
            samples[i]
        ))
        .of_kind(coevo::error::Kind::Input))),
        None => Ok(()),
    }
}

/// Mean of `a` minus mean of `b` with Welch's 95 % interval and test, degrees of freedom rounded down, as
/// coevo's reports compute it (`coevo::analysis::stats::difference`); None without samples.
#[pyfunction]
fn welch(py: Python<'_>, a: Vec<f64>, b: Vec<f64>) -> PyResult<Option<Py<PyDict>>> {
    finite("a", &a)?;
    finite("b", &b)?;
    estimate_dict(py, stats::difference(&a, &b))
}

/// Holm's step-down adjustment of a family of p-values, in the order given, as coevo's reports adjust a
/// family (`coevo::analysis::stats::holm`).
#[pyfunction]
fn holm(p: Vec<f64>) -> PyResult<Vec<f64>> {
    finite("p", &p)?;
    Ok(stats::holm(&p))
}

/// Training curves made elsewhere against coevo's own, judged as coevo's reports judge two variants
/// (`coevo::experiment::external::compare`). `theirs` and `ours`: one dict per run of per-episode
/// `"dos"`, `"doa"` and `"catches"`. For each `(text, quantity, margin)` of `comparisons` (the quantity as
/// experiment files write it: `"DoaLast"`, `'FromStart("doa")'`): theirs minus ours with Welch's 95 %
/// interval, TOST within the margin when one is given (else the two-sided test), Holm over the family.
/// Returns per comparison a dict: text, mean, ci, p, p_holm, level (the Holm step's α), verdict.
#[pyfunction]
fn compare_curves(
    py: Python<'_>,
    family: &str,
    theirs: Vec<std::collections::HashMap<String, Vec<f64>>>,
    ours: Vec<std::collections::HashMap<String, Vec<f64>>>,
    comparisons: Vec<(String, String, Option<f64>)>,
) -> PyResult<Py<PyList>> {
    use coevo::experiment::external::{compare, curves, Comparison};
    let runs = |side: &str, runs: Vec<std::collections::HashMap<String, Vec<f64>>>| {
        runs.into_iter()
            .enumerate()
            .map(|(i, mut run)| {
                let mut take = |name: &str| {
                    run.remove(name).ok_or_else(|| InputError::new_err(format!("{side}[{i}]: no \"{name}\" curve")))
                };
                Ok(curves(take("dos")?, take("doa")?, take("catches")?))
            })
            .collect::<PyResult<Vec<_>>>()
    };
    let (theirs, ours) = (runs("theirs", theirs)?, runs("ours", ours)?);
    let comparisons = comparisons
        .iter()
        .map(|(text, quantity, margin)| Comparison::parse(text, quantity, *margin))
        .collect::<Result<Vec<_>, _>>()
        .map_err(err)?;
    let out = PyList::empty(py);
    for r in compare(family, &theirs, &ours, &comparisons).map_err(err)? {
        let row = PyDict::new(py);
        row.set_item("text", &r.claim.text)?;
        row.set_item("mean", r.estimate.map(|e| e.mean))?;
        row.set_item("ci", r.estimate.and_then(|e| e.ci))?;
        row.set_item("p", r.p)?;
        row.set_item("p_holm", r.p_holm)?;
        row.set_item("level", r.level)?;
        row.set_item("verdict", r.verdict_text())?;
        out.append(row)?;
    }
    Ok(out.unbind())
}

/// The seed of world `i` of a VecEnv seeded `seed` (world_seeds="independent"): `seed` for world 0, else
/// SplitMix64 of the two mixed, so neighbouring seeds' worlds do not coincide.
#[pyfunction]
fn world_seed(seed: u64, i: u64) -> u64 {
    coevo::run::env::world_seed(seed, i)
}

/// Positions `[frames, individuals, 2]` (m) with each individual's species written to `path` as a
/// `movement` poses dataset in netCDF, as `coevo --record OUT.nc` writes one (`coevo::run::movement`);
/// `fps` None gives a time coordinate in frames. Refuses an existing file, writing nothing.
#[pyfunction]
#[pyo3(signature = (path, positions, species, fps=None))]
fn save_movement(path: &str, positions: PyReadonlyArray3<f64>, species: Vec<String>, fps: Option<f64>) -> PyResult<()> {
    let view = positions.as_array();
    let frames: Vec<Vec<(f64, f64)>> =
        view.outer_iter().map(|frame| frame.outer_iter().map(|p| (p[0], p[1])).collect()).collect();
    let poses = coevo::run::movement::Poses { positions: &frames, species: &species, fps };
    coevo::run::movement::write(Path::new(path), &poses, coevo::io::Existing::Refuse).map_err(|mut e| {
        // What the file would hold is refused as the caller's input; a file that cannot be written stays I/O.
        if e.kind == coevo::error::Kind::Other {
            e.kind = coevo::error::Kind::Input;
        }
        err(e)
    })
}

#[pymodule]
fn _coevo(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", coevo::VERSION)?;
    m.add("git_commit", coevo::GIT_COMMIT)?;
    m.add_class::<Env>()?;
    m.add_class::<VecEnv>()?;
    m.add_class::<RunFolder>()?;
    m.add_function(wrap_pyfunction!(world_seed, m)?)?;
    m.add_function(wrap_pyfunction!(scene_text, m)?)?;
    m.add_function(wrap_pyfunction!(response_fields, m)?)?;
    m.add_function(wrap_pyfunction!(force_maps, m)?)?;
    m.add_function(wrap_pyfunction!(t_estimate, m)?)?;
    m.add_function(wrap_pyfunction!(welch, m)?)?;
    m.add_function(wrap_pyfunction!(holm, m)?)?;
    m.add_function(wrap_pyfunction!(compare_curves, m)?)?;
    m.add_function(wrap_pyfunction!(save_movement, m)?)?;
    let py = m.py();
    m.add("CoevoError", py.get_type::<CoevoError>())?;
    m.add("SceneError", py.get_type::<SceneError>())?;
    m.add("CheckpointError", py.get_type::<CheckpointError>())?;
    m.add("RunFolderError", py.get_type::<RunFolderError>())?;
    m.add("ExperimentError", py.get_type::<ExperimentError>())?;
    m.add("InputError", py.get_type::<InputError>())?;
    m.add("SimulationError", py.get_type::<SimulationError>())?;
    m.add("CoevoIOError", py.get_type::<CoevoIOError>())?;
    Ok(())
}
