//! The presets a scene starts from (`../shared/reference/parameters.md`): `paper`, the paper's values with
//! the authors' code's where the paper is silent, and `gym-pps`, the authors' code as it runs.

use super::schema::*;

/// The `paper` preset: the paper's values, the authors' code's where the paper is silent.
pub(super) fn paper() -> Scene {
    let species = |name: &str, count, radius, colour, catches: &[&str], policy| SpeciesDef {
        name: name.into(),
        count,
        mass: 1.0,
        radius,
        max_speed: 0.5,
        max_thrust: 1.0,
        max_turn_rate: 0.5,
        perception: Perception::Full,
        topological_limit: 6,
        colour,
        catches: catches.iter().map(|s| s.to_string()).collect(),
        policy,
        blind_to: vec![],
        field_of_view: super::schema::FULL_VIEW,
        field_of_view_of: vec![],
        perception_of: vec![],
        topological_limit_of: vec![],
    };
    Scene {
        preset: "paper".into(),
        seed: 0,
        episode_steps: 500,
        episodes: 2000,
        world: WorldParams {
            arena_edge: 2.0,
            boundary: Boundary::Periodic,
            dt: 0.1,
            drag: 2.0,
            contact_stiffness: 50.0,
            wall_stiffness: 50.0,
            wall_damping: 0.0,
            speed_clip: SpeedClip::Norm,
            energy_budget: false,
            spawn: Spawn::Anywhere,
        },
        rewards: RewardParams {
            contact: 1.0,
            thrust_cost: 0.01,
            turn_cost: 0.1,
            wall_penalty: 0.0,
            wall_penalty_mode: WallPenaltyMode::AnyWall,
            contacts_judged: ContactJudging::AfterMove,
        },
        species: vec![
            species("predator", 3, 0.06, [0.96, 0.55, 0.15], &["prey"], Policy::Learned),
            species("prey", 10, 0.035, [0.2, 0.45, 0.9], &[], Policy::Learned),
        ],
        learning: LearningParams {
            hidden: 64,
            actor_lr: 1e-4,
            critic_lr: 1e-3,
            gamma: 0.95,
            tau: 0.01,
            batch_size: 256,
            buffer_capacity: 500_000,
            updates_per_episode: 30,
            updates_per_step: 0,
            warmup_transitions: 256,
            noise_std: 0.1,
            epsilon: 0.1,
            exploration_decay: 5e-5,
            exploration_floor: 0.05,
            checkpoint_every: 100,
            snapshot_every: default_snapshot_every(),
            replay_window: ReplayWindow::Latest,
            stored_action: StoredAction::Normalized,
            noise_draw: NoiseDraw::PerIndividual,
            batch_draw: BatchDraw::WithReplacement,
            opponents: vec![],
        },
        observation_frame: ObservationFrame::World,
        observation_layout: ObservationLayout::Paper,
        cluster_link: default_cluster_link(),
        confusion_radius: None,
        contact_rewards: vec![],
        authors_metrics: false,
    }
}

/// The `gym-pps` preset: the authors' code as it runs (parameters.md, "gym-pps preset").
pub(super) fn gym_pps() -> Scene {
    let mut s = paper();
    s.preset = "gym-pps".into();
    s.world.wall_stiffness = 100.0;
    s.world.wall_damping = 5.0;
    s.world.speed_clip = SpeedClip::PerComponent;
    s.world.energy_budget = true;
    s.rewards = RewardParams {
        contact: 5.0,
        thrust_cost: 0.0,
        // −|Δθ| with Δθ = a_R·Δt in rad per step is −0.1·|a_R| with a_R in rad/s.
        turn_cost: 0.1,
        wall_penalty: 0.0,
        wall_penalty_mode: WallPenaltyMode::PerWall,
        contacts_judged: ContactJudging::BeforeMove,
    };
    for sp in &mut s.species {
        // 0.5 rad per step at Δt = 0.1 s.
        sp.max_turn_rate = 5.0;
    }
    s.species[0].mass = 3.0;
    s
}
