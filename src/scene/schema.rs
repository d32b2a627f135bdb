//! The scene's schema: every field of a scene, resolved ([`Scene`]) and as a file holds it (the patches),
//! with the defaults and the few questions a scene answers about itself. Read, resolved and validated by
//! the sibling modules.

pub use super::classic::{CouzinRule, VicsekRule};
pub use super::rules::{BinnedRule, PursuitRule, ZonalRule};
use serde::{Deserialize, Serialize};

/// Declares a resolved config struct and its patch (every field optional) with `apply` between them,
/// so a field is written once.
macro_rules! patchable {
    ($(#[$meta:meta])* pub struct $name:ident / $patch:ident {
        $( $(#[$fmeta:meta])* pub $field:ident : $ty:ty, )*
    }) => {
        $(#[$meta])*
        #[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
        #[serde(deny_unknown_fields)]
        pub struct $name { $( $(#[$fmeta])* pub $field: $ty, )* }

        #[doc = concat!("A partial [`", stringify!($name), "`], as written in a scene file.")]
        #[derive(Clone, Debug, Default, Deserialize)]
        #[serde(deny_unknown_fields)]
        pub struct $patch { $( #[serde(default)] pub $field: Option<$ty>, )* }

        impl $patch {
            /// Overwrites the fields this patch sets.
            pub fn apply(self, to: &mut $name) { $( if let Some(v) = self.$field { to.$field = v; } )* }
        }
    };
}

/// The two boundary conditions of the paper (Section "Modeling").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Boundary {
    /// A torus: leaving one edge re-enters at the opposite one by the overshoot (Appendix B).
    Periodic,
    /// A square box whose walls push back with Hooke's law.
    Walls,
}

/// How the speed limit is enforced after the velocity update.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum SpeedClip {
    /// Rescale v so that ‖v‖ ≤ max speed (the paper).
    Norm,
    /// Clamp v_x and v_y each to [−max, max] (the authors' code).
    PerComponent,
}

/// When contacts are judged for the reward of the transition t → t+1.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum ContactJudging {
    /// On the state after the move, so an action is answered by its own consequence (the `paper` preset).
    AfterMove,
    /// On the positions before the move (the authors' code).
    BeforeMove,
}

/// How the wall penalty counts walls.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum WallPenaltyMode {
    /// One penalty while touching any wall (the paper: "−0.1 when contact ... happens").
    AnyWall,
    /// One penalty per wall touched, two in a corner (the authors' code).
    PerWall,
}

/// The perception radius R of a species (Section "Agent Observation").
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Perception {
    /// R = D, the largest possible distance in the arena (the paper's default).
    Full,
    /// R as a fraction of D, as the paper's perception experiments state it (2/3·D, 1/3·D).
    FractionOfD(f64),
    /// R in metres.
    Radius(f64),
}

/// What chooses a species' actions each step (the Decide set).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Policy {
    /// Uniformly random normalized actions.
    Random,
    /// No thrust, no turning.
    Still,
    /// The paper's rule-based predator: turn toward the nearest observed agent of a species it catches at
    /// the maximum turn rate, full thrust.
    ChaseNearest,
    /// Turn away from the nearest observed agent of a species that catches it, full thrust.
    FleeNearest,
    /// As `FleeNearest`, also steering off walls closer than [`FLEE_WALL_MARGIN`] (not in the paper), and
    /// braking while it faces away from where it should go: in a box, prey that flee straight away at full
    /// speed end pressed into walls and corners (their turning circle, v / max turn rate, is 1 m in the
    /// paper's 2 m box); these turn along and away from them. On the torus, and away from walls, it is
    /// `FleeNearest` exactly. The viewer's rule-based prey.
    FleeInside,
    /// A prey's zonal rule (repulsion, alignment, attraction, predator evasion), e.g. as `coevo --distill`
    /// fitted it to a trained run ([`ZonalRule`], `sim::rules`).
    Zonal(ZonalRule),
    /// A prey's rule additive over its neighbours with a gain per distance bin, as `coevo --distill` fits
    /// it in the `Binned` form ([`BinnedRule`], `sim::rules`).
    Binned(BinnedRule),
    /// A predator's pursuit of the nearest prey, the centre of the prey in view and the most isolated one
    /// ([`PursuitRule`], `sim::rules`).
    Pursuit(PursuitRule),
    /// Vicsek et al.'s model (PRL 1995): the mean heading within a radius, plus uniform noise
    /// ([`VicsekRule`], `sim::classic`).
    Vicsek(VicsekRule),
    /// Couzin et al.'s model (J. Theor. Biol. 2002): repulsion, orientation and attraction zones, plus
    /// Gaussian noise ([`CouzinRule`], `sim::classic`).
    Couzin(CouzinRule),
    /// Trained by the learning plugin (Algorithm 1).
    Learned,
    /// A trained actor loaded from a checkpoint folder, no updates.
    Frozen(String),
    /// Decided by your own plugin: a system in `SimSet::Decide` that writes this species' rows of the action
    /// batch (see `tests/species_plugin.rs`).
    Plugin(String),
}

/// How near a wall `FleeInside` starts to steer off it, in metres: beyond the ~0.25 m a prey at the paper's
/// top speed coasts while braking (drag 2 N·s/m on 1 kg).
pub const FLEE_WALL_MARGIN: f64 = 0.4;

/// Whether a field holds its default, so a scene file written by coevo leaves it out: a switch added
/// later (the authors' code's behaviours, docs/src/results/authors-code.md) changes neither the `scene.ron` of a run that leaves
/// it off nor the scene's identity its checkpoints are sealed with.
pub fn is_default<T: Default + PartialEq>(value: &T) -> bool {
    *value == T::default()
}

/// Where a population is spawned (difference 7 of the authors' code (docs/src/results/authors-code.md)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Spawn {
    /// Uniform over the arena (inset by each body's radius with walls), overlaps allowed: coevo's default.
    #[default]
    Anywhere,
    /// As WindyLab/Gym-PPS `gym/envs/pps/pps.py` `reset()`: every position uniform in the arena inset by
    /// the largest body radius of any species (±0.94 m for 0.06 m predators), on either boundary, the
    /// whole population drawn again until no two bodies overlap (at most 100 draws, the last kept), then
    /// the headings.
    AuthorsNoOverlap,
}

/// Which of a species' stored transitions a mini-batch is drawn from (difference 1 of the authors' code (docs/src/results/authors-code.md)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum ReplayWindow {
    /// The last `buffer_capacity` transitions, a ring (coevo's default; the paper's "5e5").
    #[default]
    Latest,
    /// As WindyLab/Gym-PPS `NJP_algorithm/utils/buffer.py`: rows for `buffer_capacity` × n transitions
    /// (n the species' count), written in turn and overwritten from the first when full, and mini-batches
    /// drawn only from the first `buffer_capacity` rows (rounded up to a multiple of n, as `filled_i`
    /// counts in steps of n). With 10 prey and 500 steps, prey learn from episodes 1–100 until episode
    /// 1000, then from 1001–1100; predators (n = 3) from 1–333, then 1001–1333.
    AuthorsFirstRows,
}

/// The action a transition stores (difference 2 of the authors' code (docs/src/results/authors-code.md)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum StoredAction {
    /// The normalized action the actor outputs (after noise), in [−1, 1], which is also what the critic
    /// is queried at: coevo's default.
    #[default]
    Normalized,
    /// As WindyLab/Gym-PPS: `env.step` (`gym/envs/pps/pps.py`) rescales the action array in place to
    /// physical units (turn × the maximum turn per step, thrust to [min, max] acceleration), and
    /// `NJP_algorithm/main.py` then stores that array, while the actor and target actor are still
    /// queried at normalized outputs.
    AuthorsRescaled,
}

/// How the Gaussian exploration noise is drawn (difference 3 of the authors' code (docs/src/results/authors-code.md)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum NoiseDraw {
    /// Independently for every individual and action component: coevo's default.
    #[default]
    PerIndividual,
    /// As WindyLab/Gym-PPS `NJP_algorithm/utils/agents.py` `step()`: one noise vector per species and
    /// step (`GaussianNoise.noise()` has the action's size), added to every individual's action.
    PerSpecies,
}

/// How a mini-batch is drawn from the transitions it may use (difference 8 of the authors' code (docs/src/results/authors-code.md)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum BatchDraw {
    /// Uniformly with replacement: coevo's default.
    #[default]
    WithReplacement,
    /// Uniformly without replacement, as WindyLab/Gym-PPS `NJP_algorithm/utils/buffer.py` `sample()`
    /// (`np.random.choice(..., replace=False)`); needs `warmup_transitions` ≥ `batch_size`.
    WithoutReplacement,
}

/// Who a learning species trains against (`experiments/league.ron`; not in the paper): `learning.opponents` names the
/// species that do not train against the latest opponents only.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub enum Opponents {
    /// The other species' current actors, every episode: Algorithm 1 as printed, coevo's default.
    #[default]
    Latest,
    /// With probability `p` an episode is played by snapshots of every other learning species kept
    /// earlier in the run (`snapshot_every`), drawn as `pick` says; they act without noise, and only this
    /// species stores transitions and updates in that episode (`learning::league`).
    Pool { p: f64, pick: Pick },
}

/// How a pool episode's snapshot is drawn from those kept so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Pick {
    /// Every kept snapshot equally likely (fictitious self-play).
    #[default]
    Uniform,
    /// By rank of the training species' mean return against each snapshot, worst first, weights n, n−1,
    /// …, 1 (snapshots not yet played rank first): prioritised fictitious self-play, as in AlphaStar's
    /// league (Vinyals et al. 2019), on ranks so the weights do not depend on the reward's scale.
    Prioritised,
}

patchable! {
    /// The physical world: Eq. (1), Appendix B and the environment table.
    pub struct WorldParams / WorldParamsPatch {
        /// Edge length of the square arena in metres; the arena is centred on the origin.
        pub arena_edge: f64,
        pub boundary: Boundary,
        /// Δt in seconds.
        pub dt: f64,
        /// Drag coefficient in N·s/m: f_d = −drag·v.
        pub drag: f64,
        /// Agent–agent contact stiffness in N/m (Hooke on the overlap).
        pub contact_stiffness: f64,
        /// Wall contact stiffness in N/m.
        pub wall_stiffness: f64,
        /// Wall damping in N·s/m on the velocity component normal to a penetrated wall.
        pub wall_damping: f64,
        pub speed_clip: SpeedClip,
        /// The authors' energy budget (1000 units, −|v| per step, +0.1 when resting): `gym-pps` only.
        pub energy_budget: bool,
        /// Where a population is spawned ([`Spawn`]; docs/src/results/authors-code.md): left out of scene files at its default.
        #[serde(default, skip_serializing_if = "is_default")]
        pub spawn: Spawn,
    }
}

patchable! {
    /// Per-agent rewards of the transition t → t+1 (Section "Rewards").
    pub struct RewardParams / RewardParamsPatch {
        /// +this per caught agent touched (predator), −this per catcher touching (prey).
        pub contact: f64,
        /// Energy cost per newton of thrust: −thrust_cost·|a_F|.
        pub thrust_cost: f64,
        /// Energy cost per rad/s of turn rate: −turn_cost·|a_R|.
        pub turn_cost: f64,
        /// Penalty for touching a wall (0 disables it).
        pub wall_penalty: f64,
        pub wall_penalty_mode: WallPenaltyMode,
        pub contacts_judged: ContactJudging,
    }
}

patchable! {
    /// One species: its body, its limits, what it perceives and what it catches.
    pub struct SpeciesDef / SpeciesPatch {
        pub name: String,
        /// Number of agents spawned each episode.
        pub count: usize,
        /// Mass in kg.
        pub mass: f64,
        /// Body radius in metres.
        pub radius: f64,
        /// Speed limit in m/s.
        pub max_speed: f64,
        /// a_F ∈ [0, max_thrust] in newtons.
        pub max_thrust: f64,
        /// a_R ∈ [−max_turn_rate, max_turn_rate] in rad/s.
        pub max_turn_rate: f64,
        pub perception: Perception,
        /// At most this many agents of each species are observed (the paper: 6).
        pub topological_limit: usize,
        /// sRGB in [0, 1]: the colour the viewer draws the species in.
        pub colour: [f32; 3],
        /// Names of the species this one catches on contact.
        pub catches: Vec<String>,
        pub policy: Policy,
        /// Names of species whose observation block this species never sees (not in the paper): the slots
        /// stay in the layout as zeros, so d_o and checkpoints are unchanged. `blind_to: ["prey"]` on the prey
        /// trains prey that cannot see each other, the control that separates flocking from herding.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        pub blind_to: Vec<String>,
        /// Perception per observed species (not in the paper): `[("predator", FractionOfD(0.0833))]` sees
        /// predators only within D/12 and every other species within `perception` (the "many eyes" condition).
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        pub perception_of: Vec<(String, Perception)>,
        /// Slots per observed species (not in the paper, which observes 6 of each): `[("predator", 2)]`
        /// observes at most 2 predators and `topological_limit` of every other species. With
        /// `topological_limit: 5` on both species it is the authors' code (WindyLab/Gym-PPS
        /// `NJP_algorithm/custom_param.json`: `topo_n_p2p` = `topo_n_e2p` = 2, `topo_n_p2e` = `topo_n_e2e` = 5;
        /// difference 4 of the authors' code (docs/src/results/authors-code.md)).
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        pub topological_limit_of: Vec<(String, usize)>,
        /// Field of view in degrees, in (0, 360] (not in the paper, whose agents see all around: 360). An
        /// agent in the blind sector behind, the 360 − `field_of_view` degrees centred on the direction
        /// opposite the heading, is not perceived: its slot goes to the next nearest agent in view, and the
        /// slots left over stay zero as for absent agents. Couzin et al. (J. Theor. Biol. 2002) call the
        /// field of perception α and use 270°. The boundary of the sector is in view.
        #[serde(default = "full_view", skip_serializing_if = "is_full_view")]
        pub field_of_view: f64,
        /// Field of view per observed species (not in the paper): `[("predator", 360.0)]` sees predators all
        /// around and every other species within `field_of_view`.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        pub field_of_view_of: Vec<(String, f64)>,
    }
}

/// The paper's field of view: all around.
pub const FULL_VIEW: f64 = 360.0;

fn full_view() -> f64 {
    FULL_VIEW
}

/// A field of view left out of scene files: all around, so scenes and runs written before the field
/// existed read and write as they did (and their checkpoints' scene identity stays the same).
fn is_full_view(degrees: &f64) -> bool {
    *degrees == FULL_VIEW
}

patchable! {
    /// Algorithm 1's hyper-parameters (Appendix B; the values of the authors' code where the paper is silent).
    pub struct LearningParams / LearningParamsPatch {
        /// Hidden layer width of actor and critic (three hidden layers).
        pub hidden: usize,
        pub actor_lr: f64,
        pub critic_lr: f64,
        /// Discount factor γ.
        pub gamma: f64,
        /// Soft target update rate τ.
        pub tau: f64,
        /// Mini-batch size S.
        pub batch_size: usize,
        /// Replay buffer capacity per species, in transitions.
        pub buffer_capacity: usize,
        /// Gradient steps per species after each episode (the authors' schedule); 0 disables.
        pub updates_per_episode: usize,
        /// Gradient steps per species after each environment step (Algorithm 1 as printed); 0 disables.
        pub updates_per_step: usize,
        /// No update before a buffer holds this many transitions.
        pub warmup_transitions: usize,
        /// Initial std of the Gaussian action noise, on the tanh output.
        pub noise_std: f64,
        /// Initial probability that a species acts uniformly at random for a step.
        pub epsilon: f64,
        /// σ and ε fall by this much per episode ...
        pub exploration_decay: f64,
        /// ... down to this floor.
        pub exploration_floor: f64,
        /// Save a checkpoint every this many episodes (and at the end).
        pub checkpoint_every: usize,
        /// Keep each learning species' actor before training and every this many episodes (and at the end)
        /// in `RUN/snapshots/`, for cross-play (`coevo --crossplay`); 0 keeps none. Not in the paper.
        #[serde(default = "default_snapshot_every")]
        pub snapshot_every: usize,
        /// The authors' code's learning details, each a switch left out of scene files at coevo's default
        /// (docs/src/results/authors-code.md; `scenes/gym-pps-code.ron` turns them all on): which transitions a mini-batch is
        /// drawn from ([`ReplayWindow`]), ...
        #[serde(default, skip_serializing_if = "is_default")]
        pub replay_window: ReplayWindow,
        /// ... the action a transition stores ([`StoredAction`]), ...
        #[serde(default, skip_serializing_if = "is_default")]
        pub stored_action: StoredAction,
        /// ... how exploration noise is drawn ([`NoiseDraw`]) ...
        #[serde(default, skip_serializing_if = "is_default")]
        pub noise_draw: NoiseDraw,
        /// ... and how a mini-batch is drawn ([`BatchDraw`]).
        #[serde(default, skip_serializing_if = "is_default")]
        pub batch_draw: BatchDraw,
        /// Who each named species trains against ([`Opponents`]; not in the paper): `[("predator",
        /// Pool(p: 0.5, pick: Uniform))]`. A species not named trains against the latest opponents.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        pub opponents: Vec<(String, Opponents)>,
    }
}

/// Snapshots every 100 episodes: 21 actors of ~50 KB per species in a standard run. Also the value of a
/// scene written before snapshots existed.
pub fn default_snapshot_every() -> usize {
    100
}

/// A fully resolved scene: what the simulation runs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    pub preset: String,
    pub seed: u64,
    /// Steps per episode (T).
    pub episode_steps: usize,
    /// Episodes of a training run (M).
    pub episodes: usize,
    pub world: WorldParams,
    pub rewards: RewardParams,
    pub species: Vec<SpeciesDef>,
    pub learning: LearningParams,
    /// The frame observations are written in (`World` in both presets; absent in older scene files).
    #[serde(default)]
    pub observation_frame: ObservationFrame,
    /// The order of an observation's parts ([`ObservationLayout`]); left out of scene files at the paper's.
    #[serde(default, skip_serializing_if = "is_default")]
    pub observation_layout: ObservationLayout,
    /// Agents of one species closer than this many body diameters (centre to centre) belong to one
    /// cluster, for the group-structure measures (not in the paper; absent in older scene files).
    #[serde(default = "default_cluster_link")]
    pub cluster_link: f64,
    /// Prey within this many metres of a predator count as "in view" for the confusion curve (None:
    /// the predator's perception radius; with `Full` perception every prey is in view, so a smaller
    /// radius is needed for a curve).
    #[serde(default)]
    pub confusion_radius: Option<f64>,
    /// Contact rewards of particular (catcher, caught) pairs; every other pair pays ±`rewards.contact`.
    #[serde(default)]
    pub contact_rewards: Vec<ContactReward>,
    /// Also log DoS and DoA as the authors' shipped code computes them (differences 9–11 of the authors' code (docs/src/results/authors-code.md); columns
    /// `authors_dos_<species>` and `authors_doa_<species>` of metrics.csv, beside the paper's, never
    /// replacing them): WindyLab/Gym-PPS `gym/wrappers/njp.py` `dos_and_doa` as `NJP_algorithm/main.py`
    /// calls it, over the states t = 0…T−1 (the spawn state included, the last state not), with plain
    /// Euclidean distances (no minimum image), D = √2 (the torus' D on its 2 m arena), and DoA's partner
    /// the agent k ≠ j that minimises ‖h_j + h_k‖ (the most opposed heading), not the nearest neighbour.
    /// Left out of scene files when off.
    #[serde(default, skip_serializing_if = "is_default")]
    pub authors_metrics: bool,
}

/// The reward of one contact between a catcher and a species it catches, for each side (a species plugin
/// brings these for its pairs; a scene may set or override them).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactReward {
    pub catcher: String,
    pub caught: String,
    /// Paid to the catcher per contact (the paper: +contact).
    pub catcher_reward: f64,
    /// Paid to the caught per contact (the paper: −contact).
    pub caught_reward: f64,
}

/// Body diameters within which two agents of a species belong to one cluster, unless the scene says.
pub const DEFAULT_CLUSTER_LINK: f64 = 2.0;

pub(super) fn default_cluster_link() -> f64 {
    DEFAULT_CLUSTER_LINK
}

/// The frame of an agent's observation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum ObservationFrame {
    /// The paper's: own absolute position, velocity and heading, neighbours' displacements and heading
    /// differences in world coordinates.
    #[default]
    World,
    /// Everything relative to the observer and rotated into its frame (forward, left): own forward and
    /// lateral speed, its last turn command, the nearest wall point; neighbours' displacements and
    /// headings. Nothing absolute, so no actor can steer every agent to one absolute heading: any
    /// alignment must come from interaction (not in the paper; see docs/src/results/observation-frames.md).
    Body,
}

/// The order of an observation's parts (difference 4 of the authors' code (docs/src/results/authors-code.md)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum ObservationLayout {
    /// The paper's (Section "Agent Observation"): own `[x, y, v_x, v_y, h_x, h_y]`, then the neighbour
    /// blocks of every species in registry order.
    #[default]
    Paper,
    /// As WindyLab/Gym-PPS `gym/envs/pps/pps.py` `_get_obs()` in its `Polar` dynamics: own `[x, y, v_x, v_y]`,
    /// the neighbour blocks, the energy input 2·E/E_max − 1 (+1 without `energy_budget`: never tired), then
    /// own `[h_x, h_y]`: d_o = 7 + 4·(slots), 35 with 2 + 5 slots. World frame only.
    Authors,
}

/// A scene file: a preset and what it overrides.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenePatch {
    #[serde(default)]
    pub preset: Option<String>,
    #[serde(default)]
    pub seed: Option<u64>,
    #[serde(default)]
    pub episode_steps: Option<usize>,
    #[serde(default)]
    pub episodes: Option<usize>,
    #[serde(default)]
    pub world: Option<WorldParamsPatch>,
    #[serde(default)]
    pub rewards: Option<RewardParamsPatch>,
    #[serde(default)]
    pub species: Option<Vec<SpeciesPatch>>,
    #[serde(default)]
    pub learning: Option<LearningParamsPatch>,
    #[serde(default)]
    pub observation_frame: Option<ObservationFrame>,
    #[serde(default)]
    pub observation_layout: Option<ObservationLayout>,
    #[serde(default)]
    pub cluster_link: Option<f64>,
    #[serde(default)]
    pub confusion_radius: Option<f64>,
    /// Replaces the list of per-pair contact rewards.
    #[serde(default)]
    pub contact_rewards: Option<Vec<ContactReward>>,
    #[serde(default)]
    pub authors_metrics: Option<bool>,
}

/// The largest scene file read (a real one is a few hundred bytes).
pub const MAX_SCENE_BYTES: u64 = 1 << 20;

/// The names `preset:` accepts.
pub const PRESETS: [&str; 2] = ["paper", "gym-pps"];

impl Scene {
    /// D: the largest possible distance between two agents (√2·edge/2 on the torus, √2·edge with walls).
    pub fn max_distance(&self) -> f64 {
        max_distance(self.world.boundary, self.world.arena_edge)
    }

    /// The species with this name.
    pub fn species_named(&self, name: &str) -> Option<&SpeciesDef> {
        self.species.iter().find(|s| s.name == name)
    }

    /// Sets the count of a named species (for `--prey 50`-style overrides).
    pub fn set_count(&mut self, name: &str, count: usize) -> crate::error::Result<()> {
        self.species_mut(name)?.count = count;
        Ok(())
    }

    /// Replaces a species' policy, e.g. learned predators by the paper's rule-based chase-nearest ones for
    /// an evaluation of prey against opponents they never trained with.
    pub fn set_policy(&mut self, name: &str, policy: Policy) -> crate::error::Result<()> {
        self.species_mut(name)?.policy = policy;
        Ok(())
    }

    fn species_mut(&mut self, name: &str) -> crate::error::Result<&mut SpeciesDef> {
        self.species.iter_mut().find(|s| s.name == name).ok_or_else(|| format!("no species named {name:?}").into())
    }

    /// The resolved scene as RON, loadable again as a scene file.
    pub fn to_ron(&self) -> String {
        let pretty = ron::ser::PrettyConfig::new().depth_limit(4).struct_names(false);
        ron::Options::default().to_string_pretty(self, pretty).expect("a Scene always serializes")
    }
}

/// D for a boundary kind and arena edge (Section "Results", definition of DoS).
pub fn max_distance(boundary: Boundary, edge: f64) -> f64 {
    match boundary {
        Boundary::Periodic => edge * std::f64::consts::SQRT_2 / 2.0,
        Boundary::Walls => edge * std::f64::consts::SQRT_2,
    }
}
