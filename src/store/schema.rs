//! The CSV files of a run folder, as written by training (`metrics.csv`, one row per episode) and
//! evaluation (`eval*.csv`, one row per step) and read back by the experiment layer: one definition of
//! every column, used to write and to read.
//!
//! Per-species columns are `{quantity}_{species}`: the order parameters of [`Swarming::NAMES`] and
//! `edge_rank` for every species, `return_{species}`, and per learning species its losses and exploration.

use crate::learning::Learners;
use crate::sim::metrics::{EpisodeSummary, Swarming};
use crate::sim::species::SpeciesRegistry;
use std::path::Path;

pub(crate) const EPISODE: &str = "episode";
pub(crate) const STEPS: &str = "steps";
pub(crate) const STEP: &str = "step";
pub(crate) const CATCHES: &str = "catches";
pub(crate) const WALL_SECONDS: &str = "wall_seconds";
/// The per-step quantity of an evaluation (and per-episode one of training) besides [`Swarming::NAMES`].
pub(crate) const EDGE_RANK: &str = "edge_rank";
/// The authors' DoS and DoA (`sim::metrics::authors_dos_doa`), per species, with `authors_metrics`.
pub(crate) const AUTHORS: [&str; 2] = ["authors_dos", "authors_doa"];

/// The column of a per-species quantity: `dos_prey`, `edge_rank_prey`, `return_predator`.
pub(crate) fn of(quantity: &str, species: &str) -> String {
    format!("{quantity}_{species}")
}

/// The catches column of one catcher species (scenes where more than one species catches).
pub(crate) fn catches_by(species: &str) -> String {
    format!("catches_by_{species}")
}

/// The species whose catches are also given apart (`catches_by_<name>`): every species that catches,
/// when more than one does (a third species); none in the two-species scenes.
pub(crate) fn split_catchers(registry: &SpeciesRegistry) -> Vec<usize> {
    let catchers: Vec<usize> = (0..registry.len()).filter(|&s| registry.prey_of(s).next().is_some()).collect();
    if catchers.len() > 1 {
        catchers
    } else {
        vec![]
    }
}

/// The order parameters of a species, in their column order.
fn species_columns(species: &str) -> impl Iterator<Item = String> + '_ {
    Swarming::NAMES.iter().chain(&[EDGE_RANK]).map(move |q| of(q, species))
}

/// A CSV cell of a value that may be missing: blank then.
pub(crate) fn blank(x: Option<f64>) -> String {
    x.map_or(String::new(), |v| v.to_string())
}

/// The cells of a species' order parameters, blank where it has none (fewer than two agents).
fn species_cells(swarming: Option<Swarming>, edge_rank: Option<f64>) -> impl Iterator<Item = String> {
    swarming.map_or([None; Swarming::N], |s| s.values().map(Some)).map(blank).into_iter().chain([blank(edge_rank)])
}

/// `metrics.csv`'s header.
/// `authors`: the scene's `authors_metrics` (the authors' DoS and DoA columns after the returns).
pub(crate) fn metrics_header(registry: &SpeciesRegistry, learners: &Learners, authors: bool) -> String {
    let learning: Vec<usize> =
        (0..learners.species.len()).filter(|&s| learners.species[s].as_ref().is_some_and(|l| !l.frozen)).collect();
    let league = learners.league.as_ref().map(|g| g.columns()).unwrap_or_default();
    header(registry, &learning, &league, authors)
}

/// `metrics.csv`'s header when the species `learning` (registry indices) learn, by coevo's learners or by
/// a learner outside coevo (the Python package's `VecEnv.metrics_header`): the episode's columns
/// ([`episode_cells`]), then per learning species `critic_loss`, `actor_loss`, `noise_std`, `epsilon`,
/// then `wall_seconds`.
pub fn metrics_header_for(registry: &SpeciesRegistry, learning: &[usize], authors: bool) -> String {
    header(registry, learning, &[], authors)
}

/// The header with `league`'s columns (`learning::league::League::columns`) before `wall_seconds`, and
/// with `authors` the authors' DoS and DoA per species after the returns.
fn header(registry: &SpeciesRegistry, learning: &[usize], league: &[String], authors: bool) -> String {
    let mut cols = vec![EPISODE.to_string(), STEPS.into()];
    for d in &registry.defs {
        cols.extend(species_columns(&d.name));
    }
    cols.push(CATCHES.into());
    cols.extend(split_catchers(registry).iter().map(|&s| catches_by(&registry.defs[s].name)));
    for d in &registry.defs {
        cols.push(of("return", &d.name));
    }
    if authors {
        for d in &registry.defs {
            cols.extend(AUTHORS.map(|q| of(q, &d.name)));
        }
    }
    for &s in learning {
        let n = &registry.defs[s].name;
        cols.extend(["critic_loss", "actor_loss", "noise_std", "epsilon"].map(|q| of(q, n)));
    }
    cols.extend(league.iter().cloned());
    cols.push(WALL_SECONDS.into());
    cols.join(",")
}

/// One episode's row of `metrics.csv` (takes the losses since the last row from the learners).
pub(crate) fn metrics_row(
    e: &EpisodeSummary,
    registry: &SpeciesRegistry,
    learners: &mut Learners,
    wall_seconds: f64,
) -> String {
    let mut cols = episode_cells(e, registry);
    let losses = learners.take_losses();
    for (l, loss) in learners.species.iter().zip(losses) {
        if let Some(l) = l.as_ref().filter(|l| !l.frozen) {
            cols.push(blank(loss.map(|x| x.critic as f64)));
            cols.push(blank(loss.map(|x| x.actor as f64)));
            cols.push(l.noise_std.to_string());
            cols.push(l.epsilon.to_string());
        }
    }
    cols.extend(learners.league.as_ref().map(|g| g.cells()).unwrap_or_default());
    cols.push(format!("{wall_seconds:.3}"));
    cols.join(",")
}

/// The cells of `metrics.csv` that the episode alone decides (up to the returns): what a learner outside
/// coevo writes before its own loss columns.
pub fn episode_cells(e: &EpisodeSummary, registry: &SpeciesRegistry) -> Vec<String> {
    let mut cols = vec![e.episode.to_string(), e.steps.to_string()];
    for (s, edge_rank) in e.swarming.iter().zip(&e.edge_rank) {
        cols.extend(species_cells(*s, *edge_rank));
    }
    cols.push(e.catches.to_string());
    cols.extend(split_catchers(registry).iter().map(|&s| e.catches_by.get(s).copied().unwrap_or(0).to_string()));
    cols.extend(e.mean_return.iter().map(|r| r.to_string()));
    for a in &e.authors {
        cols.extend(a.map_or([None; 2], |a| a.map(Some)).map(blank));
    }
    cols
}

/// An evaluation's per-step header: the headline species' order parameters and the catches.
pub(crate) fn eval_header(registry: &SpeciesRegistry, prey: usize) -> String {
    let columns: Vec<String> = species_columns(&registry.defs[prey].name).collect();
    let by: String =
        split_catchers(registry).iter().map(|&s| format!(",{}", catches_by(&registry.defs[s].name))).collect();
    format!("{EPISODE},{STEP},{},{CATCHES}{by}", columns.join(","))
}

/// One step's row of an evaluation.
pub(crate) fn eval_row(
    episode: usize,
    step: usize,
    swarming: Option<Swarming>,
    edge_rank: Option<f64>,
    catches: u32,
    catches_by: impl Iterator<Item = u32>,
) -> String {
    let cells: Vec<String> = species_cells(swarming, edge_rank).collect();
    let by: String = catches_by.map(|c| format!(",{c}")).collect();
    format!("{episode},{step},{},{catches}{by}", cells.join(","))
}

/// CSV `text` rewritten under `header`: each row's cells moved to the columns of the same name, columns
/// the old header lacks left blank, columns the new one lacks dropped. Identity when the headers agree.
pub(crate) fn with_header(text: &str, header: &str) -> String {
    let mut lines = text.lines();
    let old: Vec<&str> = lines.next().unwrap_or("").split(',').collect();
    if old.join(",") == header {
        return text.to_string();
    }
    let map: Vec<Option<usize>> = header.split(',').map(|h| old.iter().position(|o| *o == h)).collect();
    let mut out = format!("{header}\n");
    for line in lines.filter(|l| !l.is_empty()) {
        let cells: Vec<&str> = line.split(',').collect();
        let row: Vec<&str> = map.iter().map(|i| i.and_then(|i| cells.get(i).copied()).unwrap_or("")).collect();
        out.push_str(&row.join(","));
        out.push('\n');
    }
    out
}

/// The wall_seconds of the last row of a metrics text (0 without rows).
pub(crate) fn last_wall_seconds(metrics: &str) -> f64 {
    let mut lines = metrics.lines();
    let header: Vec<&str> = lines.next().unwrap_or("").split(',').collect();
    let col = header.iter().position(|h| *h == WALL_SECONDS);
    col.and_then(|col| lines.rfind(|l| !l.is_empty())?.split(',').nth(col)?.parse().ok()).unwrap_or(0.0)
}

/// A CSV file of numbers: its header, and its rows (blank or unreadable cells NaN; rows of another
/// width than the header dropped).
pub struct Table {
    pub header: Vec<String>,
    pub rows: Vec<Vec<f64>>,
    path: std::path::PathBuf,
}

impl Table {
    /// A run's `metrics.csv` as training writes it, refused in one line unless it is whole: every line
    /// complete (the file ends in a line break) and as wide as the header, every cell a finite number or
    /// blank, the episodes 0, 1, 2, … in order, at least one row. With `partial`, a last line cut short
    /// (a run killed mid-write) is dropped instead of refused. `text` is the file `path` as read (errors
    /// name it).
    pub fn metrics_of(text: &str, path: &Path, partial: bool) -> crate::error::Result<Table> {
        Table::whole(text, path, partial, true)
    }

    /// An evaluation's per-step CSV, refused unless whole as [`Table::metrics_of`] says (episodes are
    /// repeated there, one row per step).
    pub fn read_eval(path: &Path) -> crate::error::Result<Table> {
        Table::whole(&crate::io::read_text(path, crate::io::MAX_TEXT_BYTES)?, path, false, false)
    }

    fn whole(text: &str, path: &Path, partial: bool, one_row_per_episode: bool) -> crate::error::Result<Table> {
        let refuse = |line: usize, why: String| -> crate::error::Error {
            crate::error::Error {
                file: Some(path.display().to_string()),
                line: Some(line),
                field: None,
                message: why,
                kind: crate::error::Kind::RunFolder,
            }
        };
        let mut lines: Vec<&str> = text.split_terminator('\n').collect();
        if !text.is_empty() && !text.ends_with('\n') {
            if !partial {
                return Err(refuse(lines.len(), "the last row is cut short (no line break): the file is damaged or still being written; --partial draws the rows before it".into()));
            }
            lines.pop();
        }
        let header: Vec<String> = lines.first().unwrap_or(&"").split(',').map(str::to_string).collect();
        let episode = header
            .iter()
            .position(|h| h == EPISODE)
            .ok_or_else(|| refuse(1, format!("no column {EPISODE}: not a metrics.csv")))?;
        let mut rows = Vec::with_capacity(lines.len());
        for (i, line) in lines.iter().enumerate().skip(1) {
            let cells: Vec<&str> = line.split(',').collect();
            if cells.len() != header.len() {
                return Err(refuse(i + 1, format!("{} cells where the header has {}", cells.len(), header.len())));
            }
            let row = cells
                .iter()
                .zip(&header)
                .map(|(c, h)| match c.parse::<f64>() {
                    _ if c.is_empty() => Ok(f64::NAN),
                    Ok(x) if x.is_finite() => Ok(x),
                    _ => Err(refuse(i + 1, format!("{h}: {c:?} is not a finite number"))),
                })
                .collect::<crate::error::Result<Vec<f64>>>()?;
            if one_row_per_episode && row[episode] != (i - 1) as f64 {
                return Err(refuse(
                    i + 1,
                    format!(
                        "episode {} where episode {} belongs: rows missing, repeated or out of order",
                        cells[episode],
                        i - 1
                    ),
                ));
            }
            rows.push(row);
        }
        if rows.is_empty() {
            return Err(refuse(1, "holds no episode (a header only)".into()));
        }
        Ok(Table { header, rows, path: path.to_path_buf() })
    }

    pub(crate) fn read(path: &Path) -> crate::error::Result<Table> {
        let text = crate::io::read_text(path, crate::io::MAX_TEXT_BYTES)?;
        let mut lines = text.lines();
        let header: Vec<String> = lines.next().unwrap_or("").split(',').map(str::to_string).collect();
        let rows: Vec<Vec<f64>> = lines
            .filter(|l| !l.is_empty())
            .map(|l| l.split(',').map(|c| c.parse::<f64>().unwrap_or(f64::NAN)).collect::<Vec<f64>>())
            .filter(|r| r.len() == header.len())
            .collect();
        Ok(Table { header, rows, path: path.to_path_buf() })
    }

    /// A column by name.
    pub(crate) fn column(&self, name: &str) -> crate::error::Result<Vec<f64>> {
        let i = self
            .header
            .iter()
            .position(|h| h == name)
            .ok_or_else(|| format!("{}: no column {name}", self.path.display()))?;
        Ok(self.rows.iter().map(|r| r[i]).collect())
    }
}
