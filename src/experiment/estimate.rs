//! How long an experiment's trainings will take here, said before they start: the seconds an episode
//! takes on this machine, measured (on the experiment's own runs when some have episodes, else by a probe
//! of a few episodes of its first run left to make, at the threads each run gets), times the episodes left,
//! over the runs made at a time. Only training is counted: read-outs and evaluations come on top.

use super::file::{Experiment, Run};
use super::pin::Executable;

/// Episodes a probe trains, at most (fewer when the runs are shorter).
const PROBE_EPISODES: usize = 10;

/// Episodes `run` has left to train: its scene's, less those its checkpoint holds.
fn episodes_left(run: &Run) -> crate::error::Result<usize> {
    Ok(match super::runner::stage(run)? {
        super::runner::Stage::Trained => 0,
        super::runner::Stage::Partial(done) => run.scene.episodes.saturating_sub(done),
        super::runner::Stage::Fresh | super::runner::Stage::Unsaved => run.scene.episodes,
    })
}

/// Seconds per episode over the experiment's runs here that have trained at least one episode (their
/// `metrics.csv`'s last `wall_seconds` over its rows), and how many runs that is.
fn measured(exp: &Experiment) -> Option<(f64, usize)> {
    let rates: Vec<f64> = exp
        .runs
        .iter()
        .filter_map(|run| {
            let metrics = crate::run::RunDir::new(&run.dir).metrics();
            let table = crate::run::schema::Table::read(&metrics).ok()?;
            let wall = table.column(crate::run::schema::WALL_SECONDS).ok()?;
            let last = *wall.last()?;
            (last.is_finite() && last > 0.0).then(|| last / wall.len() as f64)
        })
        .collect();
    (!rates.is_empty()).then(|| (rates.iter().sum::<f64>() / rates.len() as f64, rates.len()))
}

/// Seconds per episode of `run`'s scene trained by `exe` on `threads` threads for a few episodes, in a
/// folder of the experiment's that is removed after.
fn probe(exp: &Experiment, run: &Run, exe: &Executable, threads: usize) -> crate::error::Result<(f64, usize)> {
    let episodes = PROBE_EPISODES.min(run.scene.episodes).max(1);
    let dir = exp.root.join(".probe");
    let _ = std::fs::remove_dir_all(&dir);
    let opts = crate::run::train::TrainOptions {
        run: dir.clone(),
        resume: false,
        overwrite: false,
        episodes: Some(episodes),
        progress: false,
    };
    let args =
        [opts.to_argv(&super::runner::variant_scene(run), run.seed), crate::run::args::threads_argv(threads)].concat();
    let started = std::time::Instant::now();
    let made = super::runner::child(exe, &args);
    let seconds = started.elapsed().as_secs_f64();
    let _ = std::fs::remove_dir_all(&dir);
    made.map_err(|e| format!("{}: timing a probe of {episodes} episodes: {e}", exp.file.display()))?;
    Ok((seconds / episodes as f64, episodes))
}

/// The line said before the runs `runs` (indices into `exp.runs`) are made, `jobs` at a time with
/// `threads` threads each; None when none has an episode left to train.
pub(crate) fn say(
    exp: &Experiment,
    runs: &[usize],
    exe: &Executable,
    jobs: usize,
    threads: usize,
) -> crate::error::Result<Option<String>> {
    let mut left = vec![];
    for &i in runs {
        let episodes = episodes_left(&exp.runs[i])?;
        if episodes > 0 {
            left.push((i, episodes));
        }
    }
    let Some(&(first, _)) = left.first() else { return Ok(None) };
    let episodes: usize = left.iter().map(|(_, e)| e).sum();
    let (rate, basis) = match measured(exp) {
        Some((rate, n)) => (rate, format!("measured on {n} of its runs here")),
        None => {
            let (rate, probed) = probe(exp, &exp.runs[first], exe, threads)?;
            let run = &exp.runs[first];
            (rate, format!("measured here by a {probed}-episode probe of {}/{}", run.preset, run.variant))
        }
    };
    let hours = episodes as f64 * rate / 3600.0;
    let at_once = jobs.clamp(1, left.len());
    Ok(Some(format!(
        "coevo: {}: {} training{} left, {episodes} episodes at {rate:.3} s each ({basis}): about {} of training, \
         {} with {at_once} at a time (read-outs and evaluations come on top)",
        exp.file.display(),
        left.len(),
        if left.len() == 1 { "" } else { "s" },
        duration(hours),
        duration(hours / at_once as f64)
    )))
}

/// Hours said as minutes below one hour, as hours with one decimal above.
fn duration(hours: f64) -> String {
    if hours < 1.0 {
        format!("{:.0} min", (hours * 60.0).max(1.0))
    } else {
        format!("{hours:.1} h")
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn durations_are_minutes_below_an_hour() {
        assert_eq!(super::duration(0.001), "1 min");
        assert_eq!(super::duration(0.5), "30 min");
        assert_eq!(super::duration(2.25), "2.2 h");
    }
}
