//! What an experiment's figures plot, per run, kept in `results/NAME/figure-data.ron.gz` beside its
//! summaries. Run folders are not committed (a run holds megabytes of per-step CSVs and its networks);
//! this file is, so a clone's `coevo --plot` redraws every figure byte for byte from it: the figures are
//! drawn from these values, whether they were just read from the run folders or from the file.
//!
//! Per run (keyed `preset/variant/seedK`): the headline species' DoS and DoA and the catches per training
//! episode (`metrics.csv`); per evaluation its DoS and DoA per step (mean over episodes), its confusion
//! curve and, with a perturbation, the response by lag of the nearest six and of ranks 25+; the cross-play
//! matrix when the run was cross-played. RON (numbers printed to round-trip exactly, NaN as `NaN`),
//! gzip-compressed by flate2.

use super::claims::RunData;
use super::crossplay::{Cell, Matrix, Pair};
use super::file::{Experiment, Run};
use super::runner::eval_file;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// The file, in an experiment's results folder.
pub const FILE: &str = "figure-data.ron.gz";

/// The response of the other prey to the turned one, by lag: the rank bins it averages (`run::perturb`).
pub const RESPONSE_RANKS: [(&str, std::ops::RangeInclusive<f64>); 2] =
    [("ranks 1–6", 1.0..=6.0), ("ranks 25+", 25.0..=f64::INFINITY)];

/// What the figures plot of one run.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FigureData {
    /// Per training episode, of the headline species.
    pub dos: Vec<f64>,
    pub doa: Vec<f64>,
    /// Per training episode.
    pub catches: Vec<f64>,
    /// Per evaluation, by name.
    pub evals: BTreeMap<String, EvalFigures>,
    /// The cross-play matrix, when the run was cross-played.
    pub crossplay: Option<CrossplayCells>,
}

/// What the figures plot of one evaluation.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct EvalFigures {
    /// Per step, mean over the evaluation's episodes.
    pub dos: Vec<f64>,
    pub doa: Vec<f64>,
    /// Per bin of prey in view: mean |turn command|, mean speed / max speed, catches per predator-step.
    pub confusion: Vec<[f64; 3]>,
    /// With a perturbation: the response per lag of each of [`RESPONSE_RANKS`].
    pub response: Option<Vec<Vec<f64>>>,
}

/// A cross-play matrix's cells (`Cell::NAMES` in order), with the snapshots' episodes.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CrossplayCells {
    pub prey_episodes: Vec<usize>,
    pub predator_episodes: Vec<usize>,
    pub cells: Vec<Vec<[f64; 5]>>,
}

impl CrossplayCells {
    pub fn matrix(&self, pair: Pair) -> Matrix {
        Matrix {
            pair,
            prey_episodes: self.prey_episodes.clone(),
            predator_episodes: self.predator_episodes.clone(),
            cells: self.cells.iter().map(|row| row.iter().map(|v| Cell::from_values(*v)).collect()).collect(),
        }
    }
}

/// A run's key in the file.
pub fn key(run: &Run) -> String {
    format!("{}/{}/seed{}", run.preset, run.variant, run.seed)
}

fn path(exp: &Experiment) -> PathBuf {
    exp.root.join(FILE)
}

/// What the figures plot of a trained run: its loaded `data` and, from its folder, the perturbation
/// responses and the cross-play matrix.
pub fn of_run(exp: &Experiment, run: &Run, data: &RunData) -> crate::error::Result<FigureData> {
    let mut evals = BTreeMap::new();
    for (name, e) in &data.evals {
        let spec = exp.spec.evaluations.iter().find(|s| &s.name == name);
        let response = match spec.filter(|s| s.perturb.is_some()) {
            Some(_) => {
                let path = crate::io::beside(&eval_file(&run.dir, name), crate::run::PERTURBATION);
                response_by_lag(&path)?
            }
            None => None,
        };
        let figures = EvalFigures {
            dos: e.series("dos").to_vec(),
            doa: e.series("doa").to_vec(),
            confusion: e.confusion.clone(),
            response,
        };
        evals.insert(name.clone(), figures);
    }
    let crossplay = match (&exp.spec.crossplay, super::crossplay::only_pair(&run.scene)) {
        (Some(_), Some(pair)) => super::crossplay::read_matrix(&run.dir, &pair)?.map(|m| CrossplayCells {
            prey_episodes: m.prey_episodes,
            predator_episodes: m.predator_episodes,
            cells: m.cells.iter().map(|row| row.iter().map(Cell::values).collect()).collect(),
        }),
        _ => None,
    };
    Ok(FigureData { dos: data.dos.clone(), doa: data.doa.clone(), catches: data.catches.clone(), evals, crossplay })
}

/// The response per lag (1, 2, ...) of each of [`RESPONSE_RANKS`], from a perturbation file; None without it.
fn response_by_lag(path: &Path) -> crate::error::Result<Option<Vec<Vec<f64>>>> {
    use crate::run::perturb::{read_rows, weighted_mean, LAGS};
    Ok(read_rows(path)?.map(|rows| {
        RESPONSE_RANKS
            .iter()
            .map(|(_, ranks)| {
                (1..=LAGS).map(|lag| weighted_mean(&rows, lag as f64..=lag as f64, ranks.clone())).collect()
            })
            .collect()
    }))
}

/// Writes an experiment's figure data (by run index), replacing the file whole.
pub fn write(exp: &Experiment, data: &BTreeMap<usize, FigureData>) -> crate::error::Result<()> {
    let keyed: BTreeMap<String, &FigureData> = data.iter().map(|(i, d)| (key(&exp.runs[*i]), d)).collect();
    let text = ron::to_string(&keyed).map_err(|e| format!("{}: {e}", path(exp).display()))?;
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    gz.write_all(text.as_bytes()).and_then(|_| gz.finish()).map_or_else(
        |e| Err(format!("{}: {e}", path(exp).display()).into()),
        |bytes| crate::io::write_file(&path(exp), crate::io::Existing::Replace, &bytes),
    )
}

/// Reads an experiment's committed figure data, by run index: None without the file; an error when it
/// cannot be read or lacks one of `runs` (indices into the experiment's runs).
pub fn read(exp: &Experiment, runs: &[usize]) -> crate::error::Result<Option<BTreeMap<usize, FigureData>>> {
    let path = path(exp);
    let file = match std::fs::File::open(&path) {
        Ok(file) => file,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(format!("{}: {e}", path.display()).into()),
    };
    let mut text = String::new();
    flate2::read::GzDecoder::new(file)
        .take(crate::io::MAX_TEXT_BYTES * 8)
        .read_to_string(&mut text)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let mut keyed: BTreeMap<String, FigureData> =
        ron::from_str(&text).map_err(|e| format!("{}: not an experiment's figure data ({e})", path.display()))?;
    let mut out = BTreeMap::new();
    for &i in runs {
        let k = key(&exp.runs[i]);
        let d = keyed.remove(&k).ok_or_else(|| format!("{}: holds no figure data for the run {k}", path.display()))?;
        out.insert(i, d);
    }
    Ok(Some(out))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_survive_the_file_exactly_also_nan_and_infinities() {
        let d = FigureData {
            dos: vec![0.1 + 0.2, 1e-300, -0.0, f64::NAN],
            doa: vec![std::f64::consts::FRAC_2_PI],
            catches: vec![3.0, f64::INFINITY],
            evals: [(
                "50 prey, blind".to_string(),
                EvalFigures {
                    dos: vec![0.123456789012345],
                    doa: vec![],
                    confusion: vec![[f64::NAN, 0.5, 1.0 / 3.0]],
                    response: Some(vec![vec![0.07], vec![f64::NEG_INFINITY]]),
                },
            )]
            .into(),
            crossplay: Some(CrossplayCells {
                prey_episodes: vec![0, 2000],
                predator_episodes: vec![0],
                cells: vec![vec![[1.0, 2.0, 3.0, f64::NAN, 5.0]]],
            }),
        };
        let back: FigureData = ron::from_str(&ron::to_string(&d).unwrap()).unwrap();
        let bits = |d: &FigureData| format!("{:?}", ron::to_string(d).unwrap());
        assert_eq!(bits(&back), bits(&d));
        assert_eq!(
            back.dos[..3].iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            d.dos[..3].iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
        assert!(back.dos[3].is_nan() && back.evals["50 prey, blind"].confusion[0][0].is_nan());
        assert_eq!(back.catches[1], f64::INFINITY);
    }
}
