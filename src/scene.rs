//! Scenes: the whole configuration of a run, as RON files under `scenes/`.
//!
//! A scene names a **preset** (`paper` or `gym-pps`, see `../shared/reference/parameters.md` and the
//! README) and overrides any field of it. Every struct here exists twice: the resolved value the simulation
//! reads ([`Scene`], [`WorldParams`], [`RewardParams`], [`SpeciesDef`], [`LearningParams`]) and a patch with every field
//! optional, which is what a scene file holds. Species are patched by `name`; a name the preset does not
//! know adds a new species and must then give every field.
//!
//! Every error is one line naming the file, the line when it is known, and the field.

use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::Path;

/// Declares a resolved config struct and its patch (every field optional) with `apply` between them,
/// so a field is written once.
macro_rules! patchable {
    ($(#[$meta:meta])* pub struct $name:ident / $patch:ident {
        $( $(#[doc = $doc:literal])* pub $field:ident : $ty:ty, )*
    }) => {
        $(#[$meta])*
        #[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
        #[serde(deny_unknown_fields)]
        pub struct $name { $( $(#[doc = $doc])* pub $field: $ty, )* }

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
    /// Trained by the learning plugin (Algorithm 1).
    Learned,
    /// A trained actor loaded from a checkpoint folder, no updates.
    Frozen(String),
    /// Decided by your own plugin: a system in `SimSet::Decide` that writes this species' rows of the action
    /// batch (see `tests/species_plugin.rs`).
    Plugin(String),
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
    }
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
    }
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

fn default_cluster_link() -> f64 {
    crate::sim::metrics::DEFAULT_CLUSTER_LINK
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
    /// alignment must come from interaction (not in the paper; see README "Observation frames").
    Body,
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
    pub cluster_link: Option<f64>,
    #[serde(default)]
    pub confusion_radius: Option<f64>,
    /// Replaces the list of per-pair contact rewards.
    #[serde(default)]
    pub contact_rewards: Option<Vec<ContactReward>>,
}

/// Reads RON text of a coevo file (a scene, an experiment) into `T`, with `Some` implied for optional
/// fields, and errors in a user's words: `file:line: field: message`.
pub fn parse_ron<T: serde::de::DeserializeOwned>(text: &str, file: &str) -> Result<T, SceneError> {
    ron::Options::default().with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME).from_str(text).map_err(|e| {
        SceneError {
            file: file.to_string(),
            line: Some(e.span.start.line),
            field: match &e.code {
                ron::Error::NoSuchStructField { found, .. } => found.clone(),
                _ => field_before(text, e.span.start.line, e.span.start.col),
            },
            message: readable(text, &e),
        }
    })
}

/// The largest scene file read (a real one is a few hundred bytes).
pub const MAX_SCENE_BYTES: u64 = 1 << 20;

/// The names `preset:` accepts.
pub const PRESETS: [&str; 2] = ["paper", "gym-pps"];

/// One clear error line: `file:line: field: message`.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneError {
    pub file: String,
    pub line: Option<usize>,
    pub field: String,
    pub message: String,
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if !self.field.is_empty() {
            write!(f, ": {}", self.field)?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for SceneError {}

impl Scene {
    /// A preset by name (`paper` or `gym-pps`).
    pub fn preset(name: &str) -> Option<Scene> {
        match name {
            "paper" => Some(paper_preset()),
            "gym-pps" => Some(gym_pps_preset()),
            _ => None,
        }
    }

    /// Loads, resolves and validates a scene file.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let file = path.display().to_string();
        let text = crate::io::read_text(path, MAX_SCENE_BYTES).map_err(|e| SceneError {
            file: file.clone(),
            line: None,
            field: String::new(),
            message: e.replace("cannot read:", "cannot read scene:"),
        })?;
        Scene::parse(&text, &file)
    }

    /// Parses, resolves and validates scene text; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<Scene, SceneError> {
        Scene::parse_with_preset(text, file, None)
    }

    /// [`Scene::parse`], on `preset` instead of the one the text names (experiments switch a sweep's base
    /// between the `paper` and `gym-pps` presets).
    pub fn parse_with_preset(text: &str, file: &str, preset: Option<&str>) -> Result<Scene, SceneError> {
        let patch: ScenePatch = parse_ron(text, file)?;
        let located = |field: String, message: String| SceneError { file: file.to_string(), line: locate(text, &field), field, message };
        let preset_name = preset.map(str::to_string).or_else(|| patch.preset.clone()).unwrap_or_else(|| "paper".to_string());
        let mut scene = Scene::preset(&preset_name).ok_or_else(|| {
            located("preset".into(), format!("unknown preset {preset_name:?} (known: {})", PRESETS.join(", ")))
        })?;
        scene.apply(patch).map_err(|(field, message)| located(field, message))?;
        scene.validate().map_err(|(field, message)| located(field, message))?;
        Ok(scene)
    }

    /// Applies a scene patch (an experiment's variant) and validates the result. Err is (field, message).
    pub fn patched(&self, patch: ScenePatch) -> Result<Scene, (String, String)> {
        let mut scene = self.clone();
        scene.apply(patch)?;
        scene.validate()?;
        Ok(scene)
    }

    /// Applies a patch; a new species must give every field.
    fn apply(&mut self, patch: ScenePatch) -> Result<(), (String, String)> {
        if let Some(v) = patch.seed {
            self.seed = v;
        }
        if let Some(v) = patch.episode_steps {
            self.episode_steps = v;
        }
        if let Some(v) = patch.episodes {
            self.episodes = v;
        }
        if let Some(v) = patch.observation_frame {
            self.observation_frame = v;
        }
        if let Some(v) = patch.cluster_link {
            self.cluster_link = v;
        }
        if let Some(v) = patch.confusion_radius {
            self.confusion_radius = Some(v);
        }
        if let Some(v) = patch.contact_rewards {
            self.contact_rewards = v;
        }
        if let Some(p) = patch.world {
            p.apply(&mut self.world);
        }
        if let Some(p) = patch.rewards {
            p.apply(&mut self.rewards);
        }
        if let Some(p) = patch.learning {
            p.apply(&mut self.learning);
        }
        let mut seen = std::collections::BTreeSet::new();
        for (i, sp) in patch.species.unwrap_or_default().into_iter().enumerate() {
            let Some(name) = sp.name.clone() else {
                return Err((format!("species[{i}].name"), "every species entry needs a name".into()));
            };
            if !seen.insert(name.clone()) {
                return Err((
                    format!("species[{name}]"),
                    "appears twice in this scene; give each species one entry".into(),
                ));
            }
            if let Some(existing) = self.species.iter_mut().find(|s| s.name == name) {
                sp.apply(existing);
            } else if let Some(t) = crate::sim::species::catalog::get(&name) {
                // A species a plugin of this program defines: its defaults, then the scene's fields.
                let mut def = t.def.clone();
                sp.apply(&mut def);
                self.species.push(def);
                for catcher in &t.caught_by {
                    if let Some(c) = self.species.iter_mut().find(|s| &s.name == catcher) {
                        if !c.catches.contains(&name) {
                            c.catches.push(name.clone());
                        }
                    }
                }
                for r in &t.contact_rewards {
                    let present = |n: &str| self.species.iter().any(|s| s.name == n);
                    let set = self.contact_rewards.iter().any(|c| c.catcher == r.catcher && c.caught == r.caught);
                    if !set && present(&r.catcher) && present(&r.caught) {
                        self.contact_rewards.push(r.clone());
                    }
                }
            } else {
                let mut def = SpeciesDef::template(&name);
                let missing = sp.missing_fields();
                if !missing.is_empty() {
                    return Err((
                        format!("species[{name}]"),
                        format!(
                            "no preset or species plugin of this program defines {name:?}; a new species must set: {}",
                            missing.join(", ")
                        ),
                    ));
                }
                sp.apply(&mut def);
                self.species.push(def);
            }
        }
        Ok(())
    }

    /// Checks every value the physics or learning would choke on. Err is (field path, message).
    pub fn validate(&self) -> Result<(), (String, String)> {
        fn check(ok: bool, field: &str, message: impl FnOnce() -> String) -> Result<(), (String, String)> {
            if ok {
                Ok(())
            } else {
                Err((field.to_string(), message()))
            }
        }
        fn positive(v: f64, field: &str) -> Result<(), (String, String)> {
            check(v.is_finite() && v > 0.0, field, || format!("must be a finite number > 0 (got {v})"))
        }
        fn non_negative(v: f64, field: &str) -> Result<(), (String, String)> {
            check(v.is_finite() && v >= 0.0, field, || format!("must be a finite number ≥ 0 (got {v})"))
        }
        let w = &self.world;
        positive(self.cluster_link, "cluster_link")?;
        if let Some(r) = self.confusion_radius {
            positive(r, "confusion_radius")?;
        }
        positive(w.arena_edge, "world.arena_edge")?;
        positive(w.dt, "world.dt")?;
        non_negative(w.drag, "world.drag")?;
        non_negative(w.contact_stiffness, "world.contact_stiffness")?;
        non_negative(w.wall_stiffness, "world.wall_stiffness")?;
        non_negative(w.wall_damping, "world.wall_damping")?;
        let r = &self.rewards;
        for (v, f) in [
            (r.contact, "rewards.contact"),
            (r.thrust_cost, "rewards.thrust_cost"),
            (r.turn_cost, "rewards.turn_cost"),
            (r.wall_penalty, "rewards.wall_penalty"),
        ] {
            check(v.is_finite(), f, || format!("must be a finite number (got {v})"))?;
        }
        check(self.episode_steps > 0, "episode_steps", || "must be ≥ 1".into())?;
        check(self.episodes > 0, "episodes", || "must be ≥ 1".into())?;
        check(!self.species.is_empty(), "species", || "a scene needs at least one species".into())?;
        check(self.species.iter().any(|s| s.count > 0), "species", || {
            "every species has count 0: there would be no agent to simulate".into()
        })?;
        for (i, s) in self.species.iter().enumerate() {
            let f = |name: &str| format!("species[{}].{name}", s.name);
            check(!s.name.is_empty(), &format!("species[{i}].name"), || "must not be empty".into())?;
            // Names become CSV column names (dos_prey, catches_by_hawk) and file names (prey-actor.safetensors).
            check(
                s.name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-'),
                &format!("species[{i}].name"),
                || format!("{:?}: use letters, digits, _ and - only (it names CSV columns and checkpoint files)", s.name),
            )?;
            check(self.species.iter().filter(|o| o.name == s.name).count() == 1, &f("name"), || {
                format!("species name {:?} appears twice", s.name)
            })?;
            positive(s.mass, &f("mass"))?;
            positive(s.radius, &f("radius"))?;
            check(2.0 * s.radius < w.arena_edge, &f("radius"), || {
                format!("body diameter {} m does not fit in the arena of edge {} m", 2.0 * s.radius, w.arena_edge)
            })?;
            positive(s.max_speed, &f("max_speed"))?;
            non_negative(s.max_thrust, &f("max_thrust"))?;
            non_negative(s.max_turn_rate, &f("max_turn_rate"))?;
            match s.perception {
                Perception::Full => {}
                Perception::FractionOfD(x) => positive(x, &f("perception"))?,
                Perception::Radius(x) => positive(x, &f("perception"))?,
            }
            for c in &s.colour {
                check((0.0..=1.0).contains(c), &f("colour"), || format!("components must be in [0, 1] (got {c})"))?;
            }
            for target in &s.catches {
                check(self.species.iter().any(|o| &o.name == target), &f("catches"), || {
                    format!("no species named {target:?} in this scene")
                })?;
                check(target != &s.name, &f("catches"), || "a species cannot catch itself".into())?;
            }
        }
        for (i, r) in self.contact_rewards.iter().enumerate() {
            let field = format!("contact_rewards[{i}]");
            let catcher = self.species.iter().find(|s| s.name == r.catcher);
            check(catcher.is_some(), &field, || format!("no species named {:?} in this scene", r.catcher))?;
            check(self.species.iter().any(|s| s.name == r.caught), &field, || format!("no species named {:?} in this scene", r.caught))?;
            check(catcher.is_some_and(|c| c.catches.contains(&r.caught)), &field, || format!("{} does not catch {}", r.catcher, r.caught))?;
            check(r.catcher_reward.is_finite() && r.caught_reward.is_finite(), &field, || "rewards must be finite numbers".into())?;
            check(
                !self.contact_rewards[..i].iter().any(|o| o.catcher == r.catcher && o.caught == r.caught),
                &field,
                || format!("the pair {} → {} appears twice", r.catcher, r.caught),
            )?;
        }
        let l = &self.learning;
        positive(l.actor_lr, "learning.actor_lr")?;
        positive(l.critic_lr, "learning.critic_lr")?;
        check((0.0..=1.0).contains(&l.gamma), "learning.gamma", || format!("must be in [0, 1] (got {})", l.gamma))?;
        check(l.tau > 0.0 && l.tau <= 1.0, "learning.tau", || format!("must be in (0, 1] (got {})", l.tau))?;
        check(l.hidden > 0, "learning.hidden", || "must be ≥ 1".into())?;
        check(l.batch_size > 0, "learning.batch_size", || "must be ≥ 1".into())?;
        check(l.buffer_capacity >= l.batch_size, "learning.buffer_capacity", || {
            format!("must hold at least one batch ({} transitions)", l.batch_size)
        })?;
        for (v, f) in [
            (l.noise_std, "learning.noise_std"),
            (l.epsilon, "learning.epsilon"),
            (l.exploration_decay, "learning.exploration_decay"),
            (l.exploration_floor, "learning.exploration_floor"),
        ] {
            non_negative(v, f)?;
        }
        check(l.epsilon <= 1.0, "learning.epsilon", || format!("is a probability (got {})", l.epsilon))?;
        // The noise is added to actions in [−1, 1] and clamped back: beyond a few units it is all saturation.
        check(l.noise_std <= 10.0, "learning.noise_std", || {
            format!("must be ≤ 10 on actions in [−1, 1] (got {})", l.noise_std)
        })?;
        self.check_stability()?;
        self.check_memory(crate::io::memory_bytes())
    }

    /// Refuses parameters for which the semi-implicit Euler step of Appendix B is unstable or unphysical.
    /// With m the mass of a body and Δt the step:
    ///
    /// - drag: `(drag + wall damping)·Δt/m ≤ 1`, else one step reverses the velocity it damps;
    /// - contacts: `k·Δt²·(1/m_a + 1/m_b) < 4` for the two lightest bodies, the stability bound ωΔt < 2 of
    ///   the symplectic Euler step for a spring between them (the `paper` preset: 1);
    /// - walls: `k_wall·Δt²/m < 4` for the lightest body (a spring to a fixed wall);
    /// - travel: one step moves a body at most `max_speed·Δt` (×√2 when clipped per component), which must
    ///   stay under half the arena edge, as the torus wrap and minimum-image distances assume.
    fn check_stability(&self) -> Result<(), (String, String)> {
        let w = &self.world;
        let walls = w.boundary == Boundary::Walls;
        let damping = w.drag + if walls { w.wall_damping } else { 0.0 };
        let mut masses: Vec<(f64, &str)> = self.species.iter().map(|s| (s.mass, s.name.as_str())).collect();
        masses.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (lightest, name) = masses[0];
        let field = |f: &str| format!("species[{name}].{f}");
        let ratio = damping * w.dt / lightest;
        if ratio > 1.0 {
            let what = if walls { "(drag + wall_damping)·dt/mass" } else { "drag·dt/mass" };
            return Err((field("mass"), format!("{what} = {ratio} exceeds 1: a step would reverse velocities (lower world.drag or world.dt, or raise the mass)")));
        }
        // The two lightest bodies that can meet: the lightest twice if its species has two agents.
        let lightest_species = self.species.iter().filter(|s| s.mass == lightest).map(|s| s.count).sum::<usize>();
        let second = if lightest_species >= 2 || masses.len() < 2 { lightest } else { masses[1].0 };
        let spring = w.contact_stiffness * w.dt * w.dt * (1.0 / lightest + 1.0 / second);
        if spring >= 4.0 {
            return Err((
                "world.contact_stiffness".into(),
                format!("k·dt²·(1/m_a + 1/m_b) = {spring} for the lightest bodies ({name}) is ≥ 4: contacts would blow up (lower k or dt, or raise masses)"),
            ));
        }
        let wall = w.wall_stiffness * w.dt * w.dt / lightest;
        if walls && wall >= 4.0 {
            return Err((
                "world.wall_stiffness".into(),
                format!("k_wall·dt²/m = {wall} for {name} is ≥ 4: wall contacts would blow up (lower it or dt)"),
            ));
        }
        let per_component = if w.speed_clip == SpeedClip::PerComponent { std::f64::consts::SQRT_2 } else { 1.0 };
        for s in &self.species {
            let travel = s.max_speed * w.dt * per_component;
            if travel >= w.arena_edge / 2.0 {
                let message = format!(
                    "a body would move {travel} m in one step, not less than half the arena edge ({} m)",
                    w.arena_edge / 2.0
                );
                return Err((format!("species[{}].max_speed", s.name), message));
            }
        }
        Ok(())
    }

    /// Refuses a scene whose populations, observations or networks would need more than `limit` bytes,
    /// before anything is allocated. The estimate counts what grows with the scene: per agent its
    /// components and observation rows, per learned species its networks (online, target, Adam moments and
    /// the copies kept for saving) and its replay buffer (at most what a full run can fill).
    pub fn check_memory(&self, limit: f64) -> Result<(), (String, String)> {
        let registry = crate::sim::species::SpeciesRegistry::from_scene(self);
        let gb = |b: f64| format!("{:.1} GB", b / 1e9);
        let refuse = |field: String, what: String, bytes: f64| {
            Err((field, format!("{what} would need {}, more than the {} of memory coevo may use here (the least of free memory, the cgroup limit and ulimit -v)", gb(bytes), gb(limit))))
        };
        let mut total = 0.0;
        for (s, def) in self.species.iter().enumerate() {
            let n = def.count as f64;
            let d = registry.observation_dim(s) as f64;
            // Observations, the copy paired with the next step's, and an inference chunk's; ~512 B of
            // components and perception arrays per agent.
            let agents = n * (3.0 * d * 4.0 + 512.0);
            if agents > limit {
                let what = format!("{} agents with observations of {d} numbers (count, topological_limit)", def.count);
                return refuse(format!("species[{}]", def.name), what, agents);
            }
            total += agents;
            if matches!(def.policy, Policy::Learned | Policy::Frozen(_)) {
                let (h, l) = (self.learning.hidden as f64, &self.learning);
                let params = (d + 1.0) * h
                    + 2.0 * (h + 1.0) * h
                    + (h + 1.0) * 2.0
                    + (d + 3.0) * h
                    + 2.0 * (h + 1.0) * h
                    + h
                    + 1.0;
                let activations = l.batch_size as f64 * (2.0 * d + 8.0 * h) * 4.0 * 8.0;
                let nets = params * 4.0 * 10.0 + activations;
                if nets > limit {
                    let (field, what) = if activations > params * 40.0 {
                        ("learning.batch_size", format!("mini-batches of {} observations of {d} numbers", l.batch_size))
                    } else {
                        ("learning.hidden", format!("networks of width {} on {d} inputs", l.hidden))
                    };
                    return refuse(field.into(), what, nets);
                }
                let transitions = (l.buffer_capacity as f64).min(n * self.episode_steps as f64 * self.episodes as f64);
                let buffer = transitions * (2.0 * d + 3.0) * 4.0;
                if buffer > limit {
                    let what =
                        format!("a replay buffer of {transitions:.0} transitions of {d} numbers for {}", def.name);
                    return refuse("learning.buffer_capacity".into(), what, buffer);
                }
                total += nets + buffer;
            }
        }
        if total > limit {
            return refuse("species".into(), "this scene's agents, networks and replay buffers".into(), total);
        }
        Ok(())
    }

    /// D: the largest possible distance between two agents (√2·edge/2 on the torus, √2·edge with walls).
    pub fn max_distance(&self) -> f64 {
        max_distance(self.world.boundary, self.world.arena_edge)
    }

    /// The species with this name.
    pub fn species_named(&self, name: &str) -> Option<&SpeciesDef> {
        self.species.iter().find(|s| s.name == name)
    }

    /// Sets the count of a named species (for `--prey 50`-style overrides).
    pub fn set_count(&mut self, name: &str, count: usize) -> Result<(), String> {
        let s = self.species.iter_mut().find(|s| s.name == name).ok_or_else(|| format!("no species named {name:?}"))?;
        s.count = count;
        Ok(())
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

impl SpeciesDef {
    /// Placeholder values for a species a scene adds; `missing_fields` makes sure all are overwritten.
    fn template(name: &str) -> SpeciesDef {
        SpeciesDef {
            name: name.to_string(),
            count: 0,
            mass: 0.0,
            radius: 0.0,
            max_speed: 0.0,
            max_thrust: 0.0,
            max_turn_rate: 0.0,
            perception: Perception::Full,
            topological_limit: 0,
            colour: [0.0; 3],
            catches: vec![],
            policy: Policy::Still,
        }
    }
}

impl SpeciesPatch {
    fn missing_fields(&self) -> Vec<&'static str> {
        let mut m = vec![];
        macro_rules! need { ($($f:ident),*) => { $( if self.$f.is_none() { m.push(stringify!($f)); } )* } }
        need!(
            count,
            mass,
            radius,
            max_speed,
            max_thrust,
            max_turn_rate,
            perception,
            topological_limit,
            colour,
            catches,
            policy
        );
        m
    }
}

/// The `paper` preset: the paper's values, the authors' code's where the paper is silent.
fn paper_preset() -> Scene {
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
        },
        observation_frame: ObservationFrame::World,
        cluster_link: default_cluster_link(),
        confusion_radius: None,
        contact_rewards: vec![],
    }
}

/// The `gym-pps` preset: the authors' code as it runs (parameters.md, "gym-pps preset").
fn gym_pps_preset() -> Scene {
    let mut s = paper_preset();
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

/// Finds the line of a field path such as `species[prey].mass` or `world.drag` in scene text, so an
/// error can point at it; None when the value came from the preset.
fn locate(text: &str, field: &str) -> Option<usize> {
    let lines: Vec<&str> = text.lines().collect();
    let has_key = |line: &str, key: &str| {
        let code = line.split("//").next().unwrap_or("");
        code.match_indices(key).any(|(i, _)| {
            let before_ok = code[..i].chars().last().is_none_or(|c| !(c.is_alphanumeric() || c == '_'));
            let rest = code[i + key.len()..].trim_start();
            before_ok && rest.starts_with(':')
        })
    };
    let (mut from, mut key) = (0usize, field);
    if let Some(rest) = field.strip_prefix("species[") {
        let (name, tail) = rest.split_once(']')?;
        let quoted = format!("\"{name}\"");
        from = lines
            .iter()
            .position(|l| has_key(l, "name") && l.contains(&quoted))
            .or_else(|| name.parse::<usize>().ok().and_then(|_| lines.iter().position(|l| has_key(l, "species"))))?;
        key = tail.trim_start_matches('.');
        if key.is_empty() {
            return Some(from + 1);
        }
    } else if let Some((section, last)) = field.rsplit_once('.') {
        from = lines.iter().position(|l| has_key(l, section))?;
        key = last;
    }
    lines.iter().enumerate().skip(from).find(|(_, l)| has_key(l, key)).map(|(i, _)| i + 1)
}

/// The key whose value a parse error points into: the last `name:` before (line, col), 1-based.
fn field_before(text: &str, line: usize, col: usize) -> String {
    let mut before: Vec<&str> = text.lines().take(line).collect();
    if let Some(last) = before.last_mut() {
        *last = &last[..last.char_indices().nth(col.saturating_sub(1)).map_or(last.len(), |(i, _)| i)];
    }
    let joined = before.join("\n");
    let Some(colon) = joined.rfind(':') else {
        return String::new();
    };
    let key: String =
        joined[..colon].trim_end().chars().rev().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
    key.chars().rev().collect()
}

/// Whether brackets opened in `text` (outside strings and `//` comments) are left unclosed: a file cut
/// short, or a missing `)`.
fn unclosed(text: &str) -> bool {
    let mut depth = 0i64;
    for line in text.lines() {
        let mut in_string = false;
        let mut chars = line.chars().peekable();
        while let Some(c) = chars.next() {
            match c {
                '"' => in_string = !in_string,
                '\\' if in_string => {
                    chars.next();
                }
                '/' if !in_string && chars.peek() == Some(&'/') => break,
                '(' | '[' | '{' if !in_string => depth += 1,
                ')' | ']' | '}' if !in_string => depth -= 1,
                _ => {}
            }
        }
    }
    depth > 0
}

/// ron's message in a scene author's words: our patch types named as the sections they are, and the
/// common slips (a fraction where a whole number goes, a file cut short) said plainly.
fn readable(text: &str, e: &ron::error::SpannedError) -> String {
    let (line, col) = (e.span.start.line, e.span.start.col);
    let rest: String =
        text.lines().nth(line.saturating_sub(1)).unwrap_or("").chars().skip(col.saturating_sub(1)).collect();
    let before: String =
        text.lines().nth(line.saturating_sub(1)).unwrap_or("").chars().take(col.saturating_sub(1)).collect();
    let number_before = before.trim_end().chars().last().is_some_and(|c| c.is_ascii_digit());
    if number_before && (rest.starts_with('.') || rest.starts_with('e') || rest.starts_with('E')) {
        let whole: String = before
            .chars()
            .rev()
            .take_while(|c| c.is_ascii_digit() || *c == '-')
            .collect::<Vec<_>>()
            .into_iter()
            .rev()
            .collect();
        let frac: String =
            rest.chars().take_while(|c| c.is_ascii_digit() || matches!(c, '.' | 'e' | 'E' | '-' | '+')).collect();
        return format!("must be a whole number (got {whole}{frac})");
    }
    if matches!(e.code, ron::Error::Eof) || unclosed(text) {
        return "the file ends too early: a closing `)` or `]` is missing, or the file was cut short"
            .into();
    }
    [
        ("`ScenePatch`", "the scene"),
        ("`WorldParamsPatch`", "world"),
        ("`RewardParamsPatch`", "rewards"),
        ("`SpeciesPatch`", "a species"),
        ("`LearningParamsPatch`", "learning"),
    ]
    .iter()
    .fold(e.code.to_string(), |m, (from, to)| m.replace(from, to))
}
