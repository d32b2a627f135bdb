//! An experiment file's schema (`experiments/*.ron`, described in the module above): what it declares
//! (variants, evaluations, claims), the runs it resolves to, and the names it derives (slugs, partners).
//! Read and validated by `load.rs`.

use crate::scene::{Overrides, Scene, ScenePatch};
use crate::sim::metrics::Swarming;
use serde::Deserialize;
use std::path::PathBuf;

/// An experiment file as written.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExperimentFile {
    #[serde(default)]
    pub(crate) description: String,
    /// The scene file every variant starts from.
    pub(crate) base: String,
    #[serde(default = "default_presets")]
    pub(crate) presets: Vec<String>,
    pub(crate) seeds: Vec<u64>,
    #[serde(default)]
    pub(crate) episodes: Option<usize>,
    #[serde(default)]
    pub(crate) variants: Vec<VariantFile>,
    /// A grid of variants over one or two axes (`grid.rs`): every combination of levels is a variant,
    /// after those listed in `variants`, named by its levels' labels joined by ", " ("D/12, 3:5"), trained
    /// at the file's seeds, evaluated and controlled like any other. Claims read it with `grid:`.
    #[serde(default)]
    pub(crate) grid: Vec<Axis>,
    #[serde(default)]
    pub(crate) evaluations: Vec<Evaluation>,
    #[serde(default)]
    pub claims: Vec<Claim>,
    /// The family of every claim that names none ([`Claim::family`]); without it, such claims are the
    /// file's own family.
    #[serde(default)]
    pub(crate) family: Option<String>,
    /// Compare runs made by different executables (`provenance.ron`'s `binary` and `also_by`) or on
    /// different families of matrix-product kernels (its `kernels`). Off by default: every number of an
    /// experiment comes from one binary on one family, and the runner and aggregation refuse otherwise.
    #[serde(default)]
    pub(crate) mixed_binaries: bool,
    /// No interim analysis: while some of its runs are not finished, reports show how many are, never an
    /// estimate, a verdict or a figure (a confirmatory experiment whose seeds were fixed beforehand). Its
    /// finished runs are still aggregated into `summary.csv` and `figure-data.ron.gz`, so that another
    /// machine carries them ([`super::carry`]), and such an experiment in progress is reported without
    /// `--partial`. Off by default: `--partial` reports the finished runs' numbers, marked partial.
    #[serde(default)]
    pub(crate) judged_when_complete: bool,
    /// Keep each run's replay buffers once it is trained (~0.25 GB a run of the standard scene), so that
    /// `coevo --resume RUN --episodes N` can extend it exactly as an uninterrupted longer run. Off by
    /// default: a finished run's buffers are removed (`store::replay_segments::drop_replay`), so a suite of
    /// 150 runs needs ~1 GB rather than ~70 GB.
    #[serde(default)]
    pub(crate) keep_replay: bool,
    /// Cross-play every run's snapshots (`coevo --crossplay`) after its evaluations, so claims can name
    /// its read-outs (`Crossplay("...")`).
    #[serde(default)]
    pub(crate) crossplay: Option<CrossplaySpec>,
    /// Fit rules to every run's trained actors (`coevo --distill`) before its evaluations, for the
    /// evaluations that deploy them (`distilled:`).
    #[serde(default)]
    pub(crate) distill: Option<DistillSpec>,
}

/// How an experiment fits its runs' rules (`coevo --distill`): the actors deployed at these counts for
/// `episodes` episodes of `steps` steps, the first half fitted, the rest held out.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub(crate) struct DistillSpec {
    #[serde(default)]
    pub(crate) counts: Vec<(String, usize)>,
    #[serde(default = "distill_episodes")]
    pub(crate) episodes: usize,
    #[serde(default)]
    pub(crate) steps: Option<usize>,
    /// The forms whose numbers the experiment reads and reports, and whose rules its evaluations may
    /// deploy (`--distill` fits every form it can). Default: the zonal rule's two.
    #[serde(default = "distill_forms")]
    pub(crate) forms: Vec<crate::scene::RuleForm>,
}

fn distill_episodes() -> usize {
    crate::claims::distill::EPISODES
}

fn distill_forms() -> Vec<crate::scene::RuleForm> {
    vec![crate::scene::RuleForm::Memoryless, crate::scene::RuleForm::Inertial]
}

impl DistillSpec {
    /// What the fit changes of a run's scene.
    pub(crate) fn overrides(&self) -> Overrides {
        Overrides { counts: self.counts.clone(), episode_steps: self.steps, ..Default::default() }
    }
}

/// A species an evaluation deploys as the rule fitted to it (`distilled.ron`), optionally without some of
/// a zonal rule's terms (an ablation: `without: [Alignment]`).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub(crate) struct DistilledUse {
    pub(crate) species: String,
    /// The rule fitted without (`Memoryless`, the default) or with (`Inertial`) the agent's own state.
    #[serde(default)]
    pub(crate) form: crate::scene::RuleForm,
    #[serde(default)]
    pub(crate) without: Vec<crate::scene::ZonalTerm>,
}

/// How an experiment cross-plays its runs.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub(crate) struct CrossplaySpec {
    /// Episodes per cell.
    #[serde(default = "five")]
    pub(crate) episodes: usize,
}

fn five() -> usize {
    5
}

fn default_presets() -> Vec<String> {
    vec!["paper".into()]
}

/// A named change of the base scene.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct VariantFile {
    pub(crate) name: String,
    #[serde(default)]
    pub(crate) patch: ScenePatch,
    /// `"EXPERIMENT/VARIANT"`: this variant's runs are that experiment's runs (same preset and seed, the
    /// same resolved scene, checked), not trained or copied again: a shared run is one training, counted
    /// once, and never compared with itself.
    #[serde(default)]
    pub(crate) shared_from: Option<String>,
    /// `"EXPERIMENT/VARIANT"`: this variant's runs were trained again in its own folders and are that
    /// variant's trainings (same preset, seed and resolved scene, checked; by the same binary, a
    /// deterministic re-training), declared so: one training, counted once in the suite's totals. A
    /// training found twice without this or `shared_from` is refused when results are aggregated
    /// ([`super::trainings`]). For runs made before their evaluations could differ from their owner's
    /// (body-frame's); a new file shares the runs instead.
    #[serde(default)]
    pub(crate) same_training_as: Option<String>,
    /// The family of matrix-product kernels this variant's runs use instead of the experiment's (the pin's
    /// or this machine's), e.g. `kernels: Some("avx512-bf16")` beside variants on `avx512`: a comparison of
    /// kernel families, one binary (`--kernels` names them). Every run on a family other than its own is
    /// refused when results are aggregated.
    #[serde(default)]
    pub(crate) kernels: Option<crate::learning::nets::Kernels>,
    /// A grid's cell (`grid.rs`): its level on each axis, by index into the axis's levels, in the file's
    /// order of axes (their patches apply after `patch`); empty for a listed variant.
    #[serde(skip)]
    pub(crate) cell: Vec<usize>,
}

/// One axis of an experiment's grid: a scene number and its values (`path`, `values`), or levels each
/// with its own patch (`levels`), for what one number of one field does not say (the prey's perception
/// of predators as a fraction of D, a speed ratio made by slowing the slower species).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Axis {
    /// The axis in claims and figures, e.g. "speed ratio predator:prey".
    pub(crate) name: String,
    /// A number of the scene by its path as a scene file writes it: `"episode_steps"`, `"world.dt"`,
    /// `"species.prey.max_speed"` (a species by its name).
    #[serde(default)]
    pub(crate) path: Option<String>,
    /// The values `path` takes, one level each, labelled by the value as written.
    #[serde(default)]
    pub(crate) values: Vec<f64>,
    /// Levels each with a label and a patch (instead of `path` and `values`). After loading, every axis
    /// holds its levels here.
    #[serde(default)]
    pub(crate) levels: Vec<Level>,
}

/// One level of a grid's axis.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Level {
    /// Names the level in the cell's variant name, in claims (`at:`) and on the figures' axes.
    pub(crate) label: String,
    /// Its position on the axis: the x of trends and boundaries, on the scale the file chooses (e.g.
    /// log2 of a ratio, so that 3:5 and 5:3 lie as far from 1:1). Levels are listed in increasing value.
    pub(crate) value: f64,
    #[serde(default)]
    pub(crate) patch: ScenePatch,
}

/// A claim over a grid (`grid.rs` tests it): its quantity read on every run of the cells along `axis`,
/// the other axis (when the grid has two) held at the level labelled `at`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
pub(crate) enum GridTest {
    /// The trend along `axis`: the least-squares slope of the runs' values on the levels' values, each run
    /// one observation (seeds are the replicates), with HC3 standard errors and n − 2 degrees of freedom,
    /// tested as any effect (two-sided, for a direction, or for equivalence within `margin`).
    Trend {
        axis: String,
        #[serde(default)]
        at: Option<String>,
    },
    /// Where along `axis` the mean over seeds first falls through `crosses` (or rises through it, or
    /// either, as `direction` says; linear between neighbouring levels), with a bootstrap interval over
    /// seeds; tested against "no such crossing within the axis".
    Boundary {
        axis: String,
        crosses: f64,
        #[serde(default)]
        at: Option<String>,
        #[serde(default)]
        direction: Crossing,
    },
    /// How that boundary moves with the other axis: the least-squares slope of its position on the other
    /// axis's values, with a bootstrap interval over seeds; tested two-sided.
    BoundaryShift {
        axis: String,
        crosses: f64,
        #[serde(default)]
        direction: Crossing,
    },
}

/// Which way a boundary's quantity passes its value, going along the axis (up its values).
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
pub(crate) enum Crossing {
    /// From at or above the value to below it (a share that falls away), the default.
    #[default]
    Falls,
    /// From at or below it to above it.
    Rises,
    /// Either way.
    Either,
}
/// How the trained policies of every run are deployed (`coevo --eval`): species counts, episodes and
/// steps; its per-step DoS/DoA land in `eval-<name>.csv`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub(crate) struct Evaluation {
    pub(crate) name: String,
    /// Species counts for the evaluation, e.g. `[("prey", 50), ("predator", 0)]`.
    #[serde(default)]
    pub(crate) counts: Vec<(String, usize)>,
    #[serde(default = "three")]
    pub(crate) episodes: usize,
    /// Steps per episode (default: the scene's).
    #[serde(default)]
    pub(crate) steps: Option<usize>,
    /// What the actors see (`learning::control`): `Blind`, `Shuffled`, a block form such as
    /// `"blind:prey:prey"`, or a list of block forms (default: seeing).
    #[serde(default)]
    pub(crate) control: crate::learning::control::ObservationControl,
    /// Radius (m) of "prey in view" for the confusion curve (default: the scene's).
    #[serde(default)]
    pub(crate) confusion_radius: Option<f64>,
    /// The arena's edge (m) for the evaluation (default: the run's): a larger group at the density of a
    /// smaller one, as a group-size series keeps it.
    #[serde(default)]
    pub(crate) arena_edge: Option<f64>,
    /// Deploy the actors as initialised before training (`coevo --eval --untrained`): the start against
    /// which [`Quantity::Learned`] measures what training changed.
    #[serde(default)]
    pub(crate) untrained: bool,
    /// Also turn one prey of a twin world by this many radians (`coevo --eval --perturb`) after
    /// `perturb_step` (default: half the episode), for [`Quantity::Response`].
    #[serde(default)]
    pub(crate) perturb: Option<f64>,
    #[serde(default)]
    pub(crate) perturb_step: Option<usize>,
    /// Species whose policy the evaluation replaces, e.g. `[("predator", ChaseNearest)]`: trained prey
    /// against the paper's rule-based predators (`coevo --eval --policy`).
    #[serde(default)]
    pub(crate) policies: Vec<(String, crate::scene::Policy)>,
    /// Species the evaluation deploys as the rules fitted to the run's actors (needs `distill:` in the
    /// file): e.g. `[(species: "prey")]`, the learned prey replaced by their zonal rule.
    #[serde(default)]
    pub(crate) distilled: Vec<DistilledUse>,
}

impl Evaluation {
    /// What the evaluation changes of a run's scene.
    pub(crate) fn overrides(&self) -> Overrides {
        Overrides {
            counts: self.counts.clone(),
            policies: self.policies.clone(),
            seed: None,
            episode_steps: self.steps,
            confusion_radius: self.confusion_radius,
            arena_edge: self.arena_edge,
        }
    }
}

fn three() -> usize {
    3
}

/// One quantitative statement of the paper this experiment tests, for REPRODUCTION.md.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Claim {
    /// The paper's words.
    pub text: String,
    /// The variant the claim reads; empty for a claim over the grid (`grid`).
    #[serde(default)]
    pub(crate) variant: String,
    pub quantity: Quantity,
    /// The paper's number, when it gives one.
    #[serde(default)]
    pub(crate) paper: Option<f64>,
    /// Compare with this variant: the claim's number becomes `variant`'s mean minus this variant's, with
    /// Welch's 95 % interval (e.g. an ablation variant against the base it changes one thing of).
    #[serde(default)]
    pub(crate) versus: Option<String>,
    /// For a claim of no effect ("unchanged", "flat"): the margin m of the equivalence test (TOST): the
    /// claim is reproduced when the effect's 90 % interval lies inside (−m, m).
    #[serde(default)]
    pub(crate) margin: Option<f64>,
    /// For a level with the paper's value: the tolerance t, in the quantity's units, within which it is
    /// reproduced (TOST: the 90 % interval inside paper ± t). DoS and DoA levels take the project's rule
    /// (`verdict::DOS_TOLERANCE`, `verdict::DOA_TOLERANCE`) when none is given; another level must give one.
    #[serde(default)]
    pub(crate) tolerance: Option<f64>,
    /// For a level: the value that chance alone gives, which the level must be told apart from (DoA's
    /// 2/π and DoS at random positions are filled in when not given).
    #[serde(default)]
    pub(crate) baseline: Option<f64>,
    /// The paper states only the direction of this effect (e.g. "faster convergence"): `paper` then gives
    /// its sign (+1 or −1), never a size the interval could exclude.
    #[serde(default)]
    pub(crate) direction_only: bool,
    /// The direction is the project's own hypothesis, for a question the paper does not ask (e.g.
    /// `league.ron`'s "the pool lowers predator regress"), not the paper's: reports show no paper's value
    /// and judge it *detected as hypothesised*, *detected opposite to the hypothesis* or *inconclusive*,
    /// never *reproduced*. Only with `direction_only`. Who states the direction does not change the test,
    /// so the claim's fingerprint (`registry.rs`) leaves this out.
    #[serde(default)]
    pub(crate) ours: bool,
    /// The family whose tests are adjusted together (Holm), fixed with the hypothesis. A family is named
    /// by its hypotheses, not by its file: every claim of that name in the files of `experiments/` is one
    /// family (the project's are "the paper's claims", "mechanism and controls", "exploratory", and the
    /// pre-registered confirmatory ones). Without a name, the file's `family`; without that, the claim is
    /// in its own file's family. Resolved when the file is loaded, so after loading None means the file's.
    #[serde(default)]
    pub(crate) family: Option<String>,
    /// The scale the test reads its samples on, fixed with the hypothesis: `Linear` (the default, the
    /// quantity as it is) or `Log1p`, ln(1 + x) of each run's value, for counts whose seeds spread over
    /// orders of magnitude (catches: a few seeds far above the rest make Welch's interval on the raw counts
    /// wide enough to hold zero even when every seed of one arm lies above every seed of the other). On
    /// `Log1p` a difference of two arms is the log of the ratio of their geometric means of 1 + x. Only for
    /// effects; the paper's value, when given, is on the same scale.
    #[serde(default, skip_serializing_if = "crate::scene::is_default")]
    pub(crate) scale: Scale,
    /// A claim over the file's grid rather than one variant: a trend, a boundary or its shift.
    #[serde(default)]
    pub(crate) grid: Option<GridTest>,
    /// Stated after the first committed per-run row it judges (or not provably before it): reported, marked
    /// *exploratory*, never counted as a confirmation. Without it such a claim is refused when its
    /// experiment is aggregated (`registration.rs`). When it was stated does not change the test, so the
    /// claim's fingerprint leaves this out.
    #[serde(default)]
    pub(crate) exploratory: bool,
}

impl Claim {
    /// A claim of `quantity` on `variant` with every other field at its default: no paper's value, no
    /// contrast, margin or baseline, a two-sided test on the linear scale in its file's family.
    pub(crate) fn of(text: &str, variant: &str, quantity: Quantity) -> Claim {
        Claim {
            text: text.into(),
            variant: variant.into(),
            quantity,
            paper: None,
            versus: None,
            margin: None,
            tolerance: None,
            baseline: None,
            direction_only: false,
            ours: false,
            family: None,
            scale: Scale::Linear,
            grid: None,
            exploratory: false,
        }
    }
}

/// The scale a claim's test reads ([`Claim::scale`]).
#[derive(Clone, Copy, Debug, Default, Deserialize, serde::Serialize, PartialEq, Eq)]
pub(crate) enum Scale {
    #[default]
    Linear,
    /// ln(1 + x) of each run's value.
    Log1p,
}

impl Scale {
    /// A run's value on this scale: NaN (no sample) where ln(1 + x) is not defined.
    pub(crate) fn of(self, x: f64) -> f64 {
        match self {
            Scale::Linear => x,
            Scale::Log1p if x > -1.0 => x.ln_1p(),
            Scale::Log1p => f64::NAN,
        }
    }
}

/// A number the aggregate computes per run (prey, or the experiment's headline species).
#[derive(Clone, Debug, Deserialize, PartialEq)]
pub enum Quantity {
    /// Mean of the first / last 100 episodes of training.
    DosFirst,
    DosLast,
    DoaFirst,
    DoaLast,
    /// Last 100 minus first 100 (the paper's "falls from … to …").
    DosChange,
    DoaChange,
    /// Catches per episode (every predator–prey contact that began), last 100 minus first 100: whether
    /// the prey learned to escape faster than the predators learned to catch.
    CatchesChange,
    /// Catches per episode over the first / last 100 episodes of training: how well the prey survive.
    CatchesFirst,
    CatchesLast,
    /// Another per-episode order parameter of training (`polarization`, `milling`, `clusters`,
    /// `largest_cluster`, `nn_correlation`, `edge_rank`, or the shipped code's `authors_dos` and
    /// `authors_doa` in runs with `authors_metrics`): mean of the first / last 100 episodes.
    TrainingFirst(Order),
    TrainingLast(Order),
    /// The evaluation's mean over its last 50 steps (the trained policies' settled state).
    EvalDos(String),
    EvalDoa(String),
    /// The same for another order parameter of the evaluation: `polarization`, `milling`, `clusters`,
    /// `largest_cluster`, `nn_correlation`; or `edge_rank`, the mean edge rank of every prey caught in it.
    EvalOrder(String, Order),
    /// Catches per prey (the headline species) per episode in the evaluation, over its whole episodes:
    /// every predator–prey contact that began, divided by the episodes and the prey deployed (group-size
    /// series compare groups of different sizes by it). A column of `summary.csv` only in experiments
    /// whose claims read it.
    EvalCatches(String),
    /// The interaction-driven part of the alignment: DoA of the seeing evaluation with the same counts,
    /// episodes and steps, minus DoA of this control evaluation (blind or shuffled), per run.
    InteractionDoa(String),
    /// The same for another order parameter (as [`Quantity::EvalOrder`] names them), e.g.
    /// `Interaction("50 prey, blind to prey", "nn_correlation")`: seeing minus the control, per run.
    Interaction(String, Order),
    /// What training changed: an order parameter (`dos`, `doa` or as [`Quantity::EvalOrder`]) in an
    /// evaluation of the trained actors minus the same evaluation of the untrained ones (same counts,
    /// episodes, steps and control, `untrained: true`), per run.
    Learned(String, Order),
    /// An order parameter (`dos`, `doa` or as [`Quantity::EvalOrder`]) in one evaluation minus the same in
    /// another of the same run, per run (paired): e.g. `EvalDifference("50 prey, distilled prey", "50 prey",
    /// "doa")`, what replacing the learned prey by their distilled rule changes.
    EvalDifference(String, String, Order),
    /// A number of the rule `coevo --distill` fitted to one species of the run (`distilled.ron`; needs
    /// `distill:` in the file): a parameter of its policy by field name (`turn.alignment`,
    /// `repulsion_radius`, `persistence`, ...) or how much it explains on the held-out episodes
    /// (`explained_thrust`, `explained_turn`), e.g. `Distilled("prey", Memoryless, "turn.alignment")`.
    Distilled(String, crate::scene::RuleForm, String),
    /// A number of [`Quantity::Distilled`] in one form minus the same in another, per run (paired): e.g.
    /// `DistilledDifference("prey", Binned, Memoryless, "explained_turn")`, how much more of the turn's
    /// held-out variance the binned rule explains than the zonal one.
    DistilledDifference(String, crate::scene::RuleForm, crate::scene::RuleForm, String),
    /// The episode at which the 100-episode running mean of `dos` or `doa` first completes 90 % of its
    /// change from the first 100 episodes to the last 100 (the paper's time course, Fig. 3).
    Reach90(Curve),
    /// Mean of the first [`START`](super::curves::START) training episodes of `dos`, `doa` or `catches`
    /// (or `authors_dos`, `authors_doa`: the shipped code's metric, in runs with `authors_metrics`):
    /// the untrained level the paper's curves start from (the actors learn from the first episodes on,
    /// so this is the nearest a training run gives; `Learned` evaluations measure untrained actors directly).
    Start(Curve),
    /// The last 100 training episodes minus [`Quantity::Start`]: the paper's rise or fall over training,
    /// from where its curves start (`DoaChange` and `DosChange` measure it from the first 100 episodes).
    FromStart(Curve),
    /// The extreme of the 100-episode running mean of `doa` (its peak) or `dos` (its trough), the window
    /// chosen on the odd episodes and its mean taken over the even ones. That removes the bias of picking
    /// the best window from episode-to-episode noise, not from the policy's slow drift, which neighbouring
    /// episodes share: a curve that only wanders also shows a fall back after its peak, so
    /// [`Quantity::AfterExtreme`] measures how far the curve ended from its best, not that it declined.
    Extreme(Curve),
    /// The episode ending that window.
    ExtremeEpisode(Curve),
    /// The last 100 episodes minus the extreme, both over the even episodes: how far the curve moved
    /// back after its peak (DoA) or trough (DoS).
    AfterExtreme(Curve),
    /// How fast a curve converges: the episode at which the [`HALFWAY_WINDOW`](super::results::HALFWAY_WINDOW)-
    /// episode running mean of `dos` or `doa` first completes half of its change from the start (the
    /// first [`START`](super::curves::START) episodes) to the last 100 episodes. Half the change is crossed
    /// where the curve is steepest, so its seed-to-seed spread is small (the 90 % of
    /// [`Quantity::Reach90`] is crossed where the curve is flat); the short window resolves curves that
    /// do most of their change within the first 100 episodes.
    Halfway(Curve),
    /// How fast a curve gets to one level common to the arms compared: the episode at which the
    /// [`HALFWAY_WINDOW`](super::results::HALFWAY_WINDOW)-episode running mean of `dos` first falls to the
    /// level or below, or of `doa` first rises to it or above (from its first whole window on). A run
    /// that never gets there counts as getting there one episode after its last (censored), so that it is
    /// neither dropped nor counted as early. Unlike [`Quantity::Halfway`], which times each run against
    /// its own change, the target does not move with how much a run changes.
    Reaches(Curve, f64),
    /// A part of the exponential approach fitted by least squares to a training curve (`dos`, `doa` or
    /// `catches`, per episode e from 1): y(e) = end + (start − end)·exp(−(e − 1)/time). `Time`, the time
    /// constant in episodes (the episodes to complete 63 % of the change), says how *fast* a curve
    /// converges apart from how *far* (`End`), which `Halfway` and `Reaches` mix. A curve still moving
    /// at its last episode gets a time up to [`FIT_LONGEST`](super::curves::FIT_LONGEST) times its
    /// episodes; one with no change has no time (NaN). Fitted by `curves::fit_approach`.
    Fitted(Curve, Fit),
    /// The information-transfer response of an evaluation with `perturb:`: `"near"`, the mean |Δheading|
    /// of the turned prey's 6 nearest over the 10 steps after the turn, or `"far"`, the same for ranks 25
    /// and beyond (radians).
    Response(String, String),
    /// A read-out of where the predators head and the prey gather in an evaluation (its `-confusion` and
    /// `-pursuit` files), per run: e.g. `Tactic("trained", Slowdown)`. See [`Tactic`].
    Tactic(String, Tactic),
    /// What training changed of a [`Quantity::Tactic`]: its value in an evaluation of the trained actors
    /// minus in the same evaluation of the untrained ones (`untrained: true`, as [`Quantity::Learned`]
    /// pairs them), per run.
    TacticLearned(String, Tactic),
    /// A read-out of the run's cross-play matrix (`crossplay_readouts::readouts`, the headline species against its
    /// first predator species), e.g. `Crossplay("doa_late_prey_part")`; needs `crossplay:` in the file.
    Crossplay(String),
}

/// An enum written in experiment files by name: its variants with their names, `ALL`, `name`, `parse`,
/// `Display` (the name) and `Debug` (the name quoted, as the string each was before it was a type, so that
/// a claim's fingerprint, which hashes the quantity's `Debug` in `registry.rs`, stands), and a
/// `Deserialize` that refuses any other name, listing the names.
macro_rules! named {
    ($(#[$doc:meta])* $name:ident, $what:literal { $($(#[$vdoc:meta])* $variant:ident = $text:literal,)* }) => {
        $(#[$doc])*
        #[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum $name {
            $($(#[$vdoc])* $variant,)*
        }

        impl $name {
            /// Every one, in the order of their names.
            pub const ALL: [$name; [$($text),*].len()] = [$($name::$variant),*];

            /// Its name in experiment files and summary columns.
            pub fn name(self) -> &'static str {
                match self {
                    $($name::$variant => $text,)*
                }
            }

            pub fn parse(name: &str) -> Option<$name> {
                $name::ALL.into_iter().find(|c| c.name() == name)
            }
        }

        impl std::fmt::Debug for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                write!(f, "{:?}", self.name())
            }
        }

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.name())
            }
        }

        impl<'de> Deserialize<'de> for $name {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<$name, D::Error> {
                let name = String::deserialize(d)?;
                $name::parse(&name).ok_or_else(|| {
                    let names: Vec<String> = $name::ALL.iter().map(|c| format!("{:?}", c.name())).collect();
                    serde::de::Error::custom(format!("{name:?} is no {}: one of {}", $what, names.join(", ")))
                })
            }
        }
    };
}

named! {
    /// A training curve, per episode, that a curve quantity reads ([`Quantity::Start`], [`Quantity::Fitted`],
    /// ...): written in experiment files as its name, `"dos"`, `"doa"`, `"catches"`, or, in runs with
    /// `authors_metrics`, `"authors_dos"` and `"authors_doa"` (the shipped code's metric).
    Curve, "training curve" {
        Dos = "dos",
        Doa = "doa",
        Catches = "catches",
        AuthorsDos = "authors_dos",
        AuthorsDoa = "authors_doa",
    }
}

impl Curve {
    /// DoS and DoA fall and rise; the rest are other curves.
    pub(crate) fn is_order(self) -> bool {
        matches!(self, Curve::Dos | Curve::Doa)
    }
}

named! {
    /// What an order-parameter quantity reads ([`Quantity::EvalOrder`], [`Quantity::Interaction`],
    /// [`Quantity::Learned`], [`Quantity::EvalDifference`], [`Quantity::TrainingFirst`],
    /// [`Quantity::TrainingLast`]): the paper's DoS and DoA, catches, the order parameters of
    /// [`Swarming`] beside them, the edge rank of caught prey, and the shipped code's DoS and DoA. Which of
    /// them each quantity takes is [`Order::of_evaluation`], [`Order::of_training`] and
    /// [`Order::compared`].
    Order, "order parameter" {
        Dos = "dos",
        Doa = "doa",
        Catches = "catches",
        Polarization = "polarization",
        Milling = "milling",
        Clusters = "clusters",
        LargestCluster = "largest_cluster",
        NnCorrelation = "nn_correlation",
        EdgeRank = "edge_rank",
        AuthorsDos = "authors_dos",
        AuthorsDoa = "authors_doa",
    }
}

impl Order {
    /// Taken by [`Quantity::EvalOrder`]: [`EVAL_ORDER`] (DoS, DoA and catches have quantities of their own).
    pub(crate) fn of_evaluation(self) -> bool {
        EVAL_ORDER.contains(&self)
    }

    /// Taken by [`Quantity::TrainingFirst`] and [`Quantity::TrainingLast`]: [`EVAL_ORDER`] and the shipped
    /// code's DoS and DoA (`authors_metrics`).
    pub(crate) fn of_training(self) -> bool {
        self.of_evaluation() || matches!(self, Order::AuthorsDos | Order::AuthorsDoa)
    }

    /// Taken by the comparisons of evaluations ([`Quantity::Interaction`], [`Quantity::Learned`],
    /// [`Quantity::EvalDifference`]): DoS, DoA, catches and [`EVAL_ORDER`].
    pub(crate) fn compared(self) -> bool {
        self.of_evaluation() || matches!(self, Order::Dos | Order::Doa | Order::Catches)
    }

    /// The order parameter it measures, whoever's metric: DoS and DoA for the shipped code's.
    pub(crate) fn measured(self) -> Order {
        match self {
            Order::AuthorsDos => Order::Dos,
            Order::AuthorsDoa => Order::Doa,
            other => other,
        }
    }

    /// The width of the values it can take, None when unbounded: DoS, DoA, polarization, milling, the
    /// largest cluster's share and the edge rank lie in [0, 1], C_nn in [−1, 1].
    pub(crate) fn span(self) -> Option<f64> {
        match self.measured() {
            Order::Dos
            | Order::Doa
            | Order::Polarization
            | Order::Milling
            | Order::LargestCluster
            | Order::EdgeRank => Some(1.0),
            Order::NnCorrelation => Some(2.0),
            Order::Catches | Order::Clusters | Order::AuthorsDos | Order::AuthorsDoa => None,
        }
    }
}

/// What [`Quantity::Tactic`] reads of an evaluation: the predators' pursuit (of the first species that
/// catches the headline species) and the prey's place. "Early" is an episode's first [`EARLY_STEPS`]
/// steps, "later" the rest of it; each step's value is the mean over the predators it has one for,
/// weighted by how many those are. The paper's statements they measure are in its Discussion: confusion,
/// the dispersion tactic, and boundary aggregation (Fig. 9(a)).
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq, PartialOrd, Ord)]
pub enum Tactic {
    /// Confusion ("the predator gives up the chase, slows down, and stagnates"): a predator's speed (a
    /// fraction of its max) after a decision taken with 5 or more prey in view, minus after one taken with
    /// 1 or 2 in view, over the confusion curve's bins weighted by their decisions. Below 0: slower among
    /// many prey.
    Slowdown,
    /// The same for the magnitude of the turn command (a fraction of the max turn rate). Above 0: turning
    /// more among many prey ("uncertain about which prey to focus on").
    Hesitation,
    /// The dispersion tactic's first part ("first move towards the center of a swarm"): how often a
    /// predator's turns steer toward the centre of the prey in view, minus toward the most isolated of them
    /// (each a mean of ±1 per decision, [`crate::sim::collective::steering`]), early in episodes. Above 0:
    /// steering for the centre more.
    CentreEarly,
    /// Its second part ("and then focus on isolated ones"): that difference later in episodes minus
    /// early. Below 0: turning from the centre to the isolated prey.
    CentreChange,
    /// Later in episodes, steering toward the most isolated prey in view minus toward the nearest: above
    /// 0 when a predator picks isolation over proximity.
    IsolatedOverNearest,
    /// Steering toward the nearest prey in view over the whole evaluation (1: every turn toward it; 0: as
    /// often away as toward): a predator that chases the nearest prey reads 1, one that turns at random 0.
    SteerNearest,
    /// Boundary aggregation: the share of the prey within a tenth of the arena's edge of a wall later in
    /// episodes, minus that band's share of the area (0.36, the share of uniformly spread positions).
    /// Above 0: gathered along the walls. NaN without walls.
    BoundaryExcess,
}

impl Tactic {
    pub(crate) const ALL: [Tactic; 7] = [
        Tactic::Slowdown,
        Tactic::Hesitation,
        Tactic::CentreEarly,
        Tactic::CentreChange,
        Tactic::IsolatedOverNearest,
        Tactic::SteerNearest,
        Tactic::BoundaryExcess,
    ];

    /// Its position in [`Tactic::ALL`].
    pub(crate) fn index(self) -> usize {
        self as usize
    }

    /// Its summary.csv column's last part.
    pub(crate) fn column(self) -> &'static str {
        match self {
            Tactic::Slowdown => "slowdown",
            Tactic::Hesitation => "hesitation",
            Tactic::CentreEarly => "centre_early",
            Tactic::CentreChange => "centre_change",
            Tactic::IsolatedOverNearest => "isolated_over_nearest",
            Tactic::SteerNearest => "steer_nearest",
            Tactic::BoundaryExcess => "boundary_excess",
        }
    }

    /// Its words in tables.
    pub(crate) fn words(self) -> &'static str {
        match self {
            Tactic::Slowdown => "predators' speed with 5+ prey in view minus with 1–2 (fraction of max speed)",
            Tactic::Hesitation => "predators' |turn| with 5+ prey in view minus with 1–2 (fraction of max turn)",
            Tactic::CentreEarly => {
                "predators' steering to the centre minus to the most isolated prey in view, early in episodes"
            }
            Tactic::CentreChange => {
                "(steering to the centre minus to the most isolated prey in view) later minus early in episodes"
            }
            Tactic::IsolatedOverNearest => {
                "predators' steering to the most isolated minus to the nearest prey in view, later in episodes"
            }
            Tactic::SteerNearest => "predators' steering to the nearest prey in view (1 = every turn toward it)",
            Tactic::BoundaryExcess => {
                "share of prey within a tenth of the edge of a wall minus the band's share of the area"
            }
        }
    }
}

/// The steps at the start of each evaluation episode that [`Tactic`] calls early: a tenth of the paper's
/// 500-step episode, 5 s, in which a predator at the `paper` preset's max speed (0.5 m/s) covers 2.5 m,
/// about the 2 m arena's edge.
pub(crate) const EARLY_STEPS: usize = 50;

/// A part of the approach [`Quantity::Fitted`] fits to a training curve.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
pub enum Fit {
    /// The fitted value at the first episode.
    Start,
    /// The level the curve approaches.
    End,
    /// The time constant, in episodes.
    Time,
}

/// Order parameters an [`Quantity::EvalOrder`] may name: every one of [`Swarming`] but DoS and DoA (its
/// first two; they have quantities of their own, `EvalDos` and `EvalDoa`), then the edge rank of caught
/// prey. A test holds their names to [`Swarming::NAMES`], so an order parameter added there is added here.
pub const EVAL_ORDER: [Order; EVAL_ORDERS] = [
    Order::Polarization,
    Order::Milling,
    Order::Clusters,
    Order::LargestCluster,
    Order::NnCorrelation,
    Order::EdgeRank,
];

/// The report-table heading and digits of each of [`EVAL_ORDER`], in its order.
pub const EVAL_ORDER_LABELS: [&str; EVAL_ORDERS] = eval_order(Swarming::LABELS, "edge rank");
pub(crate) const EVAL_ORDER_DIGITS: [usize; EVAL_ORDERS] = eval_order(Swarming::DIGITS, 3);

const EVAL_ORDERS: usize = Swarming::N - 2 + 1;

/// `per_swarming` without its first two (DoS, DoA), then `edge_rank`.
const fn eval_order<T: Copy>(per_swarming: [T; Swarming::N], edge_rank: T) -> [T; EVAL_ORDERS] {
    let mut out = [edge_rank; EVAL_ORDERS];
    let mut i = 2;
    while i < Swarming::N {
        out[i - 2] = per_swarming[i];
        i += 1;
    }
    out
}

/// The untrained evaluation a trained evaluation `name` is compared with: same counts, policies, episodes,
/// steps and control, `untrained: true`.
pub(crate) fn untrained_partner<'a>(evaluations: &'a [Evaluation], name: &str) -> Option<&'a Evaluation> {
    let trained = evaluations.iter().find(|e| e.name == name && !e.untrained)?;
    evaluations.iter().find(|e| {
        e.untrained
            && e.counts == trained.counts
            && e.arena_edge == trained.arena_edge
            && e.episodes == trained.episodes
            && e.steps == trained.steps
            && e.control == trained.control
            && e.policies == trained.policies
            && e.distilled == trained.distilled
    })
}

/// The seeing evaluation a control evaluation `name` is compared with: same counts, policies, episodes,
/// steps and training state.
/// None when `name` is no control or has no such partner.
pub(crate) fn seeing_partner<'a>(evaluations: &'a [Evaluation], name: &str) -> Option<&'a Evaluation> {
    let control = evaluations.iter().find(|e| e.name == name)?;
    if control.control.is_seeing() {
        return None;
    }
    evaluations.iter().find(|e| {
        e.control.is_seeing()
            && e.counts == control.counts
            && e.arena_edge == control.arena_edge
            && e.episodes == control.episodes
            && e.steps == control.steps
            && e.policies == control.policies
            && e.distilled == control.distilled
            && e.untrained == control.untrained
    })
}

/// One run of an experiment.
#[derive(Clone, Debug)]
pub struct Run {
    pub(crate) preset: String,
    pub variant: String,
    pub seed: u64,
    /// The variant's resolved scene, seed applied.
    pub scene: Scene,
    /// The run's folder: under this experiment's results, or the owner's for a shared run.
    pub dir: PathBuf,
    /// The experiment whose run this is, for a variant with `shared_from`.
    pub(crate) shared_from: Option<String>,
    /// The variant's `same_training_as`: the `"EXPERIMENT/VARIANT"` this run is a declared re-training of.
    pub(crate) same_training_as: Option<String>,
    /// The variant's own kernel family (`kernels:`), None for the experiment's.
    pub(crate) kernels: Option<crate::learning::nets::Kernels>,
}

/// A loaded and validated experiment.
#[derive(Clone, Debug)]
pub struct Experiment {
    pub name: String,
    pub(crate) file: PathBuf,
    pub spec: ExperimentFile,
    /// `results/<name>`.
    pub root: PathBuf,
    /// Every preset × variant × seed, in that order.
    pub runs: Vec<Run>,
    /// The binary every run is made by, when the experiment is pinned (`results/<name>/binary/pin.ron`).
    pub pin: Option<super::pin::Pin>,
}

/// The longest variant or evaluation name: it becomes a folder or file name (`eval-NAME-confusion.csv`),
/// which file systems cap at 255 bytes.
pub(crate) const MAX_NAME: usize = 100;

/// The file an evaluation of a run writes (named by the run folder's owner, `store::RunDir`).
pub(crate) fn eval_file(dir: &std::path::Path, evaluation: &str) -> std::path::PathBuf {
    crate::store::RunDir::new(dir).evaluation(&slug(evaluation))
}

/// A folder-safe version of a name: runs of other characters become one `-` ("5:3" → "5-3",
/// "n0 = 1" → "n0-1", "50 prey, blind" → "50-prey-blind").
pub(crate) fn slug(name: &str) -> String {
    let mut out = String::new();
    for c in name.chars() {
        if c.is_ascii_alphanumeric() || c == '.' || c == '_' {
            out.push(c);
        } else if !out.is_empty() && !out.ends_with('-') {
            out.push('-');
        }
    }
    out.trim_end_matches('-').to_string()
}

#[cfg(test)]
mod tests {
    use super::{Order, EVAL_ORDER};
    use crate::sim::metrics::Swarming;

    #[test]
    fn the_evaluations_order_parameters_are_swarmings_then_the_edge_rank() {
        // An order parameter added to `Swarming` must be added to `Order` and `EVAL_ORDER` too.
        let names: Vec<&str> = EVAL_ORDER.iter().map(|o| o.name()).collect();
        let expected: Vec<&str> =
            Swarming::NAMES[2..].iter().copied().chain([crate::store::schema::EDGE_RANK]).collect();
        assert_eq!(names, expected);
        assert_eq!(Order::parse("nn_correlation"), Some(Order::NnCorrelation));
        assert_eq!(format!("{:?}", Order::Milling), "\"milling\"", "as the string it was: fingerprints stand");
    }
}
