//! Runs an experiment's runs, `jobs` at a time, each as a `coevo` child process on its share of the cores
//! (cores / jobs threads; the number of threads never changes a result): train (or
//! resume a killed run from its checkpoint, or skip a finished one), then its evaluations. Everything a
//! child writes is atomic or checkpointed, so the experiment can be killed at any moment and run again
//! to continue; no finished run is redone.

use super::file::{eval_file, Experiment, Run};
use super::pin::Executable;
use indicatif::{ProgressBar, ProgressStyle};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

pub(crate) struct RunnerOptions {
    /// `--pinned-binary`: a build of a pinned experiment's commit to make its runs with (checked by its
    /// fingerprint, [`super::pin`]) instead of a rebuild.
    pub(crate) pinned_binary: Option<PathBuf>,
    /// Runs at a time.
    pub(crate) jobs: usize,
    pub(crate) progress: bool,
}

/// Where a run folder stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Stage {
    /// Nothing yet.
    Fresh,
    /// Started, killed before its first checkpoint: started again.
    Unsaved,
    /// Checkpointed part of the way: resumed.
    Partial(usize),
    /// All episodes trained.
    Trained,
}

/// The variant's resolved scene file, which fresh runs are trained from.
fn variant_scene(run: &Run) -> PathBuf {
    run.dir.parent().expect("runs live in a variant folder").join(crate::store::SCENE)
}

/// The stage of a run, and a refusal when its folder holds a run of another scene (the experiment file
/// changed under it: coevo never mixes the two).
pub(crate) fn stage(run: &Run) -> crate::error::Result<Stage> {
    if !crate::store::is_run(&run.dir) {
        return Ok(Stage::Fresh);
    }
    let shown = run.dir.display();
    let state = crate::store::RunDir::new(&run.dir).state();
    if !state.exists() {
        return Ok(Stage::Unsaved);
    }
    let state = crate::store::checkpoint::read_state(&state)?;
    let mut theirs = state.scene.clone();
    theirs.episodes = run.scene.episodes;
    if theirs != run.scene {
        return Err(
            format!("{shown}: holds a run of another scene than the experiment's; move it away to rerun it").into()
        );
    }
    Ok(if state.episodes_done >= run.scene.episodes { Stage::Trained } else { Stage::Partial(state.episodes_done) })
}

/// Episodes `run` has left to train: its scene's, less those its checkpoint holds.
fn episodes_left(run: &Run) -> crate::error::Result<usize> {
    Ok(match stage(run)? {
        Stage::Trained => 0,
        Stage::Partial(done) => run.scene.episodes.saturating_sub(done),
        Stage::Fresh | Stage::Unsaved => run.scene.episodes,
    })
}

/// Episodes a probe trains, at most (fewer when the runs are shorter).
const PROBE_EPISODES: usize = 10;

/// Seconds per episode of `run`'s scene trained by `exe` for a few episodes, and how many: `copies` of it
/// side by side on `threads` threads each, as the runs will be made (runs side by side share the cores'
/// memory and are slower than one alone), in folders of the experiment's removed after
/// ([`super::estimate`]).
fn probe(
    exp: &Experiment,
    run: &Run,
    exe: &Executable,
    threads: usize,
    copies: usize,
) -> crate::error::Result<(f64, usize)> {
    let episodes = PROBE_EPISODES.min(run.scene.episodes).max(1);
    let timed = |k: usize| -> crate::error::Result<f64> {
        let dir = exp.root.join(format!(".probe-{k}"));
        let _ = std::fs::remove_dir_all(&dir);
        let opts = crate::run::train::TrainOptions::new(dir.clone(), Some(episodes));
        let start = crate::run::train::StartArgs::New { scene: &variant_scene(run), seed: run.seed };
        let args = [opts.to_argv(start), crate::run::args::threads_argv(threads)].concat();
        let started = std::time::Instant::now();
        let made = child(exe, &args);
        let seconds = started.elapsed().as_secs_f64();
        let _ = std::fs::remove_dir_all(&dir);
        made.map_err(|e| format!("{}: timing a probe of {episodes} episodes: {e}", exp.file.display()))?;
        Ok(seconds)
    };
    let copies = copies.max(1);
    let seconds: Vec<crate::error::Result<f64>> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..copies).map(|k| scope.spawn(move || timed(k))).collect();
        handles.into_iter().map(|h| h.join().unwrap_or_else(|_| Err("a probe's thread panicked".into()))).collect()
    });
    let mut total = 0.0;
    for s in seconds {
        total += s?;
    }
    Ok((total / copies as f64 / episodes as f64, episodes))
}

/// Runs one child process; Err is its one-line error.
fn child(exe: &Executable, args: &[String]) -> crate::error::Result<()> {
    let mut command = Command::new(&exe.path);
    command.args(args);
    // Every run of an experiment on one kernel family: the pinned one, or the parent's, whatever pinned it.
    command.env("COEVO_KERNELS", &exe.kernels);
    dies_with_parent(&mut command);
    let out = command.output().map_err(|e| format!("{}: cannot start: {e}", exe.path.display()))?;
    if out.status.success() {
        // A child that succeeds may still warn (a resume that refills dropped buffers): pass it on.
        for line in String::from_utf8_lossy(&out.stderr).lines().filter(|l| l.starts_with("coevo: warning: ")) {
            crate::errln!("{line}")?;
        }
        Ok(())
    } else {
        let stderr = String::from_utf8_lossy(&out.stderr);
        Err(stderr.lines().rev().find(|l| !l.trim().is_empty()).unwrap_or("failed without a message").into())
    }
}

/// Makes a child end when the runner ends, also by SIGKILL: the kernel sends it SIGTERM (on which it
/// removes its temporaries and its run's lock), so no orphan keeps writing into `results/` while a re-run
/// starts on the same folders.
fn dies_with_parent(command: &mut Command) {
    // Linux only: other systems have no parent-death signal, and a child there outlives a killed runner
    // (it still finishes its run, which the next call carries or resumes).
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::process::CommandExt;
        let parent = std::process::id();
        // SAFETY: only async-signal-safe calls between fork and exec.
        unsafe {
            command.pre_exec(move || {
                if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
                // The parent died before the line above: nobody would ever send the signal.
                if libc::getppid() as u32 != parent {
                    libc::_exit(1);
                }
                Ok(())
            });
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = command;
}

/// Trains (or resumes) one run and runs its missing evaluations, on `threads` threads (results do not
/// depend on it).
pub(crate) fn complete_run(exp: &Experiment, run: &Run, exe: &Executable, threads: usize) -> crate::error::Result<()> {
    let dir = run.dir.to_string_lossy().into_owned();
    // A variant on its own kernel family (`kernels:`) is trained and evaluated on it.
    let own;
    let exe = match &run.kernels {
        Some(family) => {
            own = Executable { kernels: family.name().into(), ..exe.clone() };
            &own
        }
        None => exe,
    };
    let threads = crate::run::args::threads_argv(threads.max(1));
    use crate::run::train::{StartArgs, TrainOptions};
    let scene = variant_scene(run);
    let new = StartArgs::New { scene: &scene, seed: run.seed };
    let train = match stage(run)? {
        Stage::Trained => None,
        Stage::Partial(_) => Some((TrainOptions::new(run.dir.clone(), Some(run.scene.episodes)), StartArgs::Resume)),
        s @ (Stage::Fresh | Stage::Unsaved) => {
            Some((TrainOptions { overwrite: s == Stage::Unsaved, ..TrainOptions::new(run.dir.clone(), None) }, new))
        }
    };
    if let Some((opts, start)) = train {
        let args = [opts.to_argv(start), threads.clone()].concat();
        child(exe, &args).map_err(|e| format!("{dir}: {e}"))?;
    }
    drop_replay(exp, run)?;
    let distilled = crate::store::RunDir::new(&run.dir).distilled();
    // Rules fitted as an earlier `distill:` asked (an edited file) are fitted again, as an edited
    // evaluation is run again: the evaluations that deployed them go first, then the rules, so a kill in
    // between leaves nothing that passes for current.
    if exp.spec.distill.as_ref().is_some_and(|d| distill_stale(run, d).is_some()) {
        for e in exp.spec.evaluations.iter().filter(|e| !e.distilled.is_empty()) {
            let out = eval_file(&run.dir, &e.name);
            if out.exists() {
                std::fs::remove_file(&out).map_err(|err| format!("{}: {err}", out.display()))?;
            }
        }
        std::fs::remove_file(&distilled).map_err(|err| format!("{}: {err}", distilled.display()))?;
    }
    // Rules are fitted for the evaluations that deploy them and for the claims that read their numbers.
    let needs_rules = exp.spec.evaluations.iter().any(|e| !e.distilled.is_empty() && !evaluated_as(run, e))
        || (claims_read_rules(exp) && !distilled.exists());
    if let (Some(d), true) = (&exp.spec.distill, needs_rules && !distilled.exists()) {
        let mut argv = vec!["--distill".into(), dir.clone(), "--episodes".into(), d.episodes.to_string()];
        argv.extend(crate::run::args::overrides_argv(&d.overrides(), &[]));
        child(exe, &[argv, threads.clone()].concat()).map_err(|err| format!("{dir}: distilling: {err}"))?;
    }
    for e in &exp.spec.evaluations {
        let out = eval_file(&run.dir, &e.name);
        if evaluated_as(run, e) {
            continue;
        }
        // An evaluation run again (stale, or killed part-way): its old side files go first, the confusion
        // curve (the mark of a complete evaluation) before the rest, so a child killed before it writes
        // them anew never leaves a new CSV beside old curves that would pass for complete.
        for stem in ["confusion", "nn", "correlation", crate::store::PERTURBATION] {
            let side = crate::io::beside(&out, stem);
            if side.exists() {
                std::fs::remove_file(&side).map_err(|err| format!("{}: {err}", side.display()))?;
            }
        }
        let opts = crate::run::evaluate::EvalOptions {
            run: run.dir.clone(),
            control: e.control.clone(),
            out: Some(out.file_name().expect("a file").to_string_lossy().into_owned()),
            episodes: e.episodes,
            overrides: with_distilled(e, &distilled)?,
            untrained: e.untrained,
            snapshots: vec![],
            perturb: e.perturb,
            perturb_step: e.perturb_step,
        };
        child(exe, &[opts.to_argv(), threads.clone()].concat())
            .map_err(|err| format!("{dir}: evaluation {}: {err}", e.name))?;
    }
    if let Some(c) = exp.spec.crossplay.as_ref().filter(|_| !crossplayed(run)) {
        let opts = crate::experiment::crossplay::CrossplayOptions {
            run: run.dir.clone(),
            episodes: c.episodes,
            overrides: Default::default(),
            progress: false,
        };
        child(exe, &[opts.to_argv(), threads].concat()).map_err(|err| format!("{dir}: cross-play: {err}"))?;
    }
    Ok(())
}

/// An evaluation's overrides with the rules it deploys (`distilled:`) read from the run's `distilled`
/// file, ablated as it asks.
fn with_distilled(e: &super::file::Evaluation, distilled: &Path) -> crate::error::Result<crate::scene::Overrides> {
    use crate::scene::Policy;
    let mut overrides = e.overrides();
    if e.distilled.is_empty() {
        return Ok(overrides);
    }
    let file = super::distill::DistilledFile::read(distilled)?;
    for u in &e.distilled {
        let policy = match (file.policy(&u.species, u.form), u.without.is_empty()) {
            (Some(Policy::Zonal(rule)), _) => Policy::Zonal(rule.without(&u.without)),
            (Some(Policy::Binned(rule)), _) => Policy::Binned(rule.without(&u.without)),
            (Some(p), true) => p.clone(),
            (Some(_), false) => {
                return Err(format!(
                    "evaluation {:?}: without: applies to a zonal rule; {}'s is not",
                    e.name, u.species
                )
                .into())
            }
            (None, _) => {
                return Err(format!("{}: no {:?} rule fitted for {:?}", distilled.display(), u.form, u.species).into())
            }
        };
        overrides.policies.push((u.species.clone(), policy));
    }
    Ok(overrides)
}

/// Removes a trained run's replay buffers (`store::replay_segments::drop_replay`) under its lock, unless the
/// experiment keeps them. A shared run's buffers are its owner's to keep or drop.
fn drop_replay(exp: &Experiment, run: &Run) -> crate::error::Result<()> {
    if exp.spec.keep_replay || run.shared_from.is_some() || stage(run)? != Stage::Trained {
        return Ok(());
    }
    let dir = crate::store::RunDir::new(&run.dir);
    let _lock = dir.lock()?;
    crate::store::replay_segments::drop_replay(&run.dir)
        .map_err(|e| format!("{}: cannot remove the trained run's replay buffers: {e}", run.dir.display()))?;
    Ok(())
}

/// Whether a run's cross-play is complete (its read-outs are written last).
fn crossplayed(run: &Run) -> bool {
    crate::store::RunDir::new(&run.dir).crossplay(crate::store::CROSSPLAY_READOUTS).exists()
}

/// Whether a run is trained and has every evaluation (and its cross-play, when asked), with its rules fitted as
/// the file's `distill:` asks now.
pub(crate) fn finished(exp: &Experiment, run: &Run) -> bool {
    stage(run) == Ok(Stage::Trained)
        && exp.spec.evaluations.iter().all(|e| evaluated_as(run, e))
        && exp.spec.distill.as_ref().is_none_or(|d| distill_stale(run, d).is_none())
        && (!claims_read_rules(exp) || crate::store::RunDir::new(&run.dir).distilled().exists())
        && (exp.spec.crossplay.is_none() || crossplayed(run))
}

/// Whether a claim reads a number of the fitted rules (`Distilled(...)`): then every run needs its
/// `distilled.ron`, whether or not an evaluation deploys the rules.
fn claims_read_rules(exp: &Experiment) -> bool {
    exp.spec.distill.is_some() && exp.spec.claims.iter().any(|c| c.quantity.reads_rules())
}

/// Whether an evaluation's files are complete: its per-step CSV and, written last, its confusion curve
/// (evaluations by a coevo without the collective measures lack it and are run again).
fn evaluated(eval_csv: &Path) -> bool {
    eval_csv.exists() && crate::io::beside(eval_csv, "confusion").exists()
}

/// Whether an evaluation is complete, with its perturbation response when it asks for one, and made with
/// the episodes and steps the experiment file asks for now (else it is run again).
fn evaluated_as(run: &Run, e: &super::file::Evaluation) -> bool {
    let eval_csv = eval_file(&run.dir, &e.name);
    evaluated(&eval_csv)
        && (e.perturb.is_none() || crate::io::beside(&eval_csv, crate::store::PERTURBATION).exists())
        && stale(run, e).is_none()
}

/// The first evaluation or fit of the experiment's trained runs that is stale ([`stale`],
/// [`distill_stale`]), if any.
pub(crate) fn first_stale(exp: &Experiment) -> Option<String> {
    let trained = || exp.runs.iter().filter(|r| stage(r) == Ok(Stage::Trained));
    let refit = exp.spec.distill.as_ref().and_then(|d| trained().find_map(|r| distill_stale(r, d)));
    refit.or_else(|| {
        trained().flat_map(|r| exp.spec.evaluations.iter().map(move |e| (r, e))).find_map(|(r, e)| stale(r, e))
    })
}

/// How the rules fitted to a run (`distilled.ron`) differ from what the file's `distill:` asks for now
/// (an edited file: other counts, episodes or steps); None when they match or none are fitted yet.
pub(crate) fn distill_stale(run: &Run, d: &super::file::DistillSpec) -> Option<String> {
    let path = crate::store::RunDir::new(&run.dir).distilled();
    if !path.exists() {
        return None;
    }
    let Ok(file) = super::distill::DistilledFile::read(&path) else {
        return Some(format!("{}: unreadable, fitted again", path.display()));
    };
    let mut scene = run.scene.clone();
    d.overrides().apply(&mut scene, &path).ok()?;
    let counts: Vec<(String, usize)> = scene.species.iter().map(|s| (s.name.clone(), s.count)).collect();
    let asked = (&counts, d.episodes, scene.episode_steps);
    (asked != (&file.counts, file.episodes, file.steps)).then(|| {
        format!(
            "{}: fitted on {} episodes of {} steps with {:?}, distill: asks for {} of {} with {:?}",
            path.display(),
            file.episodes,
            file.steps,
            file.counts,
            asked.1,
            asked.2,
            asked.0
        )
    })
}

/// How an existing evaluation differs from what the experiment file asks for now (an edited file: its
/// episodes or steps changed), from the last row of its per-step CSV; None when it matches.
pub(crate) fn stale(run: &Run, e: &super::file::Evaluation) -> Option<String> {
    let path = eval_file(&run.dir, &e.name);
    // Only the last row counts: read the file's tail (a per-step CSV runs to megabytes, and every run's
    // evaluations are checked each time an experiment starts).
    let tail = {
        use std::io::{Read, Seek, SeekFrom};
        let mut file = crate::io::open_input(&path).ok()?;
        let len = file.metadata().ok()?.len();
        file.seek(SeekFrom::Start(len.saturating_sub(4096))).ok()?;
        let mut bytes = Vec::new();
        file.read_to_end(&mut bytes).ok()?;
        String::from_utf8_lossy(&bytes).into_owned()
    };
    let last = tail.lines().rev().find(|l| !l.trim().is_empty())?;
    let mut cells = last.split(',').map(|c| c.parse::<usize>().ok());
    let held = (cells.next().flatten().map(|episode| episode + 1), cells.next().flatten());
    let asked = (e.episodes, e.steps.unwrap_or(run.scene.episode_steps));
    (held != (Some(asked.0), Some(asked.1))).then(|| {
        let shown = |n: Option<usize>| n.map_or("?".to_string(), |n| n.to_string());
        format!(
            "{}: holds {} episodes of {} steps, the evaluation {:?} asks for {} of {}",
            path.display(),
            shown(held.0),
            shown(held.1),
            e.name,
            asked.0,
            asked.1
        )
    })
}

/// Writes every variant's resolved scene (the seed is set per run), refusing runs of other scenes first.
fn prepare(exp: &Experiment) -> crate::error::Result<()> {
    for run in &exp.runs {
        stage(run)?;
    }
    for run in exp.runs.iter().filter(|r| r.seed == exp.spec.seeds[0]) {
        let path = variant_scene(run);
        // A shared run's folder is its owner's: its scene file is the owner's to write (the same scene),
        // written here only when the owner has not run yet.
        if run.shared_from.is_some() && path.exists() {
            continue;
        }
        std::fs::create_dir_all(path.parent().expect("in a folder")).map_err(|e| format!("{}: {e}", path.display()))?;
        crate::io::write_file(&path, crate::io::Existing::Replace, run.scene.to_ron().as_bytes())?;
    }
    Ok(())
}

/// Whether a run is left to make (of all, or only `only`): not finished here nor carried from elsewhere.
pub(crate) fn pending(
    exp: &Experiment,
    elsewhere: &BTreeMap<usize, super::carry::Elsewhere>,
    only: Option<usize>,
) -> bool {
    let done = |i: usize| elsewhere.contains_key(&i) || finished(exp, &exp.runs[i]);
    match only {
        Some(i) => i < exp.runs.len() && !done(i),
        None => (0..exp.runs.len()).any(|i| !done(i)),
    }
}

/// Runs finished elsewhere are carried only beside runs of the same binary, on the same family of
/// matrix-product kernels, as `exe` would make here: otherwise continuing is refused now, not after hours
/// of runs that aggregation would then refuse to mix with them.
fn check_carried(
    exp: &Experiment,
    exe: &super::pin::Executable,
    elsewhere: &std::collections::BTreeMap<usize, super::carry::Elsewhere>,
) -> crate::error::Result<()> {
    let (me, kernels) = (exe.blake3.as_str(), exe.kernels.as_str());
    let key = |i: usize| super::figure_data::key(&exp.runs[i]);
    let pin = exe.pin.as_ref();
    if let Some((&i, other)) =
        elsewhere.iter().find(|(_, e)| e.binary.split(' ').any(|b| !super::pin::Pin::same(pin, b, me)))
    {
        return Err(format!(
            "{}: the committed run {} was made by the coevo binary {}, the runs here would be made by {me}; continue it with that binary (pin its commit in {}, see the book's \"Pinned binaries\"), or set mixed_binaries: true",
            exp.file.display(),
            key(i),
            other.binary,
            super::pin::Pin::path(&exp.root).display()
        )
        .into());
    }
    let family = |i: usize| exp.runs[i].kernels.or(crate::learning::nets::Kernels::parse(kernels));
    let differs = |i: usize, e: &str| {
        let recorded = crate::learning::nets::Kernels::parse(e);
        recorded.is_none() || recorded != family(i)
    };
    if let Some((&i, other)) = elsewhere.iter().find(|&(&i, e)| !e.kernels.is_empty() && differs(i, &e.kernels)) {
        return Err(format!(
            "{}: the committed run {} ran on {} kernels and this machine runs {kernels}; pin them (COEVO_KERNELS={} or --kernels), or set mixed_binaries: true",
            exp.file.display(),
            key(i),
            other.kernels,
            other.kernels
        )
        .into());
    }
    Ok(())
}

/// Runs the experiment's runs (all, or only `only`, an index into `exp.runs` as a Slurm array task
/// does), `jobs` at a time. Every run is attempted; Err lists the ones that failed.
pub(crate) fn run(exp: &Experiment, opts: &RunnerOptions, only: Option<usize>) -> crate::error::Result<()> {
    // Runs finished on another machine: their rows are committed, and aggregation carries them.
    let elsewhere = super::carry::finished_elsewhere(exp)?;
    if opts.pinned_binary.is_some() && exp.pin.is_none() {
        return Err(super::pin::not_pinned(exp));
    }
    let done = |i: usize| elsewhere.contains_key(&i) || finished(exp, &exp.runs[i]);
    let pending = pending(exp, &elsewhere, only);
    // The executable that makes the runs: this one, or the pinned commit's verified rebuild; none when
    // every run is made (a pinned experiment is not rebuilt to run nothing).
    let exe = match pending {
        true => Some(super::pin::executable(exp, opts.pinned_binary.as_deref())?),
        false => None,
    };
    // They are carried only beside runs of the same binary, on the same family of matrix-product kernels
    // (this machine's, or the one pinned): continuing them otherwise is refused now, not after hours of
    // runs that aggregation would then refuse to mix with them.
    if let Some(exe) = exe.as_ref().filter(|_| !exp.spec.mixed_binaries) {
        check_carried(exp, exe, &elsewhere)?;
    }
    prepare(exp)?;
    // The claims are recorded before the runs they are judged on (the registry flags later edits).
    let unfinished = |variant: &str| (0..exp.runs.len()).any(|i| exp.runs[i].variant == variant && !done(i));
    super::registry::record(exp, &unfinished)?;
    let runs: Vec<usize> = match only {
        Some(i) if i < exp.runs.len() => vec![i],
        Some(i) => return Err(format!("--task {i}: the experiment has runs 0 to {}", exp.runs.len() - 1).into()),
        // Seed by seed (every preset and variant of a seed before the next seed), so a stop at any point
        // leaves every variant with about as many finished seeds as the others.
        None => {
            let mut all: Vec<usize> = (0..exp.runs.len()).collect();
            all.sort_by_key(|&i| (exp.spec.seeds.iter().position(|&s| s == exp.runs[i].seed), i));
            all
        }
    };
    // How long the trainings left will take here, said before they start (a Slurm task's is its own).
    if let (Some(exe), None) = (exe.as_ref(), only) {
        let threads = (crate::parallel::threads() / opts.jobs.max(1)).max(1);
        let mut left = vec![];
        for &i in &runs {
            left.push((i, episodes_left(&exp.runs[i])?));
        }
        left.retain(|&(_, episodes)| episodes > 0);
        if let Some(line) =
            super::estimate::say(exp, &left, opts.jobs, |run, copies| probe(exp, run, exe, threads, copies))?
        {
            crate::errln!("{line}")?;
        }
    }
    let bar = if opts.progress { ProgressBar::new(runs.len() as u64) } else { ProgressBar::hidden() };
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} runs  {elapsed} elapsed, ETA {eta}  {msg}")
            .expect("valid template"),
    );
    bar.set_message(exp.name.clone());
    let already = runs.iter().filter(|&&i| done(i)).count();
    bar.set_position(already as u64);
    bar.reset_eta();
    let next = AtomicUsize::new(0);
    let failures = Mutex::new(Vec::new());
    // Threads the system refuses (a process limit, ulimit -u) are done without; none at all is an error.
    let started = std::thread::scope(|scope| {
        let mut started = Ok(0);
        for _ in 0..opts.jobs.clamp(1, runs.len().max(1)) {
            let spawned = std::thread::Builder::new().spawn_scoped(scope, || loop {
                let i = next.fetch_add(1, Ordering::SeqCst);
                let Some(&i) = runs.get(i) else { break };
                let run = &exp.runs[i];
                if elsewhere.contains_key(&i) {
                    continue;
                }
                if finished(exp, run) {
                    // Finished by an earlier invocation, perhaps of a coevo that kept the buffers.
                    if let Err(e) = drop_replay(exp, run) {
                        bar.println(format!("coevo: {e}"));
                        failures.lock().expect("no panics while holding it").push(e);
                    }
                    continue;
                }
                // The cores are shared among the runs at a time (one run alone updates its species on all).
                let exe = exe.as_ref().expect("resolved: a run is pending");
                match complete_run(exp, run, exe, crate::parallel::threads() / opts.jobs.max(1)) {
                    Ok(()) => bar.inc(1),
                    Err(e) => {
                        bar.println(format!("coevo: {e}"));
                        failures.lock().expect("no panics while holding it").push(e);
                    }
                }
            });
            match (spawned, &mut started) {
                (Ok(_), Ok(n)) => *n += 1,
                (Err(e), Ok(0)) => {
                    started = Err(e);
                    break;
                }
                _ => break,
            }
        }
        started
    });
    bar.finish();
    if let Err(e) = started {
        return Err(format!(
            "{}: could not start a thread to run it ({e}); is a process limit (ulimit -u) too low?",
            exp.name
        )
        .into());
    }
    let failures = failures.into_inner().expect("threads joined");
    match failures.len() {
        0 => Ok(()),
        n => Err(format!("{n} of {} runs of {} failed; first: {}", runs.len(), exp.name, failures[0]).into()),
    }
}

/// A word for a generated shell script: quoted for any POSIX shell (`shlex`), so no path or name from an
/// experiment file or the command line is ever run as shell code. Refused, before anything is written,
/// where quoting cannot be trusted: control characters (a newline would end a `#SBATCH` line or a
/// command), text that is not UTF-8, and `%` (Slurm reads it as a pattern in file names).
fn shell_word(what: &str, text: Option<&str>) -> crate::error::Result<String> {
    let text = text.ok_or_else(|| format!("--emit-slurm: {what} is not UTF-8; a job script cannot name it safely"))?;
    if text.chars().any(|c| c.is_control() || c == '%') {
        return Err(format!(
            "--emit-slurm: {what} {text:?} holds a control character or %, which a job script cannot quote safely; rename it"
        )
        .into());
    }
    Ok(shlex::try_quote(text).map_err(|e| format!("--emit-slurm: {what} {text:?}: {e}"))?.into_owned())
}

/// A Slurm job array (one task per run) and a dependent aggregate job, for the same experiment file on a
/// cluster. Written to `results/<experiment>/slurm/`; `submit.sh` submits both. Every path and name is a
/// quoted word of a command line ([`shell_word`]); the `#SBATCH` lines hold numbers only, so job names
/// and log files are given on `sbatch`'s command line, where they can be quoted.
pub(crate) fn emit_slurm(exp: &Experiment, exe: &Path, pinned: Option<&Path>) -> crate::error::Result<PathBuf> {
    let dir = exp.root.join("slurm");
    let exe = shell_word("the coevo binary's path", exe.to_str())?;
    let pinned = match pinned {
        Some(path) => format!(" --pinned-binary {}", shell_word("the pinned binary's path", path.to_str())?),
        None => String::new(),
    };
    let file = shell_word("the experiment file's path", exp.file.to_str())?;
    // The results folder is checked once (no control character, no %); the words built on it are then
    // quoted as they stand, the log pattern's %A_%a being Slurm's.
    let results = shell_word("the results folder", exp.root.to_str())?;
    let root = exp.root.to_str().unwrap_or_default();
    let quoted = |tail: &str| -> crate::error::Result<String> {
        Ok(shlex::try_quote(&format!("{root}/slurm/{tail}")).map_err(|e| format!("--emit-slurm: {e}"))?.into_owned())
    };
    let (array_sh, aggregate_sh) = (quoted("array.sh")?, quoted("aggregate.sh")?);
    let (array_log, aggregate_log) = (quoted("%A_%a.log")?, quoted("aggregate.log")?);
    let name = shell_word("the experiment's name", Some(&exp.name))?;
    let aggregate_name = shell_word("the experiment's name", Some(&format!("{}-aggregate", exp.name)))?;
    let last = exp.runs.len() - 1;
    let array = format!(
        "#!/bin/bash\n#SBATCH --array=0-{last}\n#SBATCH --cpus-per-task=1\n#SBATCH --mem=2G\n#SBATCH --time=02:00:00\n\
         # One run of the experiment (train, resume or skip, then its evaluations) per array task; submit.sh\n\
         # names the job and its log.\n\
         exec {exe} --experiment {file} --task \"$SLURM_ARRAY_TASK_ID\"{pinned} --quiet\n",
    );
    let aggregate = format!(
        "#!/bin/bash\n#SBATCH --cpus-per-task=1\n#SBATCH --mem=4G\n#SBATCH --time=00:30:00\n\
         # Summaries and figures from the runs' CSV files.\nexec {exe} --plot {results}\n",
    );
    let submit = format!(
        "#!/bin/bash\n# Submits the runs as a job array, then the aggregation once every run has succeeded.\nset -euo pipefail\n\
         cd \"$(dirname \"$0\")/{up}\"\n\
         jid=$(sbatch --parsable --job-name={name} --output={array_log} {array_sh})\n\
         sbatch --dependency=afterok:\"$jid\" --job-name={aggregate_name} --output={aggregate_log} {aggregate_sh}\n",
        up = "../".repeat(exp.root.components().count() + 1),
    );
    crate::io::own_dir(&dir)?;
    for (name, text) in [("array.sh", array), ("aggregate.sh", aggregate), ("submit.sh", submit)] {
        crate::io::write_file(&dir.join(name), crate::io::Existing::Replace, text.as_bytes())?;
    }
    Ok(dir)
}
