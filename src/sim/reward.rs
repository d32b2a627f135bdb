//! The reward of the transition t → t+1 (Section "Rewards"): survival only, plus the "laziness" energy
//! cost and, in walled scenes that enable it, a wall penalty.
//!
//! ```text
//!   r = Σ_contacts r_pair − thrust_cost·|a_F| − turn_cost·|a_R| − wall_penalty·walls
//! ```
//!
//! r_pair is what the contact pays this side: +contact to a catcher and −contact to the caught unless the
//! scene's `contact_rewards` (or a species plugin) sets the pair. In the paper's two-species world that is
//! +1 per prey touched for a predator and −1 per predator touching a prey. Contacts are judged on the state
//! after the move (`paper`) or before it (`gym-pps`). Species plugins add terms of their own after
//! [`RewardStage::Survival`].

use super::schedule::{ActiveScene, SimSet};
use crate::scene::{ContactJudging, RewardParams, WallPenaltyMode};
use crate::sim::components::*;
use crate::sim::perception::Batches;
use bevy::prelude::*;

/// Within `SimSet::Reward`: the survival reward and energy costs first; extra terms of species plugins
/// go `.after(RewardStage::Survival)` and add to both the agent's [`Reward`] and its batch row (see
/// [`add_reward`]).
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RewardStage {
    Survival,
}

pub(crate) struct RewardPlugin;

impl Plugin for RewardPlugin {
    fn build(&self, app: &mut App) {
        app.add_systems(FixedUpdate, assign_rewards.in_set(RewardStage::Survival).in_set(SimSet::Reward));
    }
}

/// Adds `amount` to an agent's reward for this transition, where the learner reads it too.
pub fn add_reward(batches: &mut Batches, species: SpeciesId, slot: Slot, reward: &mut Reward, amount: f64) {
    reward.0 += amount;
    batches.species[species.0].rewards[slot.row as usize] = reward.0 as f32;
}

/// The reward of one agent for one transition.
pub(crate) fn reward(params: &RewardParams, action: &Action, contacts: &Contacts) -> f64 {
    let c = match params.contacts_judged {
        ContactJudging::AfterMove => contacts.now,
        ContactJudging::BeforeMove => contacts.before,
    };
    let walls = match params.wall_penalty_mode {
        WallPenaltyMode::AnyWall => (c.walls > 0) as u32,
        WallPenaltyMode::PerWall => c.walls,
    };
    c.contact_reward
        - params.thrust_cost * action.thrust.abs()
        - params.turn_cost * action.turn_rate.abs()
        - params.wall_penalty * walls as f64
}

fn assign_rewards(
    scene: Res<ActiveScene>,
    mut batches: ResMut<Batches>,
    mut agents: Query<(&Slot, &SpeciesId, &Action, &Contacts, &mut Reward)>,
) {
    for (slot, species, action, contacts, mut r) in &mut agents {
        r.0 = reward(&scene.0.rewards, action, contacts);
        batches.species[species.0].rewards[slot.row as usize] = r.0 as f32;
    }
}
