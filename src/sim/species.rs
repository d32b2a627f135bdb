//! Species are data: a registry of definitions loaded from the scene; nothing in the core names
//! "predator" or "prey".
//!
//! A new species is a [`SpeciesPlugin`]: a Bevy plugin that also gives the species' definition with its
//! defaults and its interactions ([`SpeciesTemplate`]). Programs hand their species plugins to
//! [`crate::cli::main`], which registers them in a program-wide [`catalog`] before any scene is read, so a
//! scene only names the species and overrides what it wants (`(name: "hawk", count: 2)`), and every
//! simulation the program makes (headless or in the viewer) gets the plugins' systems (extra reward terms,
//! a decide system of its own). `examples/hawk.rs` is a complete one.

use crate::scene::{Perception, Policy, Scene, SpeciesDef};
use bevy::prelude::*;
use std::sync::Arc;

pub use crate::scene::catalog::SpeciesTemplate;
pub(crate) use crate::scene::layout::{Layout, ACTION_DIM, NEIGHBOUR_DIM, OWN_STATE_DIM};

/// The species of the scene, in registry order (which is also the order of observation blocks).
#[derive(Resource, Clone, Debug)]
pub struct SpeciesRegistry {
    pub defs: Vec<SpeciesDef>,
    /// `catches[a][b]`: species a catches species b on contact.
    pub(crate) catches: Vec<Vec<bool>>,
    /// Perception radius R in metres, resolved against D.
    pub(crate) perception_radius: Vec<f64>,
    /// `perception_radii[a][b]`: the radius within which species a perceives species b (R of a, unless
    /// a's `perception_of` names b).
    pub(crate) perception_radii: Vec<Vec<f64>>,
    /// `blind[a][b]`: species a never sees species b (`blind_to`): its block of b stays zero.
    pub(crate) blind: Vec<Vec<bool>>,
    /// `view[a][b]`: the cosine of half of a's field of view of species b (`field_of_view`,
    /// `field_of_view_of`), None when a sees b all around (the paper): b is perceived only where the
    /// angle between a's heading and the direction to it is at most half the field of view.
    pub(crate) view: Vec<Vec<Option<f64>>>,
    /// `contact_reward[a][b]`: (to the catcher, to the caught) per contact where a catches b; ±contact
    /// unless the scene's `contact_rewards` sets the pair.
    pub(crate) contact_reward: Vec<Vec<(f64, f64)>>,
    /// Where each part of species a's observation sits (its blocks' slots, the order of its parts).
    pub(crate) layouts: Vec<Layout>,
}

impl SpeciesRegistry {
    pub fn from_scene(scene: &Scene) -> Self {
        let defs = scene.species.clone();
        let index = |name: &str| defs.iter().position(|d| d.name == name);
        let catches = defs
            .iter()
            .map(|a| {
                let mut row = vec![false; defs.len()];
                for target in &a.catches {
                    if let Some(b) = index(target) {
                        row[b] = true;
                    }
                }
                row
            })
            .collect();
        let d = scene.max_distance();
        let resolve = |p: &Perception| match *p {
            Perception::Full => d,
            Perception::FractionOfD(f) => f * d,
            Perception::Radius(r) => r,
        };
        let perception_radius: Vec<f64> = defs.iter().map(|s| resolve(&s.perception)).collect();
        let perception_radii = defs
            .iter()
            .zip(&perception_radius)
            .map(|(a, &r)| {
                defs.iter()
                    .map(|b| a.perception_of.iter().find(|(name, _)| *name == b.name).map_or(r, |(_, p)| resolve(p)))
                    .collect()
            })
            .collect();
        let blind = defs.iter().map(|a| defs.iter().map(|b| a.blind_to.contains(&b.name)).collect()).collect();
        let view = defs
            .iter()
            .map(|a| {
                defs.iter()
                    .map(|b| {
                        let degrees = a
                            .field_of_view_of
                            .iter()
                            .find(|(name, _)| *name == b.name)
                            .map_or(a.field_of_view, |(_, f)| *f);
                        (degrees < crate::scene::FULL_VIEW).then(|| (degrees.to_radians() / 2.0).cos())
                    })
                    .collect()
            })
            .collect();
        let contact = scene.rewards.contact;
        let contact_reward = defs
            .iter()
            .map(|a| {
                defs.iter()
                    .map(|b| {
                        scene
                            .contact_rewards
                            .iter()
                            .find(|r| r.catcher == a.name && r.caught == b.name)
                            .map_or((contact, -contact), |r| (r.catcher_reward, r.caught_reward))
                    })
                    .collect()
            })
            .collect();
        let layouts = (0..defs.len()).map(|s| scene.layout(s)).collect();
        SpeciesRegistry { defs, catches, perception_radius, perception_radii, blind, view, contact_reward, layouts }
    }

    pub fn len(&self) -> usize {
        self.defs.len()
    }

    /// Species a's field of view of species b in degrees, None when it sees b all around ([`Self::view`]).
    pub(crate) fn field_of_view(&self, a: usize, b: usize) -> Option<f64> {
        self.view[a][b].map(|cos_half| 2.0 * cos_half.acos().to_degrees())
    }

    pub fn is_empty(&self) -> bool {
        self.defs.is_empty()
    }

    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.defs.iter().position(|d| d.name == name)
    }

    /// d_o for an observer of species `s` ([`Layout::dim`]; 54 for the paper's two species and limit 6).
    pub fn observation_dim(&self, s: usize) -> usize {
        self.layouts[s].dim()
    }

    /// The block of species `t` in the observation of species `s`.
    pub(crate) fn block(&self, s: usize, t: usize) -> std::ops::Range<usize> {
        self.layouts[s].block(t)
    }

    /// Offset of the block of species `t` in the observation of species `s`.
    pub fn block_offset(&self, s: usize, t: usize) -> usize {
        self.block(s, t).start
    }

    /// How many agents of species `t` an agent of species `s` observes at most.
    pub(crate) fn slots(&self, s: usize, t: usize) -> usize {
        self.layouts[s].slots[t]
    }

    /// The species whose DoS/DoA headline a run: the first that something catches and that catches nothing
    /// (the prey, also in a scene where hawks catch predators), else the first that something catches, else
    /// the first with at least two agents.
    pub(crate) fn headline(&self) -> usize {
        self.headline_counting(true)
    }

    /// The headline species as the species define it, whatever their counts: [`SpeciesRegistry::headline`]
    /// without its "two or more" condition on caught species, so it never moves to another species when the
    /// prey are few (a step's reported DoS and DoA are then NaN, not the predators').
    pub(crate) fn headline_by_kind(&self) -> usize {
        self.headline_counting(false)
    }

    fn headline_counting(&self, counts: bool) -> usize {
        let caught = |s: usize| self.predators_of(s).next().is_some() && (!counts || self.defs[s].count >= 2);
        // The bottom of the food chain first (prey, also when hawks catch predators), then anything caught.
        (0..self.len())
            .find(|&s| caught(s) && self.prey_of(s).next().is_none())
            .or_else(|| (0..self.len()).find(|&s| caught(s)))
            .or_else(|| (0..self.len()).find(|&s| self.defs[s].count >= 2))
            .unwrap_or(0)
    }

    /// What decides the actions of species `s`.
    pub(crate) fn policy(&self, s: usize) -> &Policy {
        &self.defs[s].policy
    }

    /// Species that species `s` catches.
    pub fn prey_of(&self, s: usize) -> impl Iterator<Item = usize> + '_ {
        (0..self.len()).filter(move |&t| self.catches[s][t])
    }

    /// Species that catch species `s`.
    pub(crate) fn predators_of(&self, s: usize) -> impl Iterator<Item = usize> + '_ {
        (0..self.len()).filter(move |&t| self.catches[t][s])
    }
}

/// A species of your own: a Bevy plugin (whatever systems it needs, e.g. an extra reward term in
/// `SimSet::Reward` after [`crate::sim::reward::RewardStage::Survival`], or a decide system for a `Plugin(name)`
/// policy) that also defines the species ([`SpeciesTemplate`]).
pub trait SpeciesPlugin: Plugin + Clone {
    fn template(&self) -> SpeciesTemplate;
}

/// The species plugins of a program: registered in the [`catalog`] at start-up, built into every
/// simulation it makes.
#[derive(Clone, Default)]
pub struct SpeciesPlugins {
    templates: Vec<SpeciesTemplate>,
    builders: Vec<catalog::Builder>,
}

impl SpeciesPlugins {
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a species plugin.
    pub fn with<P: SpeciesPlugin>(mut self, plugin: P) -> Self {
        self.templates.push(plugin.template());
        self.builders.push(Arc::new(move |app: &mut App| {
            app.add_plugins(plugin.clone());
        }));
        self
    }

    /// Puts every template in the program's catalog, after checking that no two species share a name
    /// (with each other or the presets' species) and that every species an interaction names exists.
    pub fn register(&self) -> crate::error::Result<()> {
        let preset_names: Vec<String> = crate::scene::PRESETS
            .iter()
            .filter_map(|p| Scene::preset(p))
            .flat_map(|s| s.species.into_iter().map(|d| d.name))
            .collect();
        let mut known: Vec<String> = preset_names.clone();
        for t in &self.templates {
            let name = &t.def.name;
            if known.contains(name) {
                let whose = if preset_names.contains(name) { "a preset's species" } else { "another species plugin" };
                return Err(format!(
                    "species plugin {name:?}: {whose} has that name already; give each species its own name"
                )
                .into());
            }
            known.push(name.clone());
        }
        for t in &self.templates {
            let names = t
                .def
                .catches
                .iter()
                .chain(&t.caught_by)
                .chain(t.contact_rewards.iter().flat_map(|r| [&r.catcher, &r.caught]));
            for other in names {
                if !known.contains(other) {
                    return Err(format!(
                        "species plugin {:?}: its interactions name {other:?}, which no preset or species plugin of this program defines",
                        t.def.name
                    ).into());
                }
            }
        }
        self.templates.iter().zip(&self.builders).try_for_each(|(t, b)| catalog::insert(t.clone(), b.clone()))
    }
}

/// The species templates of this program, read when scenes are resolved (scenes are read before any app
/// exists, like the presets, so this is program-wide state, filled once at start-up).
pub(crate) mod catalog {
    use super::SpeciesTemplate;
    use bevy::prelude::App;
    use std::sync::{Arc, RwLock};

    pub(crate) use crate::scene::catalog::get;

    /// Adds a species plugin to an app.
    pub(crate) type Builder = Arc<dyn Fn(&mut App) + Send + Sync>;

    static BUILDERS: RwLock<Vec<Builder>> = RwLock::new(Vec::new());

    /// Adds a species (its template to the scenes' catalog, its systems to every app); the same template
    /// again is a no-op, another one of the same name an error.
    pub(crate) fn insert(t: SpeciesTemplate, build: Builder) -> crate::error::Result<()> {
        if crate::scene::catalog::insert(t)? {
            BUILDERS.write().unwrap_or_else(|e| e.into_inner()).push(build);
        }
        Ok(())
    }

    /// Adds every registered species plugin to an app (what [`crate::sim::SimulationPlugin`] does); their
    /// systems find their species in the registry and do nothing in a scene without it.
    pub(crate) fn build_plugins(app: &mut App) {
        let builders: Vec<Builder> = BUILDERS.read().unwrap_or_else(|e| e.into_inner()).clone();
        for b in builders {
            b(app);
        }
    }
}

/// A scene as the simulation will run it, for `coevo --describe-scene`: species and counts, who catches
/// whom with the reward of each contact, each observer species' observation layout (offsets, d_o), then
/// every resolved parameter.
pub fn describe(scene: &Scene, source: &str) -> String {
    use std::fmt::Write as _;
    let r = SpeciesRegistry::from_scene(scene);
    let mut out = String::new();
    let _ = writeln!(
        out,
        "scene {source}: preset {}, seed {}, {:?} observations",
        scene.preset, scene.seed, scene.observation_frame
    );
    let _ = writeln!(out, "\nspecies (registry order = the order of observation blocks):");
    for (s, d) in r.defs.iter().enumerate() {
        let _ = writeln!(
            out,
            "  {s} {}: {} agents, policy {}, mass {} kg, radius {} m, max speed {} m/s, perception R = {:.4} m, at most {} observed per species{}",
            d.name, d.count, ron::to_string(&d.policy).unwrap_or_default(), d.mass, d.radius, d.max_speed, r.perception_radius[s], d.topological_limit,
            d.topological_limit_of.iter().map(|(t, k)| format!(", {k} of {t}")).collect::<String>()
        );
    }
    let _ = writeln!(out, "\ncontacts (catcher -> caught: reward to the catcher / to the caught, per contact):");
    let mut any = false;
    for a in 0..r.len() {
        for b in r.prey_of(a) {
            let (to_catcher, to_caught) = r.contact_reward[a][b];
            let _ = writeln!(out, "  {} -> {}: {to_catcher:+} / {to_caught:+}", r.defs[a].name, r.defs[b].name);
            any = true;
        }
    }
    if !any {
        out.push_str("  none\n");
    }
    for s in 0..r.len() {
        let d_o = r.observation_dim(s);
        let _ = writeln!(out, "\nobservation of {} (d_o = {d_o}):", r.defs[s].name);
        let layout = &r.layouts[s];
        let _ = writeln!(out, "  [0, {}) own state", layout.leading());
        for t in 0..r.len() {
            let from = r.block_offset(s, t);
            let slots = r.slots(s, t);
            let seen = if r.blind[s][t] {
                " — never seen (blind_to): always zero".to_string()
            } else if r.perception_radii[s][t] != r.perception_radius[s] {
                format!(" within R = {:.4} m (perception_of)", r.perception_radii[s][t])
            } else {
                String::new()
            };
            let view = match r.field_of_view(s, t) {
                Some(degrees) if !r.blind[s][t] => {
                    format!(" in a {degrees:.0}° field of view (blind {:.0}° behind)", 360.0 - degrees)
                }
                _ => String::new(),
            };
            let _ = writeln!(
                out,
                "  [{from}, {}) {}: {slots} slots × {NEIGHBOUR_DIM}{seen}{view}",
                from + slots * NEIGHBOUR_DIM,
                r.defs[t].name
            );
        }
        if let Some(e) = layout.energy() {
            let h = layout.heading();
            let _ =
                writeln!(out, "  [{e}, {}) energy input 2·E/E_max − 1\n  [{}, {}) own heading", e + 1, h.start, h.end);
        }
    }
    let _ = writeln!(out, "\nresolved scene:\n{}", scene.to_ron());
    out
}
