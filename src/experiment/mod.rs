//! Experiments: the paper's sweeps as files (`experiments/*.ron`), run as independent training runs, then
//! evaluated, aggregated over seeds (mean and Student-t 95 % confidence interval) and plotted.
//!
//! ```ron
//! (
//!     description: "Effect of the speed limit ratio predator:prey (the paper's Fig. 10)",
//!     base: "scenes/paper.ron",             // the scene every variant starts from
//!     presets: ["paper", "gym-pps"],        // the base is run on each preset (default ["paper"])
//!     seeds: [1, 2, 3],
//!     episodes: 2000,                       // optional: overrides the base scene's
//!     variants: [
//!         (name: "1:1"),                                                    // the base as it is
//!         (name: "5:3", patch: (species: [(name: "prey", max_speed: 0.3)])), // a scene patch
//!     ],
//!     evaluations: [(name: "50 prey", counts: [("prey", 50)], episodes: 3, steps: 500)],
//!     claims: [ /* the paper's numbers this experiment tests, see `Claim` */ ],
//! )
//! ```
//!
//! Every preset × variant × seed is one run folder, `results/<experiment>/<preset>/<variant>/seed<k>/`,
//! trained by `coevo --train` in a child process on its share of the cores (results never depend on how
//! many run at once or on how many threads each has), resumed from its checkpoint when it was killed, skipped when finished ([`runner`]). Then the
//! evaluations write `eval-<name>.csv` beside it, and [`aggregate`] reads only CSV files to write
//! `summary.csv`, `summary-mean.csv` and the figures ([`plot`]).

pub mod aggregate;
pub mod claims;
pub mod crossplay;
pub mod figure_data;
pub mod plot;
pub mod report;
pub mod runner;
pub mod stats;

use crate::error::{Error, Result};
use crate::scene::{parse_ron, Overrides, Scene, ScenePatch, PRESETS};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// An experiment file as written.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExperimentFile {
    #[serde(default)]
    pub description: String,
    /// The scene file every variant starts from.
    pub base: String,
    #[serde(default = "default_presets")]
    pub presets: Vec<String>,
    pub seeds: Vec<u64>,
    #[serde(default)]
    pub episodes: Option<usize>,
    pub variants: Vec<VariantFile>,
    #[serde(default)]
    pub evaluations: Vec<Evaluation>,
    #[serde(default)]
    pub claims: Vec<Claim>,
    /// Compare runs made by different executables (`provenance.ron`'s `binary` and `also_by`). Off by
    /// default: every number of an experiment comes from one binary, and aggregation refuses otherwise.
    #[serde(default)]
    pub mixed_binaries: bool,
    /// Keep each run's replay buffers once it is trained (~0.45 GB a run of the standard scene), so that
    /// `coevo --resume RUN --episodes N` can extend it exactly as an uninterrupted longer run. Off by
    /// default: a finished run's buffers are removed (`learning::checkpoint::drop_replay`), so a suite of
    /// 150 runs needs ~1 GB rather than ~70 GB.
    #[serde(default)]
    pub keep_replay: bool,
    /// Cross-play every run's snapshots (`coevo --crossplay`) after its evaluations, so claims can name
    /// its read-outs (`Crossplay("...")`).
    #[serde(default)]
    pub crossplay: Option<CrossplaySpec>,
}

/// How an experiment cross-plays its runs.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CrossplaySpec {
    /// Episodes per cell.
    #[serde(default = "five")]
    pub episodes: usize,
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
pub struct VariantFile {
    pub name: String,
    #[serde(default)]
    pub patch: ScenePatch,
    /// `"EXPERIMENT/VARIANT"`: this variant's runs are that experiment's runs (same preset and seed, the
    /// same resolved scene, checked), not trained or copied again: a shared run is one training, counted
    /// once, and never compared with itself.
    #[serde(default)]
    pub shared_from: Option<String>,
}

/// How the trained policies of every run are deployed (`coevo --eval`): species counts, episodes and
/// steps; its per-step DoS/DoA land in `eval-<name>.csv`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Evaluation {
    pub name: String,
    /// Species counts for the evaluation, e.g. `[("prey", 50), ("predator", 0)]`.
    #[serde(default)]
    pub counts: Vec<(String, usize)>,
    #[serde(default = "three")]
    pub episodes: usize,
    /// Steps per episode (default: the scene's).
    #[serde(default)]
    pub steps: Option<usize>,
    /// What the actors see (`learning::control`): `Blind`, `Shuffled`, a block form such as
    /// `"blind:prey:prey"`, or a list of block forms (default: seeing).
    #[serde(default)]
    pub control: crate::learning::control::ObservationControl,
    /// Radius (m) of "prey in view" for the confusion curve (default: the scene's).
    #[serde(default)]
    pub confusion_radius: Option<f64>,
    /// Deploy the actors as initialised before training (`coevo --eval --untrained`): the start against
    /// which [`Quantity::Learned`] measures what training changed.
    #[serde(default)]
    pub untrained: bool,
    /// Also turn one prey of a twin world by this many radians (`coevo --eval --perturb`) after
    /// `perturb_step` (default: half the episode), for [`Quantity::Response`].
    #[serde(default)]
    pub perturb: Option<f64>,
    #[serde(default)]
    pub perturb_step: Option<usize>,
    /// Species whose policy the evaluation replaces, e.g. `[("predator", ChaseNearest)]`: trained prey
    /// against the paper's rule-based predators (`coevo --eval --policy`).
    #[serde(default)]
    pub policies: Vec<(String, crate::scene::Policy)>,
}

impl Evaluation {
    /// What the evaluation changes of a run's scene.
    pub fn overrides(&self) -> Overrides {
        Overrides {
            counts: self.counts.clone(),
            policies: self.policies.clone(),
            seed: None,
            episode_steps: self.steps,
            confusion_radius: self.confusion_radius,
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
    pub variant: String,
    pub quantity: Quantity,
    /// The paper's number, when it gives one.
    #[serde(default)]
    pub paper: Option<f64>,
    /// Compare with this variant: the claim's number becomes `variant`'s mean minus this variant's, with
    /// Welch's 95 % interval (e.g. an ablation variant against the base it changes one thing of).
    #[serde(default)]
    pub versus: Option<String>,
    /// For a claim of no effect ("unchanged", "flat"): the margin m of the equivalence test (TOST): the
    /// claim is reproduced when the effect's 90 % interval lies inside (−m, m).
    #[serde(default)]
    pub margin: Option<f64>,
    /// For a level: the value that chance alone gives, which the level must be told apart from (DoA's
    /// 2/π and DoS at random positions are filled in when not given).
    #[serde(default)]
    pub baseline: Option<f64>,
    /// The paper states only the direction of this effect (e.g. "faster convergence"): `paper` then gives
    /// its sign (+1 or −1), never a size the interval could exclude.
    #[serde(default)]
    pub direction_only: bool,
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
    /// `largest_cluster`, `nn_correlation`, `edge_rank`): mean of the first / last 100 episodes.
    TrainingFirst(String),
    TrainingLast(String),
    /// The evaluation's mean over its last 50 steps (the trained policies' settled state).
    EvalDos(String),
    EvalDoa(String),
    /// The same for another order parameter of the evaluation: `polarization`, `milling`, `clusters`,
    /// `largest_cluster`, `nn_correlation`; or `edge_rank`, the mean edge rank of every prey caught in it.
    EvalOrder(String, String),
    /// The interaction-driven part of the alignment: DoA of the seeing evaluation with the same counts,
    /// episodes and steps, minus DoA of this control evaluation (blind or shuffled), per run.
    InteractionDoa(String),
    /// The same for another order parameter (as [`Quantity::EvalOrder`] names them), e.g.
    /// `Interaction("50 prey, blind to prey", "nn_correlation")`: seeing minus the control, per run.
    Interaction(String, String),
    /// What training changed: an order parameter (`dos`, `doa` or as [`Quantity::EvalOrder`]) in an
    /// evaluation of the trained actors minus the same evaluation of the untrained ones (same counts,
    /// episodes, steps and control, `untrained: true`), per run.
    Learned(String, String),
    /// The episode at which the 100-episode running mean of `dos` or `doa` first completes 90 % of its
    /// change from the first 100 episodes to the last 100 (the paper's time course, Fig. 3).
    Reach90(String),
    /// The information-transfer response of an evaluation with `perturb:`: `"near"`, the mean |Δheading|
    /// of the turned prey's 6 nearest over the 10 steps after the turn, or `"far"`, the same for ranks 25
    /// and beyond (radians).
    Response(String, String),
    /// A read-out of the run's cross-play matrix (`crossplay::readouts`, the headline species against its
    /// first predator species), e.g. `Crossplay("doa_late_prey_part")`; needs `crossplay:` in the file.
    Crossplay(String),
}

/// Order parameters an [`Quantity::EvalOrder`] may name.
pub const EVAL_ORDER: [&str; 6] =
    ["polarization", "milling", "clusters", "largest_cluster", "nn_correlation", "edge_rank"];

/// The untrained evaluation a trained evaluation `name` is compared with: same counts, policies, episodes,
/// steps and control, `untrained: true`.
pub fn untrained_partner<'a>(evaluations: &'a [Evaluation], name: &str) -> Option<&'a Evaluation> {
    let trained = evaluations.iter().find(|e| e.name == name && !e.untrained)?;
    evaluations.iter().find(|e| {
        e.untrained
            && e.counts == trained.counts
            && e.episodes == trained.episodes
            && e.steps == trained.steps
            && e.control == trained.control
            && e.policies == trained.policies
    })
}

/// The seeing evaluation a control evaluation `name` is compared with: same counts, policies, episodes,
/// steps and training state.
/// None when `name` is no control or has no such partner.
pub fn seeing_partner<'a>(evaluations: &'a [Evaluation], name: &str) -> Option<&'a Evaluation> {
    let control = evaluations.iter().find(|e| e.name == name)?;
    if control.control.is_seeing() {
        return None;
    }
    evaluations.iter().find(|e| {
        e.control.is_seeing()
            && e.counts == control.counts
            && e.episodes == control.episodes
            && e.steps == control.steps
            && e.policies == control.policies
            && e.untrained == control.untrained
    })
}

/// One run of an experiment.
#[derive(Clone, Debug)]
pub struct Run {
    pub preset: String,
    pub variant: String,
    pub seed: u64,
    /// The variant's resolved scene, seed applied.
    pub scene: Scene,
    /// The run's folder: under this experiment's results, or the owner's for a shared run.
    pub dir: PathBuf,
    /// The experiment whose run this is, for a variant with `shared_from`.
    pub shared_from: Option<String>,
}

/// A loaded and validated experiment.
#[derive(Clone, Debug)]
pub struct Experiment {
    pub name: String,
    pub file: PathBuf,
    pub spec: ExperimentFile,
    /// `results/<name>`.
    pub root: PathBuf,
    /// Every preset × variant × seed, in that order.
    pub runs: Vec<Run>,
}

/// A folder-safe version of a name: runs of other characters become one `-` ("5:3" → "5-3",
/// "n0 = 1" → "n0-1", "50 prey, blind" → "50-prey-blind").
/// The longest variant or evaluation name: it becomes a folder or file name (`eval-NAME-confusion.csv`),
/// which file systems cap at 255 bytes.
const MAX_NAME: usize = 100;

pub fn slug(name: &str) -> String {
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

/// The experiment and variant a `shared_from` names (`"EXPERIMENT/VARIANT"`, the experiment a file beside
/// `file`), loaded without its own shared variants (a variant it shares itself is refused); its evaluations of the same name must be the same
/// evaluations, since both experiments write them into the same run folders.
fn shared_owner(
    file: &Path,
    results: &Path,
    from: &str,
    ours: &[Evaluation],
) -> std::result::Result<(Experiment, String), String> {
    let Some((experiment, variant)) = from.split_once('/') else {
        return Err(format!("{from:?} is not EXPERIMENT/VARIANT"));
    };
    let owner_file = file.parent().unwrap_or(Path::new(".")).join(format!("{experiment}.ron"));
    if !owner_file.is_file() {
        return Err(format!("no experiment file {}", owner_file.display()));
    }
    let owner = Experiment::load_with(&owner_file, results, false).map_err(|e| e.to_string())?;
    match owner.spec.variants.iter().find(|v| v.name == variant) {
        None => return Err(format!("{experiment} has no variant {variant:?}")),
        Some(v) if v.shared_from.is_some() => {
            return Err(format!(
                "{experiment}/{variant} is itself shared from {}; share from the experiment that trains it",
                v.shared_from.as_deref().unwrap_or_default()
            ))
        }
        Some(_) => {}
    }
    for e in ours {
        if let Some(theirs) = owner.spec.evaluations.iter().find(|t| slug(&t.name) == slug(&e.name)) {
            if theirs != e {
                return Err(format!(
                    "evaluation {:?} differs from {experiment}'s of the same name, and both would write eval-{}.csv into the shared runs",
                    e.name,
                    slug(&e.name)
                ));
            }
        }
    }
    Ok((owner, variant.to_string()))
}

/// The first line where two texts differ (trimmed), None when they are equal.
fn first_difference(a: &str, b: &str) -> Option<String> {
    if a == b {
        return None;
    }
    let line = a.lines().zip(b.lines()).find(|(x, y)| x != y).map_or("length", |(x, _)| x.trim());
    Some(line.to_string())
}

/// The first value that appears twice.
fn first_repeat<T: PartialEq>(values: &[T]) -> Option<&T> {
    values.iter().enumerate().find(|(i, v)| values[..*i].contains(v)).map(|(_, v)| v)
}

impl Experiment {
    /// Loads an experiment file and resolves every run's scene; errors are one line naming the file and
    /// the field, as for scenes.
    pub fn load(file: &Path, results: &Path) -> Result<Experiment> {
        Experiment::load_with(file, results, true)
    }

    /// [`Experiment::load`]; `share` resolves `shared_from` variants (an owner is loaded without, so a
    /// variant shared from a shared variant is refused rather than followed).
    fn load_with(file: &Path, results: &Path, share: bool) -> Result<Experiment> {
        let shown = file.display().to_string();
        let text = crate::io::read_text(file, crate::scene::MAX_SCENE_BYTES).map_err(|e| format!("{shown}: {e}"))?;
        let spec: ExperimentFile = parse_ron(&text, &shown)?;
        let name = file.file_stem().map_or(String::new(), |s| s.to_string_lossy().into_owned());
        let err = |field: &str, message: String| Error::field(field.to_string(), message).in_file(file);
        // The name is a folder under results/: one safe component, never `.`, `..` or hidden.
        crate::run::check_name(&name)
            .map_err(|m| format!("{shown}: the file name {m}, as it names the folder results/{name}"))?;
        if spec.presets.is_empty() {
            return Err(err("presets", "an experiment needs at least one preset".into()));
        }
        if let Some(p) = first_repeat(&spec.presets) {
            return Err(err("presets", format!("{p:?} appears twice")));
        }
        if spec.seeds.is_empty() {
            return Err(err("seeds", "an experiment needs at least one seed".into()));
        }
        if let Some(s) = first_repeat(&spec.seeds) {
            return Err(err(
                "seeds",
                format!("seed {s} appears twice (a run of the same scene and seed is the same run)"),
            ));
        }
        if spec.episodes == Some(0) {
            return Err(err("episodes", "must be ≥ 1".into()));
        }
        if spec.variants.is_empty() {
            return Err(err("variants", "an experiment needs at least one variant".into()));
        }
        // Checked here, before anything is trained: a run would fail only at its cross-play.
        if let Some(c) = spec.crossplay.as_ref().filter(|c| c.episodes == 0) {
            return Err(err("crossplay.episodes", format!("must be ≥ 1 (got {})", c.episodes)));
        }
        // Names become folders, file names, CSV fields and figure labels: no control character (a NUL
        // would pass the folder's slug and fail only in the figure writer, after the runs), and short
        // enough for every file name made of them.
        let names = spec
            .variants
            .iter()
            .map(|v| ("variants", &v.name))
            .chain(spec.evaluations.iter().map(|e| ("evaluations", &e.name)));
        for (list, name) in names {
            if name.chars().any(char::is_control) {
                return Err(err(
                    &format!("{list}[{}].name", name.escape_debug()),
                    "must not hold a control character".into(),
                ));
            }
            if name.chars().count() > MAX_NAME {
                return Err(err(
                    &format!("{list}[{}…].name", name.chars().take(16).collect::<String>()),
                    format!("at most {MAX_NAME} characters (it names folders and files)"),
                ));
            }
        }
        for (i, v) in spec.variants.iter().enumerate() {
            let field = format!("variants[{}].name", v.name);
            crate::run::check_name(&slug(&v.name)).map_err(|m| {
                err(&field, format!("as a folder name ({:?}) it {m}; use letters or digits", slug(&v.name)))
            })?;
            if spec.variants[..i].iter().any(|o| slug(&o.name) == slug(&v.name)) {
                return Err(err(&field, format!("names the same folder ({:?}) as another variant", slug(&v.name))));
            }
        }
        for (i, e) in spec.evaluations.iter().enumerate() {
            let field = |f: &str| format!("evaluations[{}].{f}", e.name);
            let file = format!("eval-{}.csv", slug(&e.name));
            if slug(&e.name).is_empty() {
                return Err(err(&field("name"), "needs a letter or digit".into()));
            }
            crate::run::RunDir::new(".")
                .eval_output(Some(&file))
                .map_err(|m| err(&field("name"), m.to_string().replacen("--eval-out ", "as the file ", 1)))?;
            if spec.evaluations[..i].iter().any(|o| slug(&o.name) == slug(&e.name)) {
                return Err(err(&field("name"), format!("names the same file ({file}) as another evaluation")));
            }
            if e.episodes == 0 || e.steps == Some(0) {
                return Err(err(&field("episodes"), "episodes and steps must be ≥ 1".into()));
            }
            if let Some(r) = e.confusion_radius.filter(|r| !(r.is_finite() && *r > 0.0)) {
                return Err(err(
                    &field("confusion_radius"),
                    format!("must be a finite number of metres > 0 (got {r})"),
                ));
            }
        }
        for (i, c) in spec.claims.iter().enumerate() {
            // A claim is cited by its text (REPRODUCTION.md's rows, the book's citations): one row per text.
            if spec.claims[..i].iter().any(|d| d.text == c.text) {
                return Err(err("claims", format!("{:?} is the text of two claims", c.text)));
            }
            if let Some(v) = c.paper.filter(|v| !v.is_finite()) {
                return Err(err("claims", format!("{:?}: paper must be a finite number (got {v})", c.text)));
            }
            for v in std::iter::once(&c.variant).chain(&c.versus) {
                if !spec.variants.iter().any(|x| &x.name == v) {
                    return Err(err("claims", format!("no variant named {v:?}")));
                }
            }
            if c.versus.as_ref() == Some(&c.variant) {
                return Err(err("claims", format!("{:?} is compared with itself (versus)", c.text)));
            }
            if let Some(versus) = &c.versus {
                let source =
                    |name: &String| spec.variants.iter().find(|v| &v.name == name).and_then(|v| v.shared_from.clone());
                if let Some(shared) = source(&c.variant).filter(|s| Some(s) == source(versus).as_ref()) {
                    return Err(err(
                        "claims",
                        format!("{:?} compares runs with themselves: both variants are shared from {shared}", c.text),
                    ));
                }
            }
            if let Quantity::EvalDos(e)
            | Quantity::EvalDoa(e)
            | Quantity::EvalOrder(e, _)
            | Quantity::InteractionDoa(e)
            | Quantity::Interaction(e, _)
            | Quantity::Learned(e, _) = &c.quantity
            {
                if !spec.evaluations.iter().any(|x| &x.name == e) {
                    return Err(err("claims", format!("no evaluation named {e:?}")));
                }
            }
            if let Quantity::EvalOrder(_, q)
            | Quantity::Interaction(_, q)
            | Quantity::TrainingFirst(q)
            | Quantity::TrainingLast(q) = &c.quantity
            {
                if !EVAL_ORDER.contains(&q.as_str()) {
                    return Err(err(
                        "claims",
                        format!("no order parameter named {q:?} (one of {})", EVAL_ORDER.join(", ")),
                    ));
                }
            }
            if let Quantity::Learned(e, _) = &c.quantity {
                if untrained_partner(&spec.evaluations, e).is_none() {
                    return Err(err("claims", format!("evaluation {e:?} needs an untrained partner (untrained: true, the same counts, episodes, steps and control)")));
                }
            }
            if let Quantity::Learned(_, q) = &c.quantity {
                if !["dos", "doa"].contains(&q.as_str()) && !EVAL_ORDER.contains(&q.as_str()) {
                    return Err(err(
                        "claims",
                        format!("no order parameter named {q:?} (dos, doa or one of {})", EVAL_ORDER.join(", ")),
                    ));
                }
            }
            if let Quantity::Reach90(q) = &c.quantity {
                if !["dos", "doa"].contains(&q.as_str()) {
                    return Err(err("claims", format!("Reach90 takes \"dos\" or \"doa\" (got {q:?})")));
                }
            }
            if let Quantity::Response(e, which) = &c.quantity {
                if !["near", "far"].contains(&which.as_str()) {
                    return Err(err("claims", format!("Response takes \"near\" or \"far\" (got {which:?})")));
                }
                if !spec.evaluations.iter().any(|x| &x.name == e && x.perturb.is_some()) {
                    return Err(err(
                        "claims",
                        format!("Response({e:?}, ..) needs an evaluation {e:?} with perturb: RADIANS"),
                    ));
                }
            }
            if let Quantity::Crossplay(r) = &c.quantity {
                if !crossplay::READOUTS.contains(&r.as_str()) {
                    return Err(err(
                        "claims",
                        format!("no cross-play read-out named {r:?} (one of {})", crossplay::READOUTS.join(", ")),
                    ));
                }
                if spec.crossplay.is_none() {
                    return Err(err("claims", format!("Crossplay({r:?}) needs crossplay: (episodes: N) in the file")));
                }
            }
            if let Quantity::InteractionDoa(e) | Quantity::Interaction(e, _) = &c.quantity {
                if seeing_partner(&spec.evaluations, e).is_none() {
                    return Err(err("claims", format!("evaluation {e:?} needs a control (Blind, Shuffled or a block form) and a seeing evaluation with the same counts, policies, episodes and steps")));
                }
            }
        }
        // The base scene: relative to the working folder, as the project's files say ("scenes/paper.ron"),
        // else to the experiment file's own folder, so a file works from anywhere.
        let beside = file.parent().map(|p| p.join(&spec.base));
        let base = match beside {
            Some(b) if !Path::new(&spec.base).exists() && b.exists() => b,
            _ => PathBuf::from(&spec.base),
        };
        let base_text = crate::io::read_text(&base, crate::scene::MAX_SCENE_BYTES)
            .map_err(|e| err("base", format!("{}: {e}", base.display())))?;
        let root = results.join(&name);
        let mut runs = Vec::new();
        for preset in &spec.presets {
            if !PRESETS.contains(&preset.as_str()) {
                return Err(err("presets", format!("unknown preset {preset:?} (known: {})", PRESETS.join(", "))));
            }
            let base = Scene::parse_with_preset(&base_text, &base.display().to_string(), Some(preset))
                .map_err(|e| err("base", e.to_string()))?;
            for v in &spec.variants {
                let mut scene =
                    base.patched(v.patch.clone()).map_err(|e| err(&format!("variants[{}]", v.name), e.to_string()))?;
                if let Some(episodes) = spec.episodes {
                    scene.episodes = episodes;
                }
                // Each evaluation's scene as `coevo --eval` will make it, checked now rather than after training.
                for e in &spec.evaluations {
                    let mut evaluated = scene.clone();
                    e.overrides()
                        .apply(&mut evaluated, Path::new(&format!("evaluations[{}]", e.name)))
                        .map_err(|m| format!("{shown}: {m}"))?;
                    e.control.resolve(&crate::sim::species::SpeciesRegistry::from_scene(&evaluated)).map_err(|m| {
                        err(&format!("evaluations[{}].control", e.name), format!("variant {}: {m}", v.name))
                    })?;
                }
                let owner = match (&v.shared_from, share) {
                    (Some(from), true) => Some(
                        shared_owner(file, results, from, &spec.evaluations)
                            .map_err(|m| err(&format!("variants[{}].shared_from", v.name), m))?,
                    ),
                    // Loaded as another experiment's owner: its own shared variants are not its runs
                    // (`shared_owner` refuses sharing one of them).
                    (Some(_), false) => continue,
                    (None, _) => None,
                };
                for &seed in &spec.seeds {
                    let mut scene = scene.clone();
                    scene.seed = seed;
                    let (dir, shared_from) = match &owner {
                        None => (root.join(preset).join(slug(&v.name)).join(format!("seed{seed}")), None),
                        Some((exp, variant)) => {
                            let field = format!("variants[{}].shared_from", v.name);
                            let theirs = exp
                                .runs
                                .iter()
                                .find(|r| r.preset == *preset && &r.variant == variant && r.seed == seed)
                                .ok_or_else(|| {
                                    err(
                                        &field,
                                        format!("{}/{variant} has no run of preset {preset} and seed {seed}", exp.name),
                                    )
                                })?;
                            if let Some(line) = first_difference(&theirs.scene.to_ron(), &scene.to_ron()) {
                                return Err(err(
                                    &field,
                                    format!(
                                        "{}/{variant} is another scene (preset {preset}, first difference: {line}); a shared run must be the same run",
                                        exp.name
                                    ),
                                ));
                            }
                            (theirs.dir.clone(), Some(exp.name.clone()))
                        }
                    };
                    runs.push(Run { preset: preset.clone(), variant: v.name.clone(), seed, scene, dir, shared_from });
                }
            }
        }
        Ok(Experiment { name, file: file.to_path_buf(), spec, root, runs })
    }

    /// Every experiment file under `dir`, sorted.
    pub fn files(dir: &Path) -> Result<Vec<PathBuf>> {
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(|e| format!("{}: {e}", dir.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "ron"))
            .collect();
        files.sort();
        Ok(files)
    }
}
