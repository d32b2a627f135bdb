//! How long an experiment's trainings will take here, said before they start: the seconds an episode
//! takes on this machine, measured (on the experiment's own runs when some have episodes, else by a probe
//! of a few episodes of its first run left to make, as many side by side as runs will be, which the runner
//! times), times the episodes left, over the runs made at a time. Only training is counted: read-outs and evaluations come on top.

use super::file::{Experiment, Run};

/// Seconds per episode over the experiment's runs here that have trained at least one episode (their
/// `metrics.csv`'s last `wall_seconds` over its rows), and how many runs that is.
fn measured(exp: &Experiment) -> Option<(f64, usize)> {
    let rates: Vec<f64> = exp
        .runs
        .iter()
        .filter_map(|run| {
            let metrics = crate::store::RunDir::new(&run.dir).metrics();
            let table = crate::store::schema::Table::read(&metrics).ok()?;
            let wall = table.column(crate::store::schema::WALL_SECONDS).ok()?;
            let last = *wall.last()?;
            (last.is_finite() && last > 0.0).then(|| last / wall.len() as f64)
        })
        .collect();
    (!rates.is_empty()).then(|| (rates.iter().sum::<f64>() / rates.len() as f64, rates.len()))
}

/// The line said before runs are made, `jobs` at a time: `left` holds each run with episodes left to
/// train (an index into `exp.runs`, the episodes), `probe` times a few episodes of a run, as many copies
/// side by side as runs will be, when none of the experiment's runs has any yet (seconds per episode,
/// episodes timed). None when nothing is left.
pub(crate) fn say(
    exp: &Experiment,
    left: &[(usize, usize)],
    jobs: usize,
    probe: impl FnOnce(&Run, usize) -> crate::error::Result<(f64, usize)>,
) -> crate::error::Result<Option<String>> {
    let Some(&(first, _)) = left.first() else { return Ok(None) };
    let episodes: usize = left.iter().map(|(_, e)| e).sum();
    let at_once = jobs.clamp(1, left.len());
    let measured = measured(exp);
    let probed = measured.is_none();
    let (rate, basis) = match measured {
        Some((rate, n)) => (rate, format!("measured on {n} of its runs here")),
        None => {
            let run = &exp.runs[first];
            let (rate, probed) = probe(run, at_once)?;
            let side_by_side = match at_once {
                1 => String::new(),
                n => format!(", {n} side by side"),
            };
            (rate, format!("measured here by {probed}-episode probes of {}/{}{side_by_side}", run.preset, run.variant))
        }
    };
    let hours = episodes as f64 * rate / 3600.0;
    Ok(Some(format!(
        "coevo: {}: {} training{} left, {episodes} episodes at {rate:.3} s each ({basis}): about {} of training, \
         {} with {at_once} at a time (read-outs and evaluations come on top{})",
        exp.file.display(),
        left.len(),
        if left.len() == 1 { "" } else { "s" },
        duration(hours),
        duration(hours / at_once as f64),
        match probed {
            true => "; a probe times the first episodes, and later ones, with fuller replay buffers, take longer",
            false => "",
        }
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
