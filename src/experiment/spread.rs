//! How widely seeds of one scene differ, from the project's committed results: what `--train` adds to its
//! explanation so that one run is read as one sample.

use super::file::Experiment;
use super::report::{EXPERIMENTS, RESULTS};
use super::summary::Summary;
use crate::scene::Scene;
use std::path::Path;

/// A sentence on the spread across the seeds of `scene` (seed and episodes aside) in the experiment of
/// `experiments/` (in the working folder) that trained it on the most seeds, read from its committed
/// summary.csv: the range of the last-100 DoA, DoS and catches per episode. None when no experiment here
/// trained it. An experiment in progress that is judged only when complete is passed over.
pub(crate) fn seeds_like(scene: &Scene) -> Option<String> {
    let files = Experiment::files(Path::new(EXPERIMENTS)).ok()?;
    let mut best: Option<(usize, String)> = None;
    for file in files {
        let Ok(exp) = Experiment::load(&file, Path::new(RESULTS)) else { continue };
        let same = |other: &Scene| {
            let mut other = other.clone();
            (other.seed, other.episodes) = (scene.seed, scene.episodes);
            other == *scene
        };
        let Some(run) = exp.runs.iter().find(|r| r.shared_from.is_none() && same(&r.scene)) else { continue };
        let Ok(Some(summary)) = Summary::read(&exp.summary_path()) else { continue };
        // An experiment judged when complete shows nothing of its runs until then (no interim analysis).
        if super::aggregate::in_progress(&exp, &summary) {
            continue;
        }
        let rows: Vec<_> = summary.rows.iter().filter(|r| r.preset == run.preset && r.variant == run.variant).collect();
        if rows.len() < 2 {
            continue;
        }
        let bounds = |column: &str| {
            let values = rows.iter().map(|r| summary.value(r, column)).filter(|x| x.is_finite());
            values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| (lo.min(x), hi.max(x)))
        };
        let range = |column: &str, digits: usize| {
            let (lo, hi) = bounds(column);
            format!("{lo:.digits$}–{hi:.digits$}")
        };
        if best.as_ref().is_some_and(|(n, _)| *n >= rows.len()) {
            continue;
        }
        // Their length, so that a shorter run is not read against them as if it were as long.
        let episodes = match bounds("episodes") {
            (lo, hi) if lo == hi => format!("{lo:.0}"),
            _ => range("episodes", 0),
        };
        let line = format!(
            "  how far seeds differ: the {} seeds of this scene in {} ({} preset, variant \"{}\"), trained {episodes} episodes each, ended at DoA {}, DoS {} and {} catches per episode (their last 100 episodes; compare a run of as many episodes)\n",
            rows.len(),
            exp.root.display(),
            run.preset,
            run.variant,
            range("doa_last100", 3),
            range("dos_last100", 3),
            range("catches_last100", 1),
        );
        best = Some((rows.len(), line));
    }
    best.map(|(_, line)| line)
}
