//! Many worlds on few apps: the worlds of a [`super::VecEnv`] whose species are all decided from
//! outside or by fixed rules and actors share one running world per thread, the *engine*, and each keeps
//! only its state between steps, *parked*.
//!
//! A world's state is its agents (their components, all plain values) and the resources a step changes:
//! the clock, the random streams, the perceived population and batches, the metrics and the scene (which
//! holds the world's seed). Everything else in an engine is the same for every world of the scene: the
//! schedules and their systems, the species registry, the arena, the fixed actors. Stepping world k swaps
//! its state into the engine, runs the very `FixedUpdate` schedule a world of its own runs, and swaps it
//! out again (a swap is its own inverse), so world k computes what it computes alone, to the bit
//! (`pooled_worlds_step_as_worlds_of_their_own`). A parked world of the default scene holds ~15 kB; a
//! world of its own holds its app's ~360 kB (Bevy 0.19 keeps 64 slots for each resource, and every
//! world has its own copy of every system), and a thousand of those no longer fit the caches.
//!
//! Pooling is used only where it is known to be exact: every resource of the world is either parked or
//! known to be the same in every world, every component of an agent is one coevo parks, and no species
//! plugin is in the app (a plugin's systems may keep state of their own, e.g. in a `Local`, which no
//! swap would see). Coevo training a side (its learners are per world), a plugin, or a single world keep
//! the worlds apart ([`eligible`] says why).

use super::world::{Env, ExternalActions, EXTERNAL};
use crate::learning::{Learners, Mode};
use crate::scene::Scene;
use crate::sim::clock::Episode;
use crate::sim::components::*;
use crate::sim::episode::{SimRng, SpawnedFrom};
use crate::sim::metrics::{Confusion, EpisodeLog, SwarmMetrics};
use crate::sim::perception::{Batches, Population};
use crate::sim::physics::StateFault;
use crate::sim::space::Arena;
use crate::sim::species::SpeciesRegistry;
use crate::sim::ActiveScene;
use bevy::ecs::query::QueryState;
use bevy::ecs::schedule::Schedules;
use bevy::prelude::*;
use std::any::TypeId;

/// The resources a step changes, parked by type: `$field: $type`. A resource of a world that is
/// neither here nor among [`shared_resources`] keeps the worlds apart.
macro_rules! parked_resources {
    ($($field:ident: $ty:ty),* $(,)?) => {
        struct Resources {
            $($field: $ty,)*
        }

        impl Resources {
            /// Moves the resources out of a world of its own (which is then dropped).
            fn take(world: &mut World) -> Option<Resources> {
                Some(Resources { $($field: world.remove_resource::<$ty>()?,)* })
            }

            /// Exchanges these with the engine's.
            fn swap(&mut self, world: &mut World) {
                $(std::mem::swap(&mut self.$field, &mut *world.resource_mut::<$ty>());)*
            }

            fn types() -> Vec<TypeId> {
                vec![$(TypeId::of::<$ty>(),)*]
            }
        }
    };
}

parked_resources! {
    scene: ActiveScene,
    episode: Episode,
    rng: SimRng,
    spawned_from: SpawnedFrom,
    log: EpisodeLog,
    metrics: SwarmMetrics,
    confusion: Confusion,
    fault: StateFault,
    population: Population,
    batches: Batches,
    actions: ExternalActions,
}

/// Resources the same in every world of one scene, whatever its seed: derived from the scene's fields
/// but its seed, and nothing a step writes in them is read by a later step. `Learners` only when nothing
/// learns ([`eligible`]) and every fixed actor is the same in every world ([`Worlds::new`] compares
/// them): acting then writes only its scratch (`pending_obs`, read by learning alone).
fn shared_resources() -> Vec<TypeId> {
    vec![
        TypeId::of::<SpeciesRegistry>(),
        TypeId::of::<Arena>(),
        TypeId::of::<crate::sim::policy::PolicyPlugins>(),
        TypeId::of::<Learners>(),
        TypeId::of::<Schedules>(),
    ]
}

/// One agent's components, all of them.
#[derive(Clone, Copy, Debug)]
struct Agent {
    id: AgentId,
    species: SpeciesId,
    position: Position,
    velocity: Velocity,
    heading: Heading,
    body: Body,
    action: Action,
    reward: Reward,
    contact_force: ContactForce,
    contacts: Contacts,
    slot: Slot,
    energy: Option<Energy>,
}

fn agent_components() -> Vec<TypeId> {
    vec![
        TypeId::of::<AgentId>(),
        TypeId::of::<SpeciesId>(),
        TypeId::of::<Position>(),
        TypeId::of::<Velocity>(),
        TypeId::of::<Heading>(),
        TypeId::of::<Body>(),
        TypeId::of::<Action>(),
        TypeId::of::<Reward>(),
        TypeId::of::<ContactForce>(),
        TypeId::of::<Contacts>(),
        TypeId::of::<Slot>(),
        TypeId::of::<Energy>(),
    ]
}

type AgentQuery = (
    Entity,
    &'static mut AgentId,
    &'static mut SpeciesId,
    &'static mut Position,
    &'static mut Velocity,
    &'static mut Heading,
    &'static mut Body,
    &'static mut Action,
    &'static mut Reward,
    &'static mut ContactForce,
    &'static mut Contacts,
    &'static mut Slot,
    Option<&'static mut Energy>,
);

/// A world between its steps: its scene (with its seed), the resources a step changes and its agents
/// by id.
pub(super) struct Parked {
    scene: Scene,
    resources: Resources,
    agents: Vec<Agent>,
}

impl Parked {
    /// Parks a world of its own: its state moves out, the rest (its app) is dropped.
    fn take(mut env: Env) -> Parked {
        let world = &mut env.world;
        let mut agents: Vec<Agent> = world
            .query::<AgentQuery>()
            .iter(world)
            .map(
                |(_, id, species, position, velocity, heading, body, action, reward, force, contacts, slot, energy)| {
                    Agent {
                        id: *id,
                        species: *species,
                        position: *position,
                        velocity: *velocity,
                        heading: *heading,
                        body: *body,
                        action: *action,
                        reward: *reward,
                        contact_force: *force,
                        contacts: *contacts,
                        slot: *slot,
                        energy: energy.copied(),
                    }
                },
            )
            .collect();
        agents.sort_by_key(|a| a.id);
        let resources = Resources::take(world).expect("a world of its own holds every parked resource");
        Parked { scene: env.scene.clone(), resources, agents }
    }

    /// Asks the cache for part of this world's state while other worlds step: a thousand parked worlds
    /// do not fit the caches, and a world's buffers are read at scattered times during its step, each a
    /// wait on memory otherwise. A hint only: it changes no value. Stage `depth` fetches what lies
    /// `depth` pointers away from the world's own bytes, so stepping asks for world k + 3's own bytes,
    /// k + 2's buffers they name and k + 1's buffers those name, and no stage waits to read where the
    /// next one is.
    fn prefetch(&self, depth: usize) {
        let (p, r) = (&self.resources.population, &self.resources);
        match depth {
            0 => prefetch(std::slice::from_ref(self)),
            1 => {
                prefetch(&self.agents);
                prefetch(&p.entity);
                prefetch(&p.id);
                prefetch(&p.species);
                prefetch(&p.position);
                prefetch(&p.velocity);
                prefetch(&p.heading);
                prefetch(&p.radius);
                prefetch(&p.turn);
                prefetch(&p.energy);
                prefetch(&p.ranges);
                prefetch(&p.max_radius);
                prefetch(&p.nearest_kin);
                prefetch(&r.batches.species);
                prefetch(&r.actions.0);
                prefetch(&r.metrics.now);
                prefetch(&r.metrics.catches_now_by);
                prefetch(&r.metrics.nn_distances_now);
                prefetch(&r.metrics.edge_ranks_now);
                prefetch(&r.confusion.0);
                prefetch(&r.scene.0.species);
                prefetch(&self.scene.species);
            }
            _ => {
                for b in &r.batches.species {
                    prefetch(&b.observations);
                    prefetch(&b.actions);
                    prefetch(&b.rewards);
                }
                r.actions.0.iter().for_each(|a| prefetch(a));
                r.metrics.nn_distances_now.iter().for_each(|d| prefetch(d));
                r.metrics.edge_ranks_now.iter().for_each(|d| prefetch(d));
            }
        }
    }

    /// Exchanges this world's state with the engine's: afterwards the engine steps this world, and this
    /// holds what the engine held. Agents are matched by id (every world of the scene has the same ids,
    /// species and components); the population's entity column is pointed at the engine's entities.
    fn swap(&mut self, engine: &mut Engine) {
        std::mem::swap(&mut self.scene, &mut engine.env.scene);
        let world = &mut engine.env.world;
        self.resources.swap(world);
        let entity_of = &mut engine.entity_of;
        entity_of.resize(self.agents.len(), Entity::PLACEHOLDER);
        for (e, mut id, mut s, mut x, mut v, mut h, mut b, mut a, mut r, mut f, mut c, mut slot, energy) in
            engine.agents.iter_mut(world)
        {
            let mine = &mut self.agents[id.0 as usize];
            entity_of[id.0 as usize] = e;
            std::mem::swap(&mut *id, &mut mine.id);
            std::mem::swap(&mut *s, &mut mine.species);
            std::mem::swap(&mut *x, &mut mine.position);
            std::mem::swap(&mut *v, &mut mine.velocity);
            std::mem::swap(&mut *h, &mut mine.heading);
            std::mem::swap(&mut *b, &mut mine.body);
            std::mem::swap(&mut *a, &mut mine.action);
            std::mem::swap(&mut *r, &mut mine.reward);
            std::mem::swap(&mut *f, &mut mine.contact_force);
            std::mem::swap(&mut *c, &mut mine.contacts);
            std::mem::swap(&mut *slot, &mut mine.slot);
            match (energy, mine.energy.as_mut()) {
                (Some(mut theirs), Some(mine)) => std::mem::swap(&mut *theirs, mine),
                (None, None) => {}
                _ => unreachable!("every world of a scene gives its agents the same components"),
            }
        }
        let mut population = world.resource_mut::<Population>();
        let population = &mut *population;
        // The cell grids stay with the engine: every perceiving rebuilds them from the positions before
        // anything reads them (contacts, observations, then the metrics of the same step), so they are
        // scratch, not state, and a thousand worlds' grids would be a thousand cold ones.
        std::mem::swap(&mut population.grids, &mut self.resources.population.grids);
        for (entity, id) in population.entity.iter_mut().zip(&population.id) {
            *entity = entity_of[id.0 as usize];
        }
    }
}

/// What a world of a scene holds: in an app of its own, and parked ([`crate::scene::Scene::world_bytes`],
/// [`crate::scene::Scene::parked_bytes`]).
pub(super) struct Bytes {
    pub(super) apart: f64,
    pub(super) parked: f64,
}

/// The worlds of a [`super::VecEnv`]: each its own app, or parked on a few engines.
pub(super) enum Worlds {
    Apart(Vec<Env>),
    /// `parked[i]` is stepped on `engines[i]`: contiguous runs of worlds, in order.
    Pooled {
        engines: Vec<Engine>,
        parked: Vec<Vec<Parked>>,
    },
}

/// A world that steps parked worlds, with its query of every agent component kept (made once, not at
/// every swap).
pub(super) struct Engine {
    env: Env,
    agents: QueryState<AgentQuery>,
    entity_of: Vec<Entity>,
}

impl Engine {
    fn new(mut env: Env) -> Engine {
        let agents = env.world.query::<AgentQuery>();
        Engine { env, agents, entity_of: Vec::new() }
    }
}

impl Worlds {
    /// `worlds` worlds, world k made by `make(k)` as a world of its own; parked on up to `engines`
    /// engines when [`eligible`]. `check` is given the bytes all of them will hold before the second is
    /// made.
    pub(super) fn new(
        worlds: usize,
        engines: usize,
        bytes: Bytes,
        check: impl Fn(f64) -> crate::error::Result<()>,
        make: impl Fn(usize) -> crate::error::Result<Env>,
    ) -> crate::error::Result<Worlds> {
        let first = make(0)?;
        let engines = engines.clamp(1, worlds);
        // One world gains nothing from an engine beside it.
        if worlds < 2 || eligible(&first).is_err() {
            check(bytes.apart * worlds as f64)?;
            return Ok(Worlds::Apart(
                std::iter::once(Ok(first)).chain((1..worlds).map(make)).collect::<Result<_, _>>()?,
            ));
        }
        check(bytes.apart * (engines + 1) as f64 + bytes.parked * worlds as f64)?;
        // An engine hosts: its own state is world 0's first state, never stepped.
        let hosts: Vec<Env> = (0..engines).map(|_| make(0)).collect::<Result<_, _>>()?;
        let actors = fixed_actors(&hosts[0]);
        let mut parked: Vec<Vec<Parked>> = (0..engines).map(|_| Vec::new()).collect();
        for (k, env) in std::iter::once(Ok(first)).chain((1..worlds).map(&make)).enumerate() {
            let env = env?;
            if fixed_actors(&env) != actors {
                // Fixed actors that differ between worlds (none shipped does this) are per world: apart.
                drop((hosts, parked, env));
                check(bytes.apart * worlds as f64)?;
                return Ok(Worlds::Apart((0..worlds).map(make).collect::<Result<_, _>>()?));
            }
            parked[k * engines / worlds].push(Parked::take(env));
        }
        Ok(Worlds::Pooled { engines: hosts.into_iter().map(Engine::new).collect(), parked })
    }

    /// World k replaced by `make(k)`, one world at a time (its old state freed as the new one takes its
    /// place). Pooled worlds stay on their engines; their new fixed actors must be the engines' (the
    /// same scene gives the same, as [`Worlds::new`] checked for the first seed). A failure (a world that
    /// cannot be made, or other fixed actors) leaves the worlds before it reseeded and the rest as they
    /// were: the caller makes its worlds anew.
    pub(super) fn reseed(&mut self, make: impl Fn(usize) -> crate::error::Result<Env>) -> crate::error::Result<()> {
        match self {
            Worlds::Apart(envs) => {
                for (k, env) in envs.iter_mut().enumerate() {
                    *env = make(k)?;
                }
            }
            Worlds::Pooled { engines, parked } => {
                let actors = fixed_actors(&engines[0].env);
                for (k, world) in parked.iter_mut().flatten().enumerate() {
                    let env = make(k)?;
                    if fixed_actors(&env) != actors {
                        return Err("reset: a world of the new seed holds fixed actors other than the first seed's; \
                                    make the worlds anew instead"
                            .into());
                    }
                    *world = Parked::take(env);
                }
            }
        }
        Ok(())
    }

    /// At most `n` engines (at least one): the worlds of the engines dropped move to those kept, again in
    /// contiguous runs. Any engine of a scene hosts any of its worlds (each engine is the same host, and a
    /// step swaps a world's whole state in), so this changes no value; it spares a caller that steps on
    /// fewer threads than there are cores an app per idle core and the cache those apps would take.
    pub(super) fn keep_engines(&mut self, n: usize) {
        let Worlds::Pooled { engines, parked } = self else { return };
        let n = n.clamp(1, engines.len());
        if n == engines.len() {
            return;
        }
        engines.truncate(n);
        let worlds: Vec<Parked> = parked.drain(..).flatten().collect();
        let total = worlds.len();
        parked.extend((0..n).map(|_| Vec::new()));
        for (k, world) in worlds.into_iter().enumerate() {
            parked[k * n / total].push(world);
        }
    }

    pub(super) fn len(&self) -> usize {
        match self {
            Worlds::Apart(envs) => envs.len(),
            Worlds::Pooled { parked, .. } => parked.iter().map(Vec::len).sum(),
        }
    }

    /// Each world's seed, in order.
    pub(super) fn seeds(&self) -> Vec<u64> {
        match self {
            Worlds::Apart(envs) => envs.iter().map(|e| e.scene.seed).collect(),
            Worlds::Pooled { parked, .. } => parked.iter().flatten().map(|p| p.scene.seed).collect(),
        }
    }

    /// The engines' worlds, by id (none when apart).
    #[cfg(test)]
    pub(super) fn engine_ids(&self) -> Vec<bevy::ecs::world::WorldId> {
        match self {
            Worlds::Apart(_) => vec![],
            Worlds::Pooled { engines, .. } => engines.iter().map(|e| e.env.world.id()).collect(),
        }
    }

    /// Whether the worlds share engines.
    #[cfg(test)]
    pub(super) fn pooled(&self) -> bool {
        matches!(self, Worlds::Pooled { .. })
    }

    /// A world for what is the same in all of them (names, sizes, the registry): not one to step.
    pub(super) fn any(&self) -> &Env {
        match self {
            Worlds::Apart(envs) => &envs[0],
            Worlds::Pooled { engines, .. } => &engines[0].env,
        }
    }

    /// `f(k, world k)` for every world, on up to `workers` threads; the results in world order. Which
    /// engine or thread steps a world never changes what it computes.
    pub(super) fn map<R: Send>(&mut self, workers: usize, f: impl Fn(usize, &mut Env) -> R + Sync) -> Vec<R> {
        let n = self.len();
        self.map_with(workers, (0..n).map(|_| ()).collect(), |k, env, ()| f(k, env))
    }

    /// [`Worlds::map`] with `items[k]` handed to world k (e.g. its rows of an output array).
    pub(super) fn map_with<T: Send, R: Send>(
        &mut self,
        workers: usize,
        items: Vec<T>,
        f: impl Fn(usize, &mut Env, T) -> R + Sync,
    ) -> Vec<R> {
        match self {
            Worlds::Apart(envs) => {
                let mut work: Vec<(usize, &mut Env, Option<T>, Option<R>)> =
                    envs.iter_mut().zip(items).enumerate().map(|(k, (e, t))| (k, e, Some(t), None)).collect();
                crate::parallel::for_each_mut_on(&mut work, workers, |(k, env, item, out)| {
                    *out = item.take().map(|item| f(*k, env, item));
                });
                work.into_iter().map(|(_, _, _, r)| r.expect("every world visited")).collect()
            }
            Worlds::Pooled { engines, parked } => {
                let (mut first, mut items) = (0, items.into_iter());
                let mut work = Vec::new();
                for (engine, worlds) in engines.iter_mut().zip(parked.iter_mut()) {
                    let n = worlds.len();
                    let items = items.by_ref().take(n).collect();
                    work.push(Turn { first, engine, worlds, items, out: Vec::with_capacity(n) });
                    first += n;
                }
                crate::parallel::for_each_mut_on(&mut work, workers, |turn| {
                    for (i, item) in std::mem::take(&mut turn.items).into_iter().enumerate() {
                        for depth in 0..3 {
                            if let Some(ahead) = turn.worlds.get(i + 3 - depth) {
                                ahead.prefetch(depth);
                            }
                        }
                        let on = OnEngine::new(&mut turn.worlds[i], turn.engine);
                        turn.out.push(f(turn.first + i, &mut on.engine.env, item));
                    }
                });
                work.into_iter().flat_map(|turn| turn.out).collect()
            }
        }
    }

    /// `f(world k)` for one world.
    pub(super) fn with<R>(&mut self, k: usize, f: impl FnOnce(&mut Env) -> R) -> Option<R> {
        match self {
            Worlds::Apart(envs) => envs.get_mut(k).map(f),
            Worlds::Pooled { engines, parked } => {
                let mut k = k;
                for (engine, chunk) in engines.iter_mut().zip(parked.iter_mut()) {
                    if let Some(world) = chunk.get_mut(k) {
                        return Some(f(&mut OnEngine::new(world, engine).engine.env));
                    }
                    k -= chunk.len();
                }
                None
            }
        }
    }
}

/// A parked world swapped into an engine, swapped back out when dropped, also when what it was swapped in
/// for panics: the world is then left as that step left it, as a world of its own would be, and the
/// engine hosts again.
struct OnEngine<'a> {
    world: &'a mut Parked,
    engine: &'a mut Engine,
}

impl<'a> OnEngine<'a> {
    fn new(world: &'a mut Parked, engine: &'a mut Engine) -> OnEngine<'a> {
        world.swap(engine);
        OnEngine { world, engine }
    }
}

impl Drop for OnEngine<'_> {
    fn drop(&mut self) {
        self.world.swap(self.engine);
    }
}

/// One engine's share of a [`Worlds::map_with`]: its worlds (the first is world `first`), their items
/// and their results.
struct Turn<'a, T, R> {
    first: usize,
    engine: &'a mut Engine,
    worlds: &'a mut [Parked],
    items: Vec<T>,
    out: Vec<R>,
}

/// Prefetches the cache lines of `items` into the first-level cache (x86-64; elsewhere nothing).
#[inline]
fn prefetch<T>(items: &[T]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let start = items.as_ptr() as *const i8;
        for offset in (0..std::mem::size_of_val(items)).step_by(64) {
            // SAFETY: the address lies within `items`; a prefetch reads nothing and faults never.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(start.add(offset)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = items;
}

/// The parameters of the fixed actors a world holds (species in registry order).
fn fixed_actors(env: &Env) -> Vec<Option<Vec<Vec<f32>>>> {
    env.world
        .get_resource::<Learners>()
        .map_or_else(Vec::new, |l| l.species.iter().map(|s| s.as_ref().map(|s| s.ddpg.actor.parameters())).collect())
}

/// Whether the worlds of `env`'s kind can share engines: Err naming the first resource or component that
/// keeps them apart.
pub(super) fn eligible(env: &Env) -> Result<(), String> {
    let world = &env.world;
    if let Some(learners) = world.get_resource::<Learners>() {
        if learners.mode != Mode::Evaluate || learners.league.is_some() {
            return Err("coevo trains a side in every world".into());
        }
    }
    let plugins = &world.resource::<crate::sim::policy::PolicyPlugins>().0;
    if let Some(name) = plugins.iter().find(|name| *name != EXTERNAL) {
        return Err(format!("species plugin {name:?} is in the app; its systems may keep state of their own"));
    }
    let bare: Vec<TypeId> = {
        let mut app = App::new();
        app.finish();
        app.cleanup();
        app.world().iter_resources().filter_map(|(info, _)| info.type_id()).collect()
    };
    let (parked, shared) = (Resources::types(), shared_resources());
    for (info, _) in world.iter_resources() {
        let t = info.type_id();
        if !t.is_some_and(|t| parked.contains(&t) || shared.contains(&t) || bare.contains(&t)) {
            return Err(format!("resource {} is neither parked nor shared", info.name()));
        }
    }
    let (agent_id, known) = (world.components().component_id::<AgentId>(), agent_components());
    for archetype in world.archetypes().iter().filter(|a| agent_id.is_some_and(|id| a.contains(id))) {
        for &c in archetype.components() {
            let info = world.components().get_info(c).expect("an archetype's component is registered");
            if !info.type_id().is_some_and(|t| known.contains(&t)) {
                return Err(format!("agent component {} is not parked", info.name()));
            }
        }
    }
    Ok(())
}
