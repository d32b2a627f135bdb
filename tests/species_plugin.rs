//! A species of your own without editing the core: a scene entry gives its body, limits, colour and what it
//! catches, and your Bevy plugin decides its actions with a system in `SimSet::Decide` that writes the
//! species' rows of the action batch (`policy: Plugin("name")`).

use bevy::prelude::*;
use coevo::components::{Action, AgentId, Heading, SpeciesId};
use coevo::perception::Batches;
use coevo::physics::wrap_angle;
use coevo::policy::PolicyPlugins;
use coevo::scene::{Policy, Scene};
use coevo::species::SpeciesRegistry;
use coevo::{SimSet, Simulation};

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
    let err = Simulation::try_with_plugins(scene(), |_| {}).err().expect("refused");
    assert_eq!(
        err,
        "species[circler].policy: no plugin decides Plugin(\"circler\") in this program (registered: none)"
    );
}
