//! A third species as a plugin: the hawk, a super-predator that catches predators and learns with them
//! (the book's "Add a species", docs/src/guide/species.md, follows this file). The whole command line of
//! coevo, with one species more:
//!
//! ```text
//! cargo run --release --example hawk -- --describe-scene examples/hawk.ron
//! cargo run --release --example hawk -- --train --scene examples/hawk.ron --out runs/hawk
//! cargo run --release --features viewer --example hawk -- --scene examples/hawk.ron
//! ```

use bevy::prelude::*;
use coevo::scene::{ContactReward, Perception, Policy, SpeciesDef};
use coevo::sim::components::{Reward, Slot, SpeciesId};
use coevo::sim::perception::{Batches, Population};
use coevo::sim::reward::{add_reward, RewardStage};
use coevo::sim::space::Arena;
use coevo::sim::species::{SpeciesPlugin, SpeciesPlugins, SpeciesRegistry, SpeciesTemplate};
use coevo::sim::SimSet;

/// 1. The plugin: a Bevy plugin that is also a species.
#[derive(Clone)]
pub struct HawkPlugin;

/// Hawks are territorial: this much reward per step for each other hawk closer than `TERRITORY`.
const CROWDING_PENALTY: f64 = 0.05;
const TERRITORY: f64 = 0.3;

/// 2. The species: its defaults (a scene only names it and overrides fields) and its interactions.
impl SpeciesPlugin for HawkPlugin {
    fn template(&self) -> SpeciesTemplate {
        SpeciesTemplate {
            def: SpeciesDef {
                name: "hawk".into(),
                count: 1,
                mass: 2.0,
                radius: 0.07,
                max_speed: 0.5,
                max_thrust: 1.5,
                max_turn_rate: 5.0,
                perception: Perception::Full,
                topological_limit: 6,
                colour: [0.55, 0.2, 0.7],
                catches: vec!["predator".into()],
                policy: Policy::Learned,
                blind_to: vec![],
                perception_of: vec![],
                topological_limit_of: vec![],
                field_of_view: coevo::scene::FULL_VIEW,
                field_of_view_of: vec![],
            },
            // Nobody catches hawks.
            caught_by: vec![],
            // A hawk on a predator: +5 for the hawk, −5 for the predator (the gym-pps contact reward).
            contact_rewards: vec![ContactReward {
                catcher: "hawk".into(),
                caught: "predator".into(),
                catcher_reward: 5.0,
                caught_reward: -5.0,
            }],
        }
    }
}

/// 3. Its systems: here an extra reward term, after the survival reward of every species.
impl Plugin for HawkPlugin {
    fn build(&self, app: &mut App) {
        app.add_systems(FixedUpdate, territory.after(RewardStage::Survival).in_set(SimSet::Reward));
    }
}

fn territory(
    registry: Res<SpeciesRegistry>,
    pop: Res<Population>,
    arena: Res<Arena>,
    mut batches: ResMut<Batches>,
    mut agents: Query<(&SpeciesId, &Slot, &mut Reward)>,
) {
    // A scene without hawks: nothing to do.
    let Some(hawk) = registry.index_of("hawk") else { return };
    for (species, slot, mut reward) in &mut agents {
        if species.0 != hawk {
            continue;
        }
        let me = pop.position[slot.index as usize];
        let crowd = pop.ranges[hawk]
            .clone()
            .filter(|&j| j != slot.index as usize && arena.delta(me, pop.position[j]).length() < TERRITORY)
            .count();
        if crowd > 0 {
            add_reward(&mut batches, *species, *slot, &mut reward, -CROWDING_PENALTY * crowd as f64);
        }
    }
}

/// 4. The program: coevo's command line with the hawk registered.
fn main() -> std::process::ExitCode {
    coevo::cli::main(SpeciesPlugins::new().with(HawkPlugin))
}
