//! A species of your own without editing the core: a scene entry gives its body, limits, colour and what it
//! catches, and your Bevy plugin decides its actions with a system in `SimSet::Decide` that writes the
//! species' rows of the action batch (`policy: Plugin("name")`).

use bevy::prelude::*;
use coevo::scene::{Policy, Scene};
use coevo::sim::components::{Action, AgentId, Heading, SpeciesId};
use coevo::sim::perception::Batches;
use coevo::sim::physics::wrap_angle;
use coevo::sim::policy::PolicyPlugins;
use coevo::sim::species::SpeciesRegistry;
use coevo::sim::{SimSet, Simulation};

/// Circlers: full thrust, turning left as fast as they can, forever.
struct CirclerPlugin;

impl Plugin for CirclerPlugin {
    fn build(&self, app: &mut App) {
        app.add_systems(FixedUpdate, circle.in_set(SimSet::Decide));
        PolicyPlugins::register(app, "circler");
    }
}

fn circle(registry: Res<SpeciesRegistry>, mut batches: ResMut<Batches>) {
    for (s, def) in registry.defs.iter().enumerate() {
        if def.policy == Policy::Plugin("circler".into()) {
            // Normalized actions: thrust 1 → max_thrust, turn rate 1 → +max_turn_rate.
            batches.species[s].actions.fill(1.0);
        }
    }
}

fn scene() -> Scene {
    Scene::parse(
        r#"(
            preset: "paper",
            species: [
                (name: "predator", policy: ChaseNearest),
                (name: "prey", policy: FleeNearest),
                (name: "circler", count: 4, mass: 1.5, radius: 0.05, max_speed: 0.5, max_thrust: 1.2,
                 max_turn_rate: 2.0, perception: FractionOfD(0.5), topological_limit: 3,
                 colour: (0.3, 0.7, 0.3), catches: ["prey"], policy: Plugin("circler")),
            ],
        )"#,
        "circler.ron",
    )
    .unwrap()
}

#[test]
fn a_plugin_decides_a_third_species_that_everyone_observes() {
    let mut sim = Simulation::with_plugins(scene(), |app| {
        app.add_plugins(CirclerPlugin);
    });
    let registry = sim.world().resource::<SpeciesRegistry>().clone();
    let circler = registry.index_of("circler").unwrap();
    let prey = registry.index_of("prey").unwrap();
    // Everyone observes the third species in a block of its own: 6 + 4·6·3 for prey, 6 + 4·3·3 for it.
    assert_eq!(registry.observation_dim(prey), 78);
    assert_eq!(registry.observation_dim(circler), 42);
    assert_eq!(registry.prey_of(circler).collect::<Vec<_>>(), vec![prey]);

    let headings = |sim: &mut Simulation| -> Vec<f64> {
        let world = sim.world_mut();
        let mut h: Vec<(u32, f64)> = world
            .query::<(&AgentId, &SpeciesId, &Heading)>()
            .iter(world)
            .filter(|(_, s, _)| s.0 == circler)
            .map(|(id, _, h)| (id.0, h.0))
            .collect();
        h.sort_by_key(|x| x.0);
        h.into_iter().map(|x| x.1).collect()
    };
    let before = headings(&mut sim);
    sim.step();
    let world = sim.world_mut();
    let mut q = world.query::<(&SpeciesId, &Action)>();
    let actions: Vec<Action> = q.iter(world).filter(|(s, _)| s.0 == circler).map(|(_, a)| *a).collect();
    assert_eq!(actions.len(), 4);
    for a in actions {
        assert_eq!((a.thrust, a.turn_rate), (1.2, 2.0), "the plugin's actions, rescaled to the species' limits");
    }
    // Each turned left by max_turn_rate·dt = 0.2 rad.
    for (b, a) in before.iter().zip(headings(&mut sim)) {
        assert!(wrap_angle(a - b - 0.2).abs() < 1e-12, "turned {} rad", a - b);
    }
}

#[test]
fn a_plugin_policy_that_no_plugin_decides_is_refused() {
    let err = Simulation::try_with_plugins(scene(), |_| {}).err().expect("refused").to_string();
    assert_eq!(
        err,
        "species[circler].policy: no plugin decides Plugin(\"circler\") in this program (registered: none)"
    );
}

// ---- Species plugins: a species defined by a plugin, named by a scene, learning with the others. ----

mod owl {
    use bevy::prelude::*;
    use coevo::scene::{ContactReward, Perception, Policy, SpeciesDef};
    use coevo::sim::species::{SpeciesPlugin, SpeciesTemplate};

    /// An owl catches predators (+3 to the owl, −2 to the predator) and is caught by nobody.
    #[derive(Clone)]
    pub struct OwlPlugin;

    impl Plugin for OwlPlugin {
        fn build(&self, _: &mut App) {}
    }

    impl SpeciesPlugin for OwlPlugin {
        fn template(&self) -> SpeciesTemplate {
            SpeciesTemplate {
                def: SpeciesDef {
                    name: "owl".into(),
                    count: 1,
                    mass: 2.0,
                    radius: 0.05,
                    max_speed: 0.5,
                    max_thrust: 1.0,
                    max_turn_rate: 0.5,
                    perception: Perception::Full,
                    topological_limit: 6,
                    colour: [0.5, 0.3, 0.1],
                    catches: vec!["predator".into()],
                    policy: Policy::Learned,
                    blind_to: vec![],
                    perception_of: vec![],
                    topological_limit_of: vec![],
                    field_of_view: coevo::scene::FULL_VIEW,
                    field_of_view_of: vec![],
                },
                caught_by: vec![],
                contact_rewards: vec![ContactReward {
                    catcher: "owl".into(),
                    caught: "predator".into(),
                    catcher_reward: 3.0,
                    caught_reward: -2.0,
                }],
            }
        }
    }

    /// A broken one: its interactions name a species nobody defines.
    #[derive(Clone)]
    pub struct Griffin;

    impl Plugin for Griffin {
        fn build(&self, _: &mut App) {}
    }

    impl SpeciesPlugin for Griffin {
        fn template(&self) -> SpeciesTemplate {
            let mut t = OwlPlugin.template();
            t.def.name = "griffin".into();
            t.def.catches = vec!["unicorn".into()];
            t.contact_rewards.clear();
            t
        }
    }

    /// Another species called "prey".
    #[derive(Clone)]
    pub struct FakePrey;

    impl Plugin for FakePrey {
        fn build(&self, _: &mut App) {}
    }

    impl SpeciesPlugin for FakePrey {
        fn template(&self) -> SpeciesTemplate {
            let mut t = OwlPlugin.template();
            t.def.name = "prey".into();
            t.contact_rewards.clear();
            t
        }
    }
}

fn owl_scene() -> Scene {
    coevo::sim::species::SpeciesPlugins::new().with(owl::OwlPlugin).register().unwrap();
    Scene::parse(
        r#"(
            preset: "paper",
            species: [
                (name: "predator", count: 2),
                (name: "prey", count: 4),
                (name: "owl", count: 1),
            ],
        )"#,
        "owl.ron",
    )
    .unwrap()
}

#[test]
fn a_scene_names_a_plugin_species_and_the_plugin_supplies_the_rest() {
    let scene = owl_scene();
    let owl = scene.species.iter().find(|s| s.name == "owl").unwrap();
    assert_eq!((owl.count, owl.mass, owl.catches.clone()), (1, 2.0, vec!["predator".to_string()]));
    assert_eq!(scene.contact_rewards.len(), 1, "the plugin's pair reward entered the scene");
    // --describe-scene prints the layout the simulation uses.
    let registry = SpeciesRegistry::from_scene(&scene);
    let text = coevo::sim::species::describe(&scene, "owl.ron");
    for s in 0..registry.len() {
        let name = &registry.defs[s].name;
        assert!(text.contains(&format!("observation of {name} (d_o = {}):", registry.observation_dim(s))), "{text}");
        for t in 0..registry.len() {
            let from = registry.block_offset(s, t);
            assert!(
                text.contains(&format!("  [{from}, {}) {}: 6 slots × 4", from + 24, registry.defs[t].name)),
                "{text}"
            );
        }
    }
    assert_eq!(registry.observation_dim(registry.index_of("owl").unwrap()), 6 + 4 * 6 * 3);
    assert!(text.contains("owl -> predator: +3 / -2") && text.contains("predator -> prey: +1 / -1"), "{text}");
}

#[test]
fn contact_rewards_are_paid_pair_by_pair() {
    let mut scene = owl_scene();
    for s in &mut scene.species {
        // Heavy and still: the hand-placed contacts survive one step, and no energy is spent.
        s.mass = 100.0;
        s.policy = Policy::Still;
    }
    scene.species[0].count = 1;
    scene.species[1].count = 1;
    let mut sim = Simulation::new(scene);
    let registry = sim.world().resource::<SpeciesRegistry>().clone();
    // Ids by spawn order, species by species: predator 0, prey 1, owl 2.
    use bevy::math::DVec2;
    common_place(&mut sim, 0, DVec2::new(0.0, 0.0));
    common_place(&mut sim, 1, DVec2::new(0.03, 0.0));
    common_place(&mut sim, 2, DVec2::new(-0.03, 0.0));
    sim.step();
    let batches = sim.world().resource::<coevo::sim::perception::Batches>();
    let reward = |name: &str| batches.species[registry.index_of(name).unwrap()].rewards[0];
    // The predator catches the prey (+1) and is caught by the owl (−2); the prey is caught (−1); the owl
    // catches (+3); the prey touching the owl is no catch either way.
    assert_eq!((reward("predator"), reward("prey"), reward("owl")), (-1.0, -1.0, 3.0));
}

fn common_place(sim: &mut Simulation, id: u32, x: bevy::math::DVec2) {
    let world = sim.world_mut();
    let mut q = world.query::<(&AgentId, &mut coevo::sim::components::Position)>();
    for (aid, mut p) in q.iter_mut(world) {
        if aid.0 == id {
            p.0 = x;
        }
    }
    world.run_schedule(coevo::sim::perception::Perceive);
}

#[test]
fn a_plugin_species_learns_with_the_other_two() {
    let mut scene = owl_scene();
    scene.episode_steps = 20;
    scene.learning.hidden = 16;
    scene.learning.batch_size = 16;
    scene.learning.warmup_transitions = 16;
    scene.learning.updates_per_episode = 3;
    scene.learning.checkpoint_every = 1;
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let opts = coevo::run::train::TrainOptions::new(run.clone(), Some(2));
    coevo::run::train::train(scene, &opts).unwrap();
    let metrics = std::fs::read_to_string(run.join("metrics.csv")).unwrap();
    let header: Vec<&str> = metrics.lines().next().unwrap().split(',').collect();
    let last: Vec<&str> = metrics.lines().last().unwrap().split(',').collect();
    let cell = |name: &str| {
        last[header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("{name}"))].parse::<f64>().unwrap()
    };
    // Catches by catcher species: predators on prey and owls on predators, apart.
    assert!(header.contains(&"catches_by_predator") && header.contains(&"catches_by_owl"), "{header:?}");
    assert_eq!(cell("catches"), cell("catches_by_predator") + cell("catches_by_owl"));
    for species in ["predator", "prey", "owl"] {
        assert!(cell(&format!("critic_loss_{species}")).is_finite(), "{species} learned");
        assert!(run.join(format!("checkpoint/{species}-actor.safetensors")).exists());
    }
}

#[test]
fn bad_species_plugins_are_refused_in_one_line() {
    use coevo::sim::species::SpeciesPlugins;
    let err = SpeciesPlugins::new().with(owl::Griffin).register().unwrap_err().to_string();
    assert_eq!(err, "species plugin \"griffin\": its interactions name \"unicorn\", which no preset or species plugin of this program defines");
    let err = SpeciesPlugins::new().with(owl::FakePrey).register().unwrap_err().to_string();
    assert_eq!(
        err,
        "species plugin \"prey\": a preset's species has that name already; give each species its own name"
    );
    let err = SpeciesPlugins::new().with(owl::OwlPlugin).with(owl::OwlPlugin).register().unwrap_err().to_string();
    assert_eq!(
        err,
        "species plugin \"owl\": another species plugin has that name already; give each species its own name"
    );
    // A scene naming a species nothing defines.
    let err = Scene::parse(r#"(species: [(name: "basilisk", count: 2)])"#, "b.ron").unwrap_err().to_string();
    assert!(
        err.starts_with("b.ron:1: species[basilisk]: no preset or species plugin of this program defines \"basilisk\""),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1);
}
