//! The `coevo` command line: every run mode (headless training, evaluation, recording, animations,
//! experiments, benchmarks, the viewer), for the `coevo` binary and for programs with species of their own
//! (`examples/hawk.rs`), which call [`main`] with their [`SpeciesPlugins`].
//!
//! Each mode owns its flags (a clap struct beside the mode, see [`crate::run::args`]); this file puts
//! them into one command, refuses a flag the chosen mode does not take, and hands the call to its mode.

use crate::analysis::crossplay::{self, CrossplayArgs};
use crate::analysis::distill::{self, DistillArgs};
use crate::analysis::force_map::{self, ForceMapArgs};
use crate::analysis::response::{self, ResponseArgs};
use crate::experiment::command::{self, ExperimentArgs, PlotArgs};
use crate::run::animate::{self, AnimateArgs};
use crate::run::args::{self, CommonArgs, DescribeArgs, FingerprintArgs, Mode, SceneArgs, Shared};
use crate::run::bench::BenchArgs;
use crate::run::deploy::DeployArgs;
use crate::run::evaluate::EvalArgs;
use crate::run::record::{self, RecordArgs};
use crate::run::train::{self, ResumeArgs, TrainArgs};
use crate::sim::species::SpeciesPlugins;
use crate::viewer::args::ViewerArgs;
use clap::parser::ValueSource;
use clap::{error::ErrorKind, ArgGroup, CommandFactory, FromArgMatches, Parser};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Predators and prey that learn together: a simulator of Li, Li & Zhao (New J. Phys. 2023).
///
/// One mode per call: --train, --resume RUN, --eval RUN, --record OUT.csv or --bench run headless,
/// driving the fixed-step schedule as fast as it goes. Built with `--features viewer` and given no
/// headless mode, it opens the window. Scenes are RON files under scenes/ (see docs/src/guide/scenes.md).
/// A flag the chosen mode does not use is refused, never ignored.
#[derive(Parser, Debug, Clone)]
#[command(name = "coevo", version, about, long_about = None, allow_negative_numbers = true)]
struct Cli {
    #[command(flatten)]
    train: TrainArgs,
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    common: CommonArgs,
    #[command(flatten)]
    resume: ResumeArgs,
    #[command(flatten)]
    eval: EvalArgs,
    #[command(flatten)]
    crossplay: CrossplayArgs,
    #[command(flatten)]
    response: ResponseArgs,
    #[command(flatten)]
    distill: DistillArgs,
    #[command(flatten)]
    force_map: ForceMapArgs,
    #[command(flatten)]
    record: RecordArgs,
    #[command(flatten)]
    animate: AnimateArgs,
    #[command(flatten)]
    deploy: DeployArgs,
    #[command(flatten)]
    describe: DescribeArgs,
    #[command(flatten)]
    fingerprint: FingerprintArgs,
    #[command(flatten)]
    bench: BenchArgs,
    #[command(flatten)]
    experiment: ExperimentArgs,
    #[command(flatten)]
    plot: PlotArgs,
    #[command(flatten)]
    viewer: ViewerArgs,
}

/// Every mode: its flag ("" for the viewer, the call without one) and every flag it takes besides it,
/// `--threads` and `--kernels` (its struct's own flags and its [`Mode::TAKES`]).
fn modes() -> Vec<(&'static str, Vec<String>)> {
    fn mode<M: Mode>() -> (&'static str, Vec<String>) {
        let own =
            M::augment_args(clap::Command::new("")).get_arguments().map(|a| a.get_id().to_string()).collect::<Vec<_>>();
        let takes = own.into_iter().filter(|id| id != M::MODE).chain(M::TAKES.iter().map(|id| id.to_string()));
        (M::MODE, takes.collect())
    }
    vec![
        mode::<TrainArgs>(),
        mode::<ResumeArgs>(),
        mode::<EvalArgs>(),
        mode::<CrossplayArgs>(),
        mode::<ResponseArgs>(),
        mode::<DistillArgs>(),
        mode::<ForceMapArgs>(),
        mode::<RecordArgs>(),
        mode::<AnimateArgs>(),
        mode::<DescribeArgs>(),
        mode::<FingerprintArgs>(),
        mode::<BenchArgs>(),
        mode::<ExperimentArgs>(),
        mode::<PlotArgs>(),
        mode::<ViewerArgs>(),
    ]
}

/// The command line as clap parses it: [`Cli`] with one mode flag at most, and every other flag
/// conflicting with the modes that do not take it and, when the viewer does not take it either,
/// requiring one of the modes that do.
fn command() -> clap::Command {
    let modes = modes();
    let flags: Vec<&'static str> = modes.iter().map(|(m, _)| *m).filter(|m| !m.is_empty()).collect();
    let mut command = Cli::command().group(ArgGroup::new("mode").args(&flags).multiple(false));
    let others: Vec<String> = command
        .get_arguments()
        .map(|a| a.get_id().to_string())
        .filter(|id| !flags.contains(&id.as_str()) && !["threads", "kernels", "help", "version"].contains(&id.as_str()))
        .collect();
    for flag in others {
        let takers: Vec<&'static str> = modes.iter().filter(|(_, f)| f.contains(&flag)).map(|(m, _)| *m).collect();
        let refusers: Vec<&'static str> = flags.iter().copied().filter(|m| !takers.contains(m)).collect();
        let group = format!("modes taking {flag}");
        let viewer = takers.contains(&"");
        if !viewer {
            command = command.group(ArgGroup::new(group.clone()).args(&takers).multiple(false));
        }
        command = command.mut_arg(&flag, |arg| {
            let arg = arg.conflicts_with_all(refusers);
            if viewer {
                arg
            } else {
                arg.requires(group)
            }
        });
    }
    command
}

/// clap's error as one line: its message without the usage and help hints that follow it.
fn one_line(e: &clap::Error) -> String {
    let text = e.to_string();
    let message = text.split("\n\nUsage:").next().unwrap_or("").split("\n\nFor more information").next().unwrap_or("");
    message.split_whitespace().collect::<Vec<_>>().join(" ").trim_start_matches("error: ").to_string()
}

/// The command line `args` (without the program name) as coevo reads it, or the one line it fails with.
fn parse<I: IntoIterator<Item = String>>(args: I) -> Result<(Cli, bool), clap::Error> {
    let matches = command().try_get_matches_from(std::iter::once("coevo".to_string()).chain(args))?;
    let viewer =
        !modes().iter().any(|(m, _)| !m.is_empty() && matches.value_source(m) == Some(ValueSource::CommandLine));
    Ok((Cli::from_arg_matches(&matches)?, viewer))
}

/// Whether `args` (without the program name) is a command line coevo accepts, without running it: the
/// one line it would fail with otherwise. The book's and the README's examples are checked with it.
pub fn check_args<I: IntoIterator<Item = String>>(args: I) -> Result<(), String> {
    parse(args).map(|_| ()).map_err(|e| one_line(&e))
}

/// `coevo --help`, as the book's reference prints it.
pub fn help() -> String {
    command().render_help().to_string()
}

/// Runs the command line with `species` registered (none for plain `coevo`): one line on stderr and a
/// non-zero exit on any error.
pub fn main(species: SpeciesPlugins) -> ExitCode {
    // A file that outgrows `ulimit -f` is a write error (EFBIG) that the mode reports and cleans up after,
    // not a SIGXFSZ that would kill the process with its temporary files and lock left behind.
    // SAFETY: sets the action of one signal before any thread is started.
    unsafe { libc::signal(libc::SIGXFSZ, libc::SIG_IGN) };
    // The command line is read and run on a thread whose stack coevo sizes: the main thread's is whatever
    // `ulimit -s` says (16 KiB under `ulimit -s 16`, where reading the arguments or a scene overflowed it),
    // a spawned thread's is not. Only the viewer comes back: winit opens its window on the main thread.
    let worker =
        std::thread::Builder::new().name("coevo".into()).stack_size(MAIN_STACK).spawn(move || headless(species));
    let outcome = match worker {
        Ok(worker) => worker.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic)),
        Err(e) => {
            return fail(&format!("cannot start a thread ({e}): the system's limits on threads or memory were reached"))
        }
    };
    match outcome {
        Ran::Done(code) => code,
        Ran::Viewer(cli) => match run(*cli) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => fail(&e.to_string()),
        },
    }
}

/// What [`headless`] did: ran the command to its end, or read a viewer's command line for the main thread.
enum Ran {
    Done(ExitCode),
    Viewer(Box<Cli>),
}

/// Reads the command line and runs it, unless it opens the viewer.
fn headless(species: SpeciesPlugins) -> Ran {
    if let Err(e) = species.register() {
        return Ran::Done(fail(&e.to_string()));
    }
    // Arguments as the system gives them: one that is not UTF-8 (a path, most often) is refused in one
    // line, where std::env::args would panic.
    let mut args = Vec::new();
    for (i, arg) in std::env::args_os().enumerate().skip(1) {
        match arg.into_string() {
            Ok(text) => args.push(text),
            Err(raw) => {
                return Ran::Done(fail(&format!(
                    "argument {i} ({:?}) is not valid UTF-8: coevo takes paths and values in UTF-8",
                    raw.to_string_lossy()
                )))
            }
        }
    }
    let (cli, viewer) = match parse(args) {
        Ok(parsed) => parsed,
        Err(e) if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) => e.exit(),
        Err(e) => return Ran::Done(fail(&one_line(&e))),
    };
    if viewer {
        return Ran::Viewer(Box::new(cli));
    }
    crate::io::install_signal_cleanup();
    // Output piped into `head` ends quietly, as a Unix tool's does, instead of panicking on EPIPE.
    // SAFETY: sets the process's action for one signal; no thread of coevo's has one of its own.
    unsafe { libc::signal(libc::SIGPIPE, libc::SIG_DFL) };
    Ran::Done(match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => fail(&e.to_string()),
    })
}

/// The stack of the thread the command line runs on: far beyond any call chain of coevo's (a scene's
/// parse, a model's forward pass), and only address space until used.
const MAIN_STACK: usize = 64 << 20;

/// One line on stderr and a failure; a stderr that cannot take it (closed, full) still fails, quietly.
/// Control characters (a newline in a file's name) are shown escaped, so the message stays one line; a
/// write refused for the file size limit, or a file not opened for the open-file limit, says which limit.
fn fail(message: &str) -> ExitCode {
    let mut line: String =
        message.chars().flat_map(|c| if c.is_control() { c.escape_default().collect() } else { vec![c] }).collect();
    if line.contains(&format!("(os error {})", libc::EFBIG)) {
        line.push_str(" (a file size limit was reached, such as `ulimit -f`)");
    }
    if line.contains(&format!("(os error {})", libc::EMFILE)) {
        line.push_str(" (the limit on open files was reached, such as `ulimit -n`)");
    }
    let _ = crate::errln!("coevo: error: {line}");
    ExitCode::FAILURE
}

/// The one mode a command line asks for (clap refuses two at once, [`MODES`]), with what names it.
enum Called<'a> {
    Train,
    Resume(&'a Path),
    Eval(&'a Path),
    Crossplay(&'a Path),
    Response(&'a Path),
    Distill(&'a Path),
    ForceMap(&'a Path),
    Record(&'a Path),
    Animate(&'a Path),
    Describe(&'a Path),
    Fingerprint(&'a Path),
    Bench,
    Experiment(&'a str),
    Plot(&'a Path),
    /// No mode's flag: the window.
    Viewer,
}

impl Cli {
    /// Which mode this command line calls.
    fn called(&self) -> Called<'_> {
        let modes = [
            self.train.train.then_some(Called::Train),
            self.resume.resume.as_deref().map(Called::Resume),
            self.eval.eval.as_deref().map(Called::Eval),
            self.crossplay.crossplay.as_deref().map(Called::Crossplay),
            self.response.response.as_deref().map(Called::Response),
            self.distill.distill.as_deref().map(Called::Distill),
            self.force_map.force_map.as_deref().map(Called::ForceMap),
            self.record.record.as_deref().map(Called::Record),
            self.animate.animate.as_deref().map(Called::Animate),
            self.describe.describe_scene.as_deref().map(Called::Describe),
            self.fingerprint.fingerprint.as_deref().map(Called::Fingerprint),
            self.bench.bench.then_some(Called::Bench),
            self.experiment.experiment.as_deref().map(Called::Experiment),
            self.plot.plot.as_deref().map(Called::Plot),
        ];
        modes.into_iter().flatten().next().unwrap_or(Called::Viewer)
    }
}

/// Hands the call to its mode.
fn run(cli: Cli) -> crate::error::Result<()> {
    cli.common.apply_to_process()?;
    let called = cli.called();
    let shared = Shared { scene: cli.scene.clone(), common: cli.common.clone() };
    match called {
        Called::Train => {
            let (scene, opts) = cli.train.options(&shared)?;
            // One run is one sample: beside it, how far the seeds of its scene differ in the committed results.
            let spread = opts.progress.then(|| crate::experiment::spread::seeds_like(&scene)).flatten();
            train::main(train::Start::New(Box::new(scene)), &opts, spread.as_deref())
        }
        Called::Resume(run) => train::main(train::Start::Resume, &cli.resume.options(run, &shared), None),
        Called::Eval(run) => {
            let report = crate::run::evaluate::evaluate(&cli.eval.options(run, &shared)?)?;
            crate::outln!("{report}")
        }
        Called::Crossplay(run) => crossplay::main(&cli.crossplay.options(run, &shared)?),
        Called::Response(run) => response::main(run),
        Called::Distill(run) => distill::main(run, &shared.scene.overrides(true)?, shared.common.episodes),
        Called::ForceMap(trajectory) => {
            let default = cli
                .deploy
                .run
                .as_ref()
                .map_or(PathBuf::from(args::STANDARD_SCENE), |r| r.join(crate::store::folder::SCENE));
            let (scene, _) = shared.scene.load(&default, &Default::default())?;
            force_map::main(trajectory, &scene, shared.common.overwrite)
        }
        Called::Record(out) => record::main(out, &cli.deploy, &shared),
        Called::Animate(out) => animate::main(out, &cli.animate, &cli.deploy, &shared),
        Called::Describe(path) => args::describe(path, &shared),
        Called::Fingerprint(run) => crate::outln!("{}", crate::store::provenance::fingerprint(run)?),
        Called::Bench => {
            if let Some(stem) = &cli.bench.bench_figure {
                crate::experiment::figures::check_new_figure(stem, "--bench-figure")?;
            }
            cli.bench.main()?;
            match &cli.bench.bench_figure {
                Some(stem) => crate::experiment::figures::group_size_cost(stem, cli.bench.budget()?),
                None => Ok(()),
            }
        }
        Called::Experiment(which) => command::experiment(&cli.experiment.request(which, &shared)),
        Called::Plot(dir) => command::plot(dir, cli.plot.partial),
        Called::Viewer => cli.viewer.main(&cli.animate, &shared),
    }
}

#[cfg(test)]
mod tests;
