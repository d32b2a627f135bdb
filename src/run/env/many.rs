//! Many worlds of one scene stepped together on flat arrays ([`VecEnv`]), parked on shared apps where
//! that is exact ([`super::pool`]).

use super::pool::{Bytes, Worlds};
use super::world::{Coevolve, Env, Outcome};
use crate::error::{Kind, ResultExt};
use crate::learning::control::ObservationControl;
use crate::scene::Scene;
use crate::sim::metrics::EpisodeSummary;
use crate::sim::species::{SpeciesRegistry, ACTION_DIM};

/// How a [`VecEnv`]'s worlds are seeded from its one seed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum WorldSeeds {
    /// World 0 from the seed itself, world i > 0 from [`world_seed`]: a different seed gives other worlds
    /// (seeds 1 and 2 of 32 worlds share none), so runs with different seeds are independent samples.
    #[default]
    Independent,
    /// World i from seed + i, as the first VecEnv seeded them: runs with seeds 1 and 2 share 31 of 32
    /// worlds. Kept to reproduce runs made that way.
    Consecutive,
}

/// The seed of world `i` of a [`VecEnv`] seeded `seed` ([`WorldSeeds::Independent`]): `seed` for world 0
/// (a one-world VecEnv is the single env of that seed), else SplitMix64 (Steele et al. 2014) of `seed`
/// and `i` mixed, so neighbouring seeds' worlds do not coincide.
pub fn world_seed(seed: u64, i: u64) -> u64 {
    fn splitmix64(mut z: u64) -> u64 {
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    if i == 0 {
        seed
    } else {
        splitmix64(seed ^ splitmix64(i))
    }
}

/// Many worlds of one scene, world i from [`world_seed`]`(seed, i)`, stepped together on flat arrays.
/// Where coevo trains no species, the worlds share one app per thread and keep only their state between
/// steps ([`super::pool`]), with the same results as worlds of their own.
pub struct VecEnv {
    envs: Worlds,
    /// What every world is made from, but its seed.
    made: Made,
    agents: usize,
    /// Finished episodes not yet taken, in the order they finished (by step, then by world).
    finished: Vec<EpisodeSummary>,
    /// Episodes finished so far in all worlds: the next finished episode's number in `metrics.csv`.
    numbered: usize,
    /// No step since the worlds were made: the first `reset` returns their first episode (world i's is
    /// the first episode of its seed, as a single env's `reset(world seed)`) rather than starting a second.
    fresh: bool,
    /// Whether to step the worlds on one thread or on all ([`crate::parallel::Adaptive`]).
    threads: crate::parallel::Adaptive,
    /// At most this many threads for this VecEnv's steps (None: [`crate::parallel::threads`]).
    max_threads: Option<usize>,
}

/// What a [`VecEnv`] step returned: `[worlds × agents × d_o]` observations (of the next episode's first
/// state for a world whose episode ended: its last observations are in `final_observations`),
/// `[worlds × agents]` rewards, and per world whether its episode ended with this step.
#[derive(Clone, Debug, Default)]
pub struct VecStep {
    pub observations: Vec<f32>,
    pub rewards: Vec<f32>,
    pub truncated: Vec<bool>,
    pub final_observations: Vec<Option<Vec<f32>>>,
    /// Per world, as [`StepResult`]: DoS and DoA of the headline species, catches at the new state.
    pub dos: Vec<f64>,
    pub doa: Vec<f64>,
    pub catches: Vec<u32>,
}

/// What a [`VecEnv`]'s worlds are made from: world i of seed `seed` is [`Made::world`]`(seed, i)`.
struct Made {
    scene: Scene,
    control: ObservationControl,
    coevolve: Coevolve,
    seeds: WorldSeeds,
}

impl Made {
    fn world(&self, seed: u64, i: usize) -> crate::error::Result<Env> {
        let mut s = self.scene.clone();
        s.seed = match self.seeds {
            WorldSeeds::Independent => world_seed(seed, i as u64),
            WorldSeeds::Consecutive => seed.wrapping_add(i as u64),
        };
        Env::with_options(s, self.control.clone(), self.coevolve.clone())
    }
}

/// One world's step in a [`VecEnv`]: its result and, when its episode ended, its last observations.
type WorldStep = crate::error::Result<(Outcome, Option<Vec<f32>>, Vec<EpisodeSummary>)>;

impl VecEnv {
    pub fn new(scene: Scene, worlds: usize, seed: u64) -> crate::error::Result<VecEnv> {
        VecEnv::with_control(scene, worlds, seed, ObservationControl::default())
    }

    /// As [`VecEnv::new`], every world's observations altered by `control` ([`Env::with_control`]).
    pub(crate) fn with_control(
        scene: Scene,
        worlds: usize,
        seed: u64,
        control: ObservationControl,
    ) -> crate::error::Result<VecEnv> {
        VecEnv::seeded(scene, worlds, seed, control, WorldSeeds::default())
    }

    /// As [`VecEnv::with_control`], the worlds seeded as `seeds` says.
    pub fn seeded(
        scene: Scene,
        worlds: usize,
        seed: u64,
        control: ObservationControl,
        seeds: WorldSeeds,
    ) -> crate::error::Result<VecEnv> {
        VecEnv::coevolving(scene, worlds, seed, control, seeds, Coevolve::default())
    }

    /// As [`VecEnv::seeded`], with coevo training the species `coevolve` names in every world
    /// ([`Env::with_options`]): each world's learners learn from that world alone, as in `--train`, so
    /// n worlds train n populations of them.
    pub fn coevolving(
        scene: Scene,
        worlds: usize,
        seed: u64,
        control: ObservationControl,
        seeds: WorldSeeds,
        coevolve: Coevolve,
    ) -> crate::error::Result<VecEnv> {
        if worlds == 0 {
            return Err("num_envs: must be ≥ 1").kind(Kind::Input);
        }
        // All the worlds are bounded before the second is built: built one by one, each would be checked
        // against what the ones before it had left, and the refusal would come late and name no figure.
        let limit = crate::io::memory_bytes();
        let check = |bytes: f64| -> crate::error::Result<()> {
            if bytes > limit {
                return Err(format!(
                    "num_envs: {worlds} worlds of this scene would need about {}, more than the {} of memory coevo may use here (the least of free memory, the cgroup limit and ulimit -v)",
                    crate::io::bytes_shown(bytes),
                    crate::io::bytes_shown(limit)
                ))
                .kind(Kind::Input);
            }
            Ok(())
        };
        // Whether pooled or not is known once a world is built (one world is bounded when its scene is
        // validated).
        let bytes = Bytes { apart: scene.world_bytes(), parked: scene.parked_bytes() };
        let made = Made { scene, control, coevolve, seeds };
        let envs = Worlds::new(worlds, crate::parallel::threads(), bytes, check, |i| made.world(seed, i))?;
        let agents = envs.any().agents().len();
        Ok(VecEnv {
            envs,
            made,
            agents,
            finished: vec![],
            numbered: 0,
            fresh: true,
            threads: Default::default(),
            max_threads: None,
        })
    }

    /// Steps on at most `n` threads (at least 1; never more than [`crate::parallel::threads`]); which
    /// thread steps a world never changes what it computes. Pooled worlds keep at most `n` engines (one
    /// app a thread), and a larger `n` later does not bring the others back.
    pub fn set_max_threads(&mut self, n: usize) {
        self.max_threads = Some(n.max(1));
        self.envs.keep_engines(n);
    }

    /// Saves world `world`'s run of coevo's side ([`Env::save_run`]); between episodes, so right after a
    /// step that ended that world's episode (the world then stands at its next episode's start). A reset
    /// that cut an episode short leaves the run unsaveable ([`Env::reset`]).
    pub fn save_run(&mut self, world: usize, dir: &std::path::Path) -> crate::error::Result<()> {
        let n = self.envs.len();
        self.envs.with(world, |env| env.save_run(dir)).unwrap_or_else(|| {
            Err(format!("save_run: world {world}: there are {n} (0 to {})", n - 1)).kind(Kind::Input)
        })
    }

    /// World `world`'s [`Env::coevo_actor`].
    pub fn coevo_actor(&mut self, world: usize, species: &str) -> Option<Vec<Vec<f32>>> {
        self.envs.with(world, |env| env.coevo_actor(species))?
    }

    /// Every world's [`Env::state`], world after world: `[worlds × agents of all species × STATE_DIM]`.
    pub fn state(&mut self) -> Vec<f32> {
        self.envs.map(1, |_, env| env.state()).concat()
    }

    /// Agents of every species per world (the rows of a world's [`Env::state`]).
    pub fn population(&self) -> usize {
        self.envs.any().population()
    }

    /// Each world's seed, in order.
    pub fn world_seeds(&self) -> Vec<u64> {
        self.envs.seeds()
    }

    /// `metrics.csv`'s header ([`Env::metrics_header`]).
    pub fn metrics_header(&self) -> String {
        self.envs.any().metrics_header()
    }

    /// The episodes finished since the last call as the first cells of `metrics.csv` rows (up to the
    /// returns, [`crate::store::schema::episode_cells`]), numbered in the order they finished across all worlds
    /// (by step, then by world), so the file does not depend on how often this is called.
    pub fn take_episode_rows(&mut self) -> Vec<String> {
        let registry = self.envs.any().world.resource::<SpeciesRegistry>();
        let first = self.numbered;
        let rows: Vec<String> = self
            .finished
            .drain(..)
            .enumerate()
            .map(|(k, mut e)| {
                e.episode = first + k;
                crate::store::schema::episode_cells(&e, registry).join(",")
            })
            .collect();
        self.numbered += rows.len();
        rows
    }

    pub fn worlds(&self) -> usize {
        self.envs.len()
    }

    pub fn agents(&self) -> usize {
        self.agents
    }

    pub fn obs_dim(&self) -> usize {
        self.envs.any().obs_dim()
    }

    /// [`Env::observation_high`] (the same in every world).
    pub fn observation_high(&self) -> Vec<f32> {
        self.envs.any().observation_high()
    }

    /// The agents' names (the same in every world).
    pub fn agent_names(&self) -> Vec<String> {
        self.envs.any().agents()
    }

    /// Starts the next episode in every world (the first call after the worlds were made: their first
    /// episode, already spawned); returns the observations.
    pub fn reset(&mut self) -> crate::error::Result<Vec<f32>> {
        if !std::mem::take(&mut self.fresh) {
            self.envs.map(1, |_, env| env.start(None)).into_iter().collect::<crate::error::Result<Vec<_>>>()?;
        }
        Ok(self.observations())
    }

    /// Every world starts afresh from `seed` (world i from [`world_seed`]`(seed, i)`, or as the worlds
    /// were seeded), in place: one world at a time, its new state made and the old one freed, so memory
    /// holds the worlds and one more, and the worlds go on sharing their engines. Afterwards every value it
    /// computes is that of a VecEnv made with `seed` (`a_reseeded_vec_env_is_one_made_with_that_seed`):
    /// the next [`VecEnv::reset`] hands out each world's first episode. Finished episodes not yet taken
    /// ([`VecEnv::take_episode_rows`]) are dropped and their numbering starts again at 0, and coevo's
    /// side, where it trains one, starts untrained, as in a VecEnv made anew. An error leaves some worlds
    /// reseeded and others not: make the VecEnv anew then.
    pub fn reseed(&mut self, seed: u64) -> crate::error::Result<()> {
        let made = &self.made;
        self.envs.reseed(|i| made.world(seed, i))?;
        self.finished.clear();
        self.numbered = 0;
        self.fresh = true;
        Ok(())
    }

    /// Every world's current observations, `[worlds × agents × d_o]`, each world writing its rows.
    pub fn observations(&mut self) -> Vec<f32> {
        let rows = self.agents * self.obs_dim();
        let mut observations = vec![0.0; self.envs.len() * rows];
        self.envs.map_with(1, observations.chunks_mut(rows).collect(), |_, env, out| env.write_observations(out));
        observations
    }

    /// One step of every world (`actions`: `[worlds × agents × 2]`), on all cores; a world whose episode
    /// ends starts its next one.
    pub fn step(&mut self, actions: &[f32]) -> crate::error::Result<VecStep> {
        let per = self.agents * ACTION_DIM;
        if actions.len() != per * self.envs.len() {
            return Err(format!(
                "actions: expected {} values ({} worlds × {} agents × 2), got {}",
                per * self.envs.len(),
                self.envs.len(),
                self.agents,
                actions.len()
            ))
            .kind(Kind::Input);
        }
        // Every world's actions are checked before any world steps: a refused call changes nothing.
        if let Some(i) = actions.iter().position(|a| !a.is_finite()) {
            let names = self.envs.any().agents();
            let (world, agent) = (i / per, (i % per) / ACTION_DIM);
            return Err(format!("world {world}, {}: {} is not a finite number", names[agent], actions[i]))
                .kind(Kind::Input);
        }
        // A step taken (never one refused above) leaves the first episode: a reset after it starts the next.
        self.fresh = false;
        // On one thread or all, whichever has been faster lately (other work on the machine can make
        // all threads slower than one); the same worlds either way. Each world writes its rows of the
        // step's arrays.
        let (n, agents, d) = (self.envs.len(), self.agents, self.obs_dim());
        let (mut observations, mut rewards) = (vec![0.0; n * agents * d], vec![0.0; n * agents]);
        let rows: Vec<(&mut [f32], &mut [f32])> =
            observations.chunks_mut(agents * d).zip(rewards.chunks_mut(agents)).collect();
        let (cap, envs) = (self.max_threads, &mut self.envs);
        let stepped: Vec<WorldStep> = self.threads.run_at_most(cap, |workers| {
            envs.map_with(workers, rows, |k, env, (observed, rewarded)| {
                let outcome = env.advance(&actions[k * per..(k + 1) * per], rewarded)?;
                if !outcome.truncated {
                    env.write_observations(observed);
                    return Ok((outcome, None, vec![]));
                }
                let (last, finished) = (env.observations(), env.take_episodes());
                env.start(None)?;
                env.write_observations(observed);
                Ok((outcome, Some(last), finished))
            })
        });
        let mut step = VecStep { observations, rewards, ..VecStep::default() };
        for out in stepped {
            let (r, last, finished) = out?;
            step.truncated.push(r.truncated);
            step.final_observations.push(last);
            step.dos.push(r.dos);
            step.doa.push(r.doa);
            step.catches.push(r.catches);
            self.finished.extend(finished);
        }
        Ok(step)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::run::env::Schedule;
    use crate::scene::Policy;
    use std::alloc::{GlobalAlloc, Layout, System};
    use std::cell::Cell;

    /// The system allocator, counting the bytes live that this thread allocated (other tests run beside):
    /// what a world holds, measured.
    struct Counting;
    thread_local! {
        static LIVE: Cell<isize> = const { Cell::new(0) };
    }
    fn count(bytes: isize) {
        // A thread being torn down has no counter left: its allocations are not this test's.
        let _ = LIVE.try_with(|live| live.set(live.get() + bytes));
    }
    // SAFETY: every call is forwarded to the system allocator unchanged; only sizes are counted.
    unsafe impl GlobalAlloc for Counting {
        unsafe fn alloc(&self, l: Layout) -> *mut u8 {
            count(l.size() as isize);
            unsafe { System.alloc(l) }
        }
        unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
            count(-(l.size() as isize));
            unsafe { System.dealloc(p, l) }
        }
        unsafe fn realloc(&self, p: *mut u8, l: Layout, new: usize) -> *mut u8 {
            count(new as isize - l.size() as isize);
            unsafe { System.realloc(p, l, new) }
        }
    }
    #[global_allocator]
    static ALLOCATOR: Counting = Counting;

    /// The bytes a world of `scene` holds: made alone (an app of its own; 16 of them, a sixteenth) or
    /// parked among many (the bytes 48 pooled worlds hold beyond 16, a thirty-second of them), once made,
    /// reset and stepped, on one thread.
    fn measured(scene: &Scene) -> (f64, f64) {
        let live = || LIVE.with(|l| l.get()) as f64;
        let before = live();
        let alone: Vec<Env> = (0..16)
            .map(|_| {
                let mut env = Env::new(scene.clone()).unwrap();
                env.reset(None).unwrap();
                env.step(&vec![0.3; env.agents().len() * 2]).unwrap();
                env
            })
            .collect();
        let apart = (live() - before) / 16.0;
        drop(alone);
        let pooled = |n: usize| {
            let before = live();
            let mut env = VecEnv::seeded(scene.clone(), n, 1, Default::default(), WorldSeeds::Independent).unwrap();
            assert!(env.envs.pooled());
            env.set_max_threads(1);
            env.reset().unwrap();
            env.step(&vec![0.3; n * env.agents() * 2]).unwrap();
            live() - before
        };
        (apart, (pooled(48) - pooled(16)) / 32.0)
    }

    /// Pooled worlds against the same worlds each in an app of its own, in kinds of worlds whose steps
    /// read every parked part: learned species decided from outside, rule-based and noisy classic
    /// opponents (the environment's random stream), walls, the authors' energy budget, a shuffled control
    /// (the world's seed), episodes ending and restarting. Every output is compared to the bit.
    #[test]
    fn pooled_worlds_step_as_worlds_of_their_own() {
        let load = |f: &str| Scene::load(std::path::Path::new(f)).unwrap();
        let mut energy = load("scenes/gym-pps-code.ron");
        energy.world.energy_budget = true;
        let mut vicsek = load("scenes/confined.ron");
        vicsek.species[0].policy = Policy::Vicsek(crate::scene::VicsekRule { radius: 0.5, noise: 1.0 });
        let mut random = load("scenes/standard.ron");
        random.species[0].policy = Policy::Random;
        let shuffled = ObservationControl::parse(&["shuffled:prey:prey"]).unwrap();
        for (name, mut scene, control) in [
            ("standard", load("scenes/standard.ron"), ObservationControl::default()),
            ("prey-vs-chasers", load("scenes/prey-vs-chasers.ron"), ObservationControl::default()),
            ("energy", energy, ObservationControl::default()),
            ("vicsek in walls", vicsek, ObservationControl::default()),
            ("random, shuffled", random, shuffled),
        ] {
            scene.episode_steps = 6;
            let make = || VecEnv::seeded(scene.clone(), 7, 11, control.clone(), WorldSeeds::Independent).unwrap();
            let mut pooled = make();
            assert!(pooled.envs.pooled(), "{name}: {:?}", super::super::pool::eligible(pooled.envs.any()));
            let mut apart = make();
            let seeds = apart.world_seeds();
            apart.envs = super::super::pool::Worlds::Apart(
                seeds
                    .iter()
                    .map(|&seed| {
                        let mut s = scene.clone();
                        s.seed = seed;
                        Env::with_control(s, control.clone()).unwrap()
                    })
                    .collect(),
            );
            assert_eq!(pooled.world_seeds(), seeds);
            assert_eq!(pooled.reset().unwrap(), apart.reset().unwrap(), "{name}");
            let n = 7 * pooled.agents() * ACTION_DIM;
            for t in 0..15 {
                let actions: Vec<f32> = (0..n).map(|i| ((i * 7919 + t * 104_729) % 200) as f32 / 100.0 - 1.0).collect();
                if t == 9 {
                    // A reset between steps, mid-episode, for every world.
                    assert_eq!(pooled.reset().unwrap(), apart.reset().unwrap(), "{name}, reset at {t}");
                }
                let (a, b) = (pooled.step(&actions).unwrap(), apart.step(&actions).unwrap());
                // Debug text tells bits apart (NaN from NaN included); kept out of the message, it is long.
                assert!(format!("{a:?}") == format!("{b:?}"), "{name}, step {t}: the pooled step differs");
                assert_eq!(pooled.state(), apart.state(), "{name}, step {t}");
            }
            let rows = pooled.take_episode_rows();
            assert!(rows.len() >= 14, "{name}: {} episodes", rows.len());
            assert_eq!(rows, apart.take_episode_rows(), "{name}");
        }
    }

    /// A VecEnv reseeded after stepping (pooled, and with coevo training a side, apart) steps as one made
    /// with the new seed, to the bit: observations, rewards, state, episode rows and world seeds; its pooled
    /// worlds stay on the same engines.
    #[test]
    fn a_reseeded_vec_env_is_one_made_with_that_seed() {
        let mut scene = Scene::load(std::path::Path::new("scenes/standard.ron")).unwrap();
        scene.episode_steps = 5;
        let coevolving = Coevolve { species: vec!["predator".into()], ..Coevolve::default() };
        for (name, coevolve) in [("pooled", Coevolve::default()), ("apart", coevolving)] {
            let make = |seed| {
                let (s, c) = (scene.clone(), ObservationControl::default());
                VecEnv::coevolving(s, 5, seed, c, WorldSeeds::Independent, coevolve.clone()).unwrap()
            };
            let (mut reseeded, mut fresh) = (make(3), make(4));
            assert_eq!(reseeded.envs.pooled(), name == "pooled");
            let n = 5 * reseeded.agents() * ACTION_DIM;
            let actions =
                |t: usize| -> Vec<f32> { (0..n).map(|i| ((i * 31 + t * 17) % 20) as f32 / 10.0 - 1.0).collect() };
            reseeded.reset().unwrap();
            for t in 0..7 {
                reseeded.step(&actions(t)).unwrap();
            }
            let engines = reseeded.envs.engine_ids();
            reseeded.reseed(4).unwrap();
            assert_eq!(reseeded.envs.engine_ids(), engines, "{name}: the engines are kept");
            assert_eq!(reseeded.world_seeds(), fresh.world_seeds(), "{name}");
            assert_eq!(reseeded.reset().unwrap(), fresh.reset().unwrap(), "{name}");
            for t in 0..12 {
                let (a, b) = (reseeded.step(&actions(t)).unwrap(), fresh.step(&actions(t)).unwrap());
                assert!(format!("{a:?}") == format!("{b:?}"), "{name}, step {t}: the reseeded step differs");
                assert_eq!(reseeded.state(), fresh.state(), "{name}, step {t}");
            }
            assert_eq!(reseeded.take_episode_rows(), fresh.take_episode_rows(), "{name}");
        }
    }

    /// Pooled worlds moved onto fewer engines (`set_max_threads`) step as before, to the bit.
    #[test]
    fn worlds_moved_onto_one_engine_step_as_on_many() {
        let mut scene = Scene::load(std::path::Path::new("scenes/standard.ron")).unwrap();
        scene.episode_steps = 4;
        let make = || VecEnv::seeded(scene.clone(), 5, 2, Default::default(), WorldSeeds::Independent).unwrap();
        let (mut many, mut fewer) = (make(), make());
        // Three engines each, whatever the machine's cores.
        for env in [&mut many, &mut fewer] {
            let bytes = super::super::pool::Bytes { apart: 0.0, parked: 0.0 };
            let three = super::super::pool::Worlds::new(5, 3, bytes, |_| Ok(()), |i| env.made.world(2, i)).unwrap();
            env.envs = three;
        }
        let groups = |env: &VecEnv| match &env.envs {
            super::super::pool::Worlds::Pooled { engines, parked } => {
                (engines.len(), parked.iter().map(Vec::len).collect::<Vec<_>>())
            }
            _ => panic!("pooled"),
        };
        assert_eq!(groups(&fewer), (3, vec![2, 2, 1]));
        assert_eq!(many.reset().unwrap(), fewer.reset().unwrap());
        let n = 5 * many.agents() * ACTION_DIM;
        for t in 0..13 {
            // Onto two engines (3 + 2) before the first episode ends, onto one after it.
            match t {
                2 => fewer.set_max_threads(2),
                6 => fewer.set_max_threads(1),
                _ => {}
            }
            let actions: Vec<f32> = (0..n).map(|i| ((i * 13 + t * 7) % 20) as f32 / 10.0 - 1.0).collect();
            let (a, b) = (many.step(&actions).unwrap(), fewer.step(&actions).unwrap());
            assert!(format!("{a:?}") == format!("{b:?}"), "step {t}: fewer engines step otherwise");
            match t {
                2..6 => assert_eq!(groups(&fewer), (2, vec![3, 2])),
                6.. => assert_eq!(groups(&fewer), (1, vec![5])),
                _ => {}
            }
        }
        assert_eq!(many.take_episode_rows(), fewer.take_episode_rows());
    }

    /// A world whose step panics is swapped back out: the others, and its own seed, are as they were, and
    /// the engine hosts again.
    #[test]
    fn a_panicking_step_leaves_every_world_its_own() {
        let scene = Scene::load(std::path::Path::new("scenes/standard.ron")).unwrap();
        let make = || VecEnv::seeded(scene.clone(), 3, 5, Default::default(), WorldSeeds::Independent).unwrap();
        let (mut hit, mut calm) = (make(), make());
        let seeds = hit.world_seeds();
        let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            hit.envs.map(1, |k, env| assert_ne!(k, 1, "world {} panics", env.scene().seed))
        }));
        assert!(caught.is_err());
        assert_eq!(hit.world_seeds(), seeds);
        assert_eq!(hit.observations(), calm.observations());
        let actions = vec![0.2; 3 * hit.agents() * ACTION_DIM];
        let (a, b) = (hit.step(&actions).unwrap(), calm.step(&actions).unwrap());
        assert!(format!("{a:?}") == format!("{b:?}"));
    }

    /// What keeps worlds apart: coevo training a side (its learners are per world), or one world alone.
    #[test]
    fn worlds_where_coevo_trains_stay_apart() {
        let scene = Scene::load(std::path::Path::new("scenes/standard.ron")).unwrap();
        let coevolve = Coevolve { species: vec!["predator".into()], schedule: Schedule::Learning };
        let worlds = VecEnv::coevolving(scene, 2, 1, Default::default(), WorldSeeds::Independent, coevolve).unwrap();
        assert!(!worlds.envs.pooled());
        let one = VecEnv::new(Scene::load(std::path::Path::new("scenes/standard.ron")).unwrap(), 1, 1).unwrap();
        assert!(!one.envs.pooled());
    }

    #[test]
    fn a_refused_step_leaves_the_first_reset_its_first_episode() {
        let make =
            || VecEnv::seeded(Scene::preset("gym-pps").unwrap(), 2, 3, Default::default(), WorldSeeds::Independent);
        let (mut refused, mut fresh) = (make().unwrap(), make().unwrap());
        assert!(refused.step(&[0.0; 3]).is_err() && refused.step(&vec![f32::NAN; 2 * refused.agents * 2]).is_err());
        assert_eq!(refused.reset().unwrap(), fresh.reset().unwrap());
    }

    #[test]
    fn a_world_holds_what_the_memory_check_bounds_it_by() {
        for prey in [10, 200] {
            let mut scene = Scene::preset("gym-pps").unwrap();
            scene.species.iter_mut().filter(|s| s.name == "prey").for_each(|s| s.count = prey);
            // The check bounds a world from above (never again ~20 times too little), and not by much.
            let (apart, parked) = measured(&scene);
            for (what, held, bound) in [("alone", apart, scene.world_bytes()), ("parked", parked, scene.parked_bytes())]
            {
                assert!(
                    held <= bound && bound <= 1.5 * held,
                    "{prey} prey: a world {what} holds {held} B, bounded by {bound} B"
                );
            }
        }
    }
}
