//! Reading an experiment file: every field validated, every run's scene resolved, shared variants
//! checked against their owners, before anything runs; errors are one line naming the file and field.

use super::crossplay_readouts;
use super::file::*;
use crate::error::{Error, Result, ResultExt};
use crate::scene::{parse_ron, Scene, PRESETS};
use std::path::{Path, PathBuf};

/// The experiment and variant a `shared_from` or `same_training_as` names (`"EXPERIMENT/VARIANT"`, the
/// experiment a file beside `file`), loaded without its own shared variants (a variant it shares itself is
/// refused: name the experiment that trains it). A shared variant's evaluations (`ours`) of the same name
/// must be the owner's, since both experiments write them into the same run folders; for a re-training
/// (`ours` None) the owner must not be a declared re-training itself (name the one that trained first).
fn shared_owner(
    file: &Path,
    results: &Path,
    from: &str,
    ours: Option<&[Evaluation]>,
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
                "{experiment}/{variant} is itself shared from {}; name the experiment that trains it",
                v.shared_from.as_deref().unwrap_or_default()
            ))
        }
        Some(v) if ours.is_none() && v.same_training_as.is_some() => {
            return Err(format!(
                "{experiment}/{variant} is itself a re-training of {}; name that one",
                v.same_training_as.as_deref().unwrap_or_default()
            ))
        }
        Some(_) => {}
    }
    for e in ours.unwrap_or_default() {
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
/// The first value seen twice; linear in the list (an experiment may list tens of thousands).
fn first_repeat<T: Eq + std::hash::Hash>(values: &[T]) -> Option<&T> {
    let mut seen = std::collections::HashSet::with_capacity(values.len());
    values.iter().find(|v| !seen.insert(*v))
}

/// The files of an experiment's results folder (`results/NAME/`), named here only.
pub(crate) const SUMMARY: &str = "summary.csv";
pub(crate) const SUMMARY_MEAN: &str = "summary-mean.csv";
pub(crate) const FIGURES: &str = "figures";

impl Experiment {
    /// `results/NAME/summary.csv`: one row per finished run.
    pub(crate) fn summary_path(&self) -> PathBuf {
        self.root.join(SUMMARY)
    }

    /// `results/NAME/figures/`.
    pub(crate) fn figures_dir(&self) -> PathBuf {
        self.root.join(FIGURES)
    }

    /// Every file aggregating and reporting this experiment writes in its results folder (the figures
    /// aside, which are checked by their folder): checked before any run trains, so a folder, a FIFO or
    /// a link where one goes is refused before the work, not after it.
    pub(crate) fn check_outputs(&self) -> Result<()> {
        let files = [
            SUMMARY,
            SUMMARY_MEAN,
            super::carry::FILE,
            super::figure_data::FILE,
            super::registry::FILE,
            super::report::REPORT,
        ];
        crate::io::check_targets(&files.map(|f| self.root.join(f)), crate::io::Existing::Replace)?;
        crate::io::check_own_dir(&self.root)?;
        crate::io::check_own_dir(&self.figures_dir())?;
        Ok(())
    }

    /// Loads an experiment file and resolves every run's scene; errors are one line naming the file and
    /// the field, as for scenes.
    pub fn load(file: &Path, results: &Path) -> Result<Experiment> {
        Experiment::load_with(file, results, true).kind(crate::error::Kind::Experiment)
    }

    /// [`Experiment::load`]; `share` resolves `shared_from` variants (an owner is loaded without, so a
    /// variant shared from a shared variant is refused rather than followed).
    fn load_with(file: &Path, results: &Path, share: bool) -> Result<Experiment> {
        let shown = file.display().to_string();
        let text = crate::io::read_text(file, crate::scene::MAX_SCENE_BYTES)?;
        let mut spec: ExperimentFile = parse_ron(&text, &shown)?;
        for claim in spec.claims.iter_mut().filter(|c| c.family.is_none()) {
            claim.family.clone_from(&spec.family);
        }
        let name = file.file_stem().map_or(String::new(), |s| s.to_string_lossy().into_owned());
        let err = |field: &str, message: String| Error::field(field.to_string(), message).in_file(file);
        // The name is a folder under results/: one safe component, never `.`, `..` or hidden.
        crate::store::check_name(&name)
            .map_err(|m| format!("{shown}: the file name {m}, as it names the folder results/{name}"))?;
        check_lists(&mut spec, file)?;
        check_names(&spec, file)?;
        check_claims(&spec, file)?;
        let (base, base_text) = read_base(&spec, file)?;
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
                // A grid's cell: its levels' patches, axis by axis.
                for level in super::grid::levels_of(&spec.grid, &v.cell) {
                    scene = scene
                        .patched(level.patch.clone())
                        .map_err(|e| err(&format!("grid[{}]", v.name), e.to_string()))?;
                }
                if let Some(episodes) = spec.episodes {
                    scene.episodes = episodes;
                }
                check_evaluation_scenes(&spec, &scene, &v.name, file)?;
                check_distill(&spec, &scene, &v.name, file)?;
                let field = |name: &str| format!("variants[{}].{name}", v.name);
                if v.shared_from.is_some() && v.same_training_as.is_some() {
                    return Err(err(
                        &field("same_training_as"),
                        "a variant is shared (shared_from) or re-trained (same_training_as), not both".into(),
                    ));
                }
                if v.kernels.is_some() && (v.shared_from.is_some() || v.same_training_as.is_some()) {
                    return Err(err(
                        &field("kernels"),
                        "a shared or re-trained variant's runs are another's, on that one's kernels".into(),
                    ));
                }
                let owner = match (&v.shared_from, share) {
                    (Some(from), true) => Some(
                        shared_owner(file, results, from, Some(&spec.evaluations))
                            .map_err(|m| err(&field("shared_from"), m))?,
                    ),
                    // Loaded as another experiment's owner: its own shared variants are not its runs
                    // (`shared_owner` refuses sharing one of them).
                    (Some(_), false) => continue,
                    (None, _) => None,
                };
                // A declared re-training is checked as a shared run is: the owner's run of each seed, the
                // same scene. Not followed when this file is loaded as an owner itself.
                let retrained = match (&v.same_training_as, share) {
                    (Some(of), true) => {
                        Some(shared_owner(file, results, of, None).map_err(|m| err(&field("same_training_as"), m))?)
                    }
                    _ => None,
                };
                for &seed in &spec.seeds {
                    let mut scene = scene.clone();
                    scene.seed = seed;
                    // The owner's run of this preset and seed, which must be this very scene.
                    let same_run = |(exp, variant): &(Experiment, String), name: &str| -> Result<PathBuf> {
                        let theirs = exp
                            .runs
                            .iter()
                            .find(|r| r.preset == *preset && &r.variant == variant && r.seed == seed)
                            .ok_or_else(|| {
                                err(
                                    &field(name),
                                    format!("{}/{variant} has no run of preset {preset} and seed {seed}", exp.name),
                                )
                            })?;
                        if let Some(line) = first_difference(&theirs.scene.to_ron(), &scene.to_ron()) {
                            return Err(err(
                                &field(name),
                                format!(
                                    "{}/{variant} is another scene (preset {preset}, first difference: {line}); a {} run must be the same run",
                                    exp.name,
                                    if name == "shared_from" { "shared" } else { "re-trained" }
                                ),
                            ));
                        }
                        Ok(theirs.dir.clone())
                    };
                    if let Some(of) = &retrained {
                        same_run(of, "same_training_as")?;
                    }
                    let (dir, shared_from) = match &owner {
                        None => (root.join(preset).join(slug(&v.name)).join(format!("seed{seed}")), None),
                        Some(o) => (same_run(o, "shared_from")?, Some(o.0.name.clone())),
                    };
                    runs.push(Run {
                        preset: preset.clone(),
                        variant: v.name.clone(),
                        seed,
                        scene,
                        dir,
                        shared_from,
                        same_training_as: v.same_training_as.clone(),
                        kernels: v.kernels,
                    });
                }
            }
        }
        check_authors_curves(&spec, &runs, file)?;
        let pin = super::pin::Pin::read(&root)?;
        Ok(Experiment { name, file: file.to_path_buf(), spec, root, runs, pin })
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

/// The base scene's path and text: relative to the working folder, as the project's files say
/// ("scenes/paper.ron"), else to the experiment file's own folder, so a file works from anywhere.
fn read_base(spec: &ExperimentFile, file: &Path) -> Result<(PathBuf, String)> {
    let beside = file.parent().map(|p| p.join(&spec.base));
    let base = match beside {
        Some(b) if !Path::new(&spec.base).exists() && b.exists() => b,
        _ => PathBuf::from(&spec.base),
    };
    let text = crate::io::read_text(&base, crate::scene::MAX_SCENE_BYTES)
        .map_err(|e| refuse(file)("base", format!("{}: {}", base.display(), e.message)))?;
    Ok((base, text))
}

/// The experiment file's field `field` refused with `message`, in `file`.
fn refuse(file: &Path) -> impl Fn(&str, String) -> Error + '_ {
    move |field: &str, message: String| Error::field(field.to_string(), message).in_file(file)
}

/// Presets, seeds, episodes, the grid's cells and the variants: each list present and without repeats.
fn check_lists(spec: &mut ExperimentFile, file: &Path) -> Result<()> {
    let err = refuse(file);
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
        return Err(err("seeds", format!("seed {s} appears twice (a run of the same scene and seed is the same run)")));
    }
    if spec.episodes == Some(0) {
        return Err(err("episodes", "must be ≥ 1".into()));
    }
    super::grid::expand(spec).map_err(|(field, message)| err(&field, message))?;
    if spec.variants.is_empty() {
        return Err(err("variants", "an experiment needs at least one variant (listed, or a grid's cells)".into()));
    }
    // Checked here, before anything is trained: a run would fail only at its cross-play.
    if let Some(c) = spec.crossplay.as_ref().filter(|c| c.episodes == 0) {
        return Err(err("crossplay.episodes", format!("must be ≥ 1 (got {})", c.episodes)));
    }
    Ok(())
}

/// Variant and evaluation names, which become folders, file names, CSV fields and figure labels; and each
/// evaluation's own fields.
fn check_names(spec: &ExperimentFile, file: &Path) -> Result<()> {
    let err = refuse(file);
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
    // Folders and files already named, by slug: each name is checked against a set, so loading stays
    // linear in the file's size.
    let mut folders = std::collections::HashSet::with_capacity(spec.variants.len());
    for v in &spec.variants {
        let field = format!("variants[{}].name", v.name);
        let folder = slug(&v.name);
        crate::store::check_name(&folder)
            .map_err(|m| err(&field, format!("as a folder name ({folder:?}) it {m}; use letters or digits")))?;
        if !folders.insert(folder.clone()) {
            return Err(err(&field, format!("names the same folder ({folder:?}) as another variant")));
        }
    }
    let mut files = std::collections::HashSet::with_capacity(spec.evaluations.len());
    for e in &spec.evaluations {
        let field = |f: &str| format!("evaluations[{}].{f}", e.name);
        let file = crate::store::evaluation_file_name(&slug(&e.name));
        if slug(&e.name).is_empty() {
            return Err(err(&field("name"), "needs a letter or digit".into()));
        }
        crate::store::RunDir::new(".")
            .eval_output(Some(&file))
            .map_err(|m| err(&field("name"), m.to_string().replacen("--eval-out ", "as the file ", 1)))?;
        if !files.insert(slug(&e.name)) {
            return Err(err(&field("name"), format!("names the same file ({file}) as another evaluation")));
        }
        if e.episodes == 0 || e.steps == Some(0) {
            return Err(err(&field("episodes"), "episodes and steps must be ≥ 1".into()));
        }
        if !e.distilled.is_empty() && spec.distill.is_none() {
            return Err(err(
                &field("distilled"),
                "deploys fitted rules: the file needs distill: (counts: [...], episodes: N)".into(),
            ));
        }
        if let Some(u) = e.distilled.iter().find(|u| e.policies.iter().any(|(s, _)| s == &u.species)) {
            return Err(err(&field("distilled"), format!("{:?} is given a policy too (policies:)", u.species)));
        }
        if let Some(r) = e.confusion_radius.filter(|r| !(r.is_finite() && *r > 0.0)) {
            return Err(err(&field("confusion_radius"), format!("must be a finite number of metres > 0 (got {r})")));
        }
    }
    Ok(())
}

/// Each claim: cited by a text of its own, its family, hypothesis and scale, the variants it compares, and
/// what its quantity needs of the file (evaluations, partners, fitted rules, cross-play, a tolerance).
fn check_claims(spec: &ExperimentFile, file: &Path) -> Result<()> {
    let err = refuse(file);
    let variants: std::collections::HashMap<&String, &VariantFile> =
        spec.variants.iter().map(|v| (&v.name, v)).collect();
    let mut texts = std::collections::HashSet::with_capacity(spec.claims.len());
    for c in &spec.claims {
        // A claim is cited by its text (REPRODUCTION.md's rows, the book's citations): one row per text.
        if !texts.insert(&c.text) {
            return Err(err("claims", format!("{:?} is the text of two claims", c.text)));
        }
        if c.family.as_ref().is_some_and(|f| f.trim().is_empty()) {
            return Err(err("claims", format!("{:?}: family must name a family (got an empty name)", c.text)));
        }
        if c.ours && !(c.direction_only && c.paper.is_some()) {
            return Err(err(
                "claims",
                format!(
                    "{:?}: ours is a direction of the project's, so it needs direction_only and the sign in paper",
                    c.text
                ),
            ));
        }
        if c.scale != super::file::Scale::Linear && (!super::results::is_effect(c) || c.margin.is_some()) {
            return Err(err(
                "claims",
                format!("{:?}: a scale other than Linear is for an effect tested for a direction (not a level, not an equivalence margin)", c.text),
            ));
        }
        if let Some(v) = c.paper.filter(|v| !v.is_finite()) {
            return Err(err("claims", format!("{:?}: paper must be a finite number (got {v})", c.text)));
        }
        if let Some(test) = &c.grid {
            let what = "a claim over the grid reads its cells: no variant, versus or baseline";
            if !c.variant.is_empty() || c.versus.is_some() || c.baseline.is_some() {
                return Err(err("claims", format!("{:?}: {what}", c.text)));
            }
            super::grid::along(spec, test).map_err(|m| err("claims", format!("{:?}: grid: {m}", c.text)))?;
            if !matches!(test, GridTest::Trend { .. }) && (c.margin.is_some() || c.scale != Scale::Linear) {
                return Err(err(
                    "claims",
                    format!(
                        "{:?}: a boundary and its shift are bootstrap tests: no margin or scale (a trend takes them)",
                        c.text
                    ),
                ));
            }
        }
        for v in std::iter::once(&c.variant).chain(&c.versus).filter(|_| c.grid.is_none()) {
            if !variants.contains_key(v) {
                return Err(err("claims", format!("no variant named {v:?}")));
            }
        }
        if c.versus.as_ref() == Some(&c.variant) {
            return Err(err("claims", format!("{:?} is compared with itself (versus)", c.text)));
        }
        if let Some(versus) = &c.versus {
            let source = |name: &String| variants.get(name).and_then(|v| v.shared_from.clone());
            if let Some(shared) = source(&c.variant).filter(|s| Some(s) == source(versus).as_ref()) {
                return Err(err(
                    "claims",
                    format!("{:?} compares runs with themselves: both variants are shared from {shared}", c.text),
                ));
            }
        }
        check_quantity(c, spec, file)?;
        let level = !super::results::is_effect(c);
        match c.tolerance {
            Some(t) if !(level && c.paper.is_some() && t.is_finite() && t > 0.0) => {
                return Err(err(
                    "claims",
                    format!(
                        "{:?}: tolerance is for a level with the paper's value, a positive number (got {t})",
                        c.text
                    ),
                ));
            }
            None if level && c.paper.is_some() && super::verdict::tolerance(c).is_none() => {
                return Err(err(
                    "claims",
                    format!(
                        "{:?}: a level with the paper's value needs a tolerance (DoS and DoA levels have one by rule)",
                        c.text
                    ),
                ));
            }
            _ => {}
        }
    }
    Ok(())
}

/// What a claim's quantity needs of the file: the evaluations it reads (with their perturbation, control
/// or untrained partners), an order parameter it takes, the curves it takes, the fitted rules and the
/// cross-play it reads.
fn check_quantity(c: &Claim, spec: &ExperimentFile, file: &Path) -> Result<()> {
    let err = refuse(file);
    if let Quantity::Response(e, which) = &c.quantity {
        if !["near", "far"].contains(&which.as_str()) {
            return Err(err("claims", format!("Response takes \"near\" or \"far\" (got {which:?})")));
        }
        if !spec.evaluations.iter().any(|x| &x.name == e && x.perturb.is_some()) {
            return Err(err("claims", format!("Response({e:?}, ..) needs an evaluation {e:?} with perturb: RADIANS")));
        }
    }
    for e in c.quantity.evaluations() {
        if !spec.evaluations.iter().any(|x| x.name == e) {
            return Err(err("claims", format!("no evaluation named {e:?}")));
        }
    }
    if let Some((q, takes)) = c.quantity.named_order().filter(|(q, takes)| !takes(*q)) {
        let taken: Vec<&str> = Order::ALL.into_iter().filter(|o| takes(*o)).map(Order::name).collect();
        return Err(err("claims", format!("{q:?} is not taken here (one of {})", taken.join(", "))));
    }
    if let Quantity::Learned(e, _) | Quantity::TacticLearned(e, _) = &c.quantity {
        if untrained_partner(&spec.evaluations, e).is_none() {
            return Err(err("claims", format!("evaluation {e:?} needs an untrained partner (untrained: true, the same counts, episodes, steps and control)")));
        }
    }
    if let Quantity::EvalDifference(a, b, _) = &c.quantity {
        if a == b {
            return Err(err("claims", format!("EvalDifference({a:?}, {b:?}, ..) compares an evaluation with itself")));
        }
    }
    if let Some(message) = c.quantity.curve_argument_error() {
        return Err(err("claims", message));
    }
    if let Quantity::DistilledDifference(_, a, b, _) = &c.quantity {
        if a == b {
            return Err(err(
                "claims",
                format!("DistilledDifference(.., {a:?}, {b:?}, ..) compares a form with itself"),
            ));
        }
    }
    if let Quantity::Distilled(_, _, name) | Quantity::DistilledDifference(_, _, _, name) = &c.quantity {
        if spec.distill.is_none() {
            return Err(err(
                "claims",
                format!("Distilled(.., {name:?}) needs distill: (counts: [...], episodes: N) in the file"),
            ));
        }
        let known = super::distill::names();
        if !known.contains(name) {
            return Err(err("claims", format!("Distilled: no number named {name:?} (one of {})", known.join(", "))));
        }
    }
    if let Quantity::Crossplay(r) = &c.quantity {
        if !crossplay_readouts::READOUTS.contains(&r.as_str()) {
            return Err(err(
                "claims",
                format!("no cross-play read-out named {r:?} (one of {})", crossplay_readouts::READOUTS.join(", ")),
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
    Ok(())
}

/// Each evaluation's scene as `coevo --eval` will make it from variant `variant`'s `scene`, checked now
/// rather than after training: its overrides, its control and the rules it deploys.
fn check_evaluation_scenes(spec: &ExperimentFile, scene: &Scene, variant: &str, file: &Path) -> Result<()> {
    let err = refuse(file);
    let shown = file.display().to_string();
    // Each evaluation's scene as `coevo --eval` will make it, checked now rather than after training.
    for e in &spec.evaluations {
        let mut evaluated = scene.clone();
        e.overrides()
            .apply(&mut evaluated, Path::new(&format!("evaluations[{}]", e.name)))
            .map_err(|m| format!("{shown}: {m}"))?;
        let registry = crate::sim::species::SpeciesRegistry::from_scene(&evaluated);
        e.control
            .resolve(&registry)
            .map_err(|m| err(&format!("evaluations[{}].control", e.name), format!("variant {}: {m}", variant)))?;
        for u in &e.distilled {
            let Some(s) = registry.defs.iter().position(|d| d.name == u.species) else {
                return Err(err(
                    &format!("evaluations[{}].distilled", e.name),
                    format!("variant {}: no species named {:?}", variant, u.species),
                ));
            };
            let zonal = matches!(super::distill::rule_for(&registry, s), Some(crate::scene::Policy::Zonal(_)));
            if !u.without.is_empty() && !zonal {
                return Err(err(
                    &format!("evaluations[{}].distilled", e.name),
                    format!(
                        "without: ablates a zonal rule, fitted to a species with predators; {:?} has none",
                        u.species
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// What `distill:` will fit on variant `variant`'s runs (of `scene`): every species, form and number that an
/// evaluation deploys or a claim reads must be one of them, else it would be judged never.
fn check_distill(spec: &ExperimentFile, scene: &Scene, variant: &str, file: &Path) -> Result<()> {
    let err = refuse(file);
    // What `distill:` will fit on this variant's runs: every species, form and number that an
    // evaluation deploys or a claim reads must be one of them, else it would be judged never.
    if let Some(d) = &spec.distill {
        let mut fitted_on = scene.clone();
        d.overrides()
            .apply(&mut fitted_on, Path::new("distill"))
            .map_err(|m| err("distill", format!("variant {}: {m}", variant)))?;
        let rules = super::distill::rules(&fitted_on, &d.forms);
        let fitted: Vec<&str> = rules.iter().map(|(s, _, _)| s.as_str()).collect();
        let listed = if fitted.is_empty() { "none".to_string() } else { fitted.join(", ") };
        for e in &spec.evaluations {
            for (k, u) in e.distilled.iter().enumerate() {
                let at = format!("evaluations[{}].distilled", e.name);
                if !fitted.contains(&u.species.as_str()) {
                    return Err(err(
                        &at,
                        format!(
                            "variant {}: no rule is fitted to {:?} (a learned species with prey or predators; here: {listed})",
                            variant, u.species
                        ),
                    ));
                }
                if !rules.iter().any(|(s, f, _)| *s == u.species && *f == u.form) {
                    return Err(err(
                        &at,
                        format!(
                            "{:?}: form {:?} is not read: list it in distill's forms (here: {:?})",
                            u.species, u.form, d.forms
                        ),
                    ));
                }
                if e.distilled[..k].iter().any(|o| o.species == u.species) {
                    return Err(err(
                        &at,
                        format!("{:?} is listed twice: which rule is deployed is ambiguous", u.species),
                    ));
                }
                if let Some((_, t)) = u.without.iter().enumerate().find(|&(j, t)| u.without[..j].contains(t)) {
                    return Err(err(&at, format!("{:?}: without: lists {t:?} twice", u.species)));
                }
            }
        }
        let read = spec.claims.iter().flat_map(|c| c.quantity.rules_read());
        for (species, form, name) in read {
            let Some((_, _, names)) = rules.iter().find(|(s, f, _)| s == species && *f == form) else {
                return Err(err(
                    "claims",
                    format!(
                        "Distilled({species:?}, {form:?}, ..): variant {}: no {form:?} rule is read of {species:?} (rules are fitted to: {listed}; forms read: {:?})",
                        variant, d.forms
                    ),
                ));
            };
            if !names.iter().any(|n| n == name) {
                return Err(err(
                    "claims",
                    format!(
                        "Distilled({species:?}, {form:?}, {name:?}): the rule fitted to {species:?} has no such number (one of {})",
                        names.join(", ")
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// A claim on the authors' DoS or DoA needs runs that measure them: refused now, not after training.
fn check_authors_curves(spec: &ExperimentFile, runs: &[Run], file: &Path) -> Result<()> {
    let err = refuse(file);
    // A claim on the authors' DoS or DoA needs runs that measure them: refused now, not after training.
    for c in &spec.claims {
        let Some(q) = c.quantity.authors_curve() else { continue };
        let compared = std::iter::once(&c.variant).chain(c.versus.as_ref());
        if let Some(v) =
            compared.into_iter().find(|v| runs.iter().any(|r| &r.variant == *v && !r.scene.authors_metrics))
        {
            return Err(err(
                "claims",
                format!(
                    "{:?} reads {q}, which variant {v:?} does not measure (authors_metrics: true in its patch or the base scene)",
                    c.text
                ),
            ));
        }
    }
    Ok(())
}
