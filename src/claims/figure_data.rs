//! What an experiment's figures plot, per run, kept in `results/NAME/figure-data.ron.gz` beside its
//! summaries. Run folders are not committed (a run holds megabytes of per-step CSVs and its networks);
//! this file is, so a clone's `coevo --plot` redraws every figure byte for byte from it: the figures are
//! drawn from these values, whether they were just read from the run folders or from the file.
//!
//! Per run (keyed `preset/variant/seedK`): the headline species' DoS and DoA and the catches per training
//! episode (`metrics.csv`); per evaluation its DoS and DoA per step (mean over episodes), its confusion
//! curve and, with a perturbation, the response by lag of the nearest six and of ranks 25+; the cross-play
//! matrix when the run was cross-played. RON, gzip-compressed by flate2. Values are kept at single
//! precision (f32, shortest round-trip text, NaN as `NaN`): seven significant digits, far below a pixel
//! of any figure, at half the size; the figures are drawn from the values so rounded ([`of_run`]),
//! whether they come from the run folders or from the file.

use super::crossplay_matrix::{Cell, Matrix, Pair};
use super::file::eval_file;
use super::file::{Experiment, Run};
use super::results::RunData;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// The file, in an experiment's results folder.
pub(crate) const FILE: &str = "figure-data.ron.gz";

/// The response of the other prey to the turned one, by lag: the rank bins it averages (`run::perturb`).
pub(crate) const RESPONSE_RANKS: [(&str, std::ops::RangeInclusive<f64>); 2] =
    [("ranks 1–6", 1.0..=6.0), ("ranks 25+", 25.0..=f64::INFINITY)];

/// What the figures plot of one run.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub(crate) struct FigureData {
    /// Per training episode, of the headline species.
    #[serde(with = "single")]
    pub(crate) dos: Vec<f64>,
    #[serde(with = "single")]
    pub(crate) doa: Vec<f64>,
    /// Per training episode.
    #[serde(with = "single")]
    pub(crate) catches: Vec<f64>,
    /// Per evaluation, by name.
    pub(crate) evals: BTreeMap<String, EvalFigures>,
    /// The cross-play matrix, when the run was cross-played.
    pub(crate) crossplay: Option<CrossplayCells>,
}

/// What the figures plot of one evaluation.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub(crate) struct EvalFigures {
    /// Per step, mean over the evaluation's episodes.
    #[serde(with = "single")]
    pub(crate) dos: Vec<f64>,
    #[serde(with = "single")]
    pub(crate) doa: Vec<f64>,
    /// Per bin of prey in view: mean |turn command|, mean speed / max speed, catches per predator-step.
    #[serde(with = "single")]
    pub(crate) confusion: Vec<[f64; 3]>,
    /// With a perturbation: the response per lag of each of [`RESPONSE_RANKS`].
    #[serde(with = "single")]
    pub(crate) response: Option<Vec<Vec<f64>>>,
}

/// A cross-play matrix's cells (`Cell::NAMES` in order), with the snapshots' episodes.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub(crate) struct CrossplayCells {
    pub(crate) prey_episodes: Vec<usize>,
    pub(crate) predator_episodes: Vec<usize>,
    #[serde(with = "single")]
    pub(crate) cells: Vec<Vec<[f64; 5]>>,
}

/// Values stored at single precision: each f64 written as the f32 nearest it and read back as that f32,
/// for the shapes [`FigureData`] holds. [`single::round`] gives a value as the file will hold it.
mod single {
    use serde::de::DeserializeOwned;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub(crate) trait Single: Sized {
        type Stored: Serialize + DeserializeOwned;
        fn store(&self) -> Self::Stored;
        fn load(stored: Self::Stored) -> Self;
    }

    impl Single for f64 {
        type Stored = f32;
        fn store(&self) -> f32 {
            *self as f32
        }
        fn load(stored: f32) -> f64 {
            stored as f64
        }
    }

    impl<T: Single> Single for Vec<T> {
        type Stored = Vec<T::Stored>;
        fn store(&self) -> Self::Stored {
            self.iter().map(Single::store).collect()
        }
        fn load(stored: Self::Stored) -> Self {
            stored.into_iter().map(T::load).collect()
        }
    }

    impl<T: Single> Single for Option<T> {
        type Stored = Option<T::Stored>;
        fn store(&self) -> Self::Stored {
            self.as_ref().map(Single::store)
        }
        fn load(stored: Self::Stored) -> Self {
            stored.map(T::load)
        }
    }

    // serde has array impls for lengths up to 32, not for a generic length: the two FigureData holds.
    macro_rules! arrays {
        ($($n:literal),*) => {$(
            impl Single for [f64; $n] {
                type Stored = [f32; $n];
                fn store(&self) -> [f32; $n] {
                    self.map(|x| x as f32)
                }
                fn load(stored: [f32; $n]) -> [f64; $n] {
                    stored.map(|x| x as f64)
                }
            }
        )*};
    }
    arrays!(3, 5);

    /// The value as the file holds it.
    pub(crate) fn round<T: Single>(value: &T) -> T {
        T::load(value.store())
    }

    pub(crate) fn serialize<T: Single, S: Serializer>(value: &T, s: S) -> Result<S::Ok, S::Error> {
        value.store().serialize(s)
    }

    pub(crate) fn deserialize<'de, T: Single, D: Deserializer<'de>>(d: D) -> Result<T, D::Error> {
        T::Stored::deserialize(d).map(T::load)
    }
}

impl CrossplayCells {
    pub(crate) fn matrix(&self, pair: Pair) -> Matrix {
        Matrix {
            pair,
            prey_episodes: self.prey_episodes.clone(),
            predator_episodes: self.predator_episodes.clone(),
            cells: self.cells.iter().map(|row| row.iter().map(|v| Cell::from_values(*v)).collect()).collect(),
        }
    }
}

impl FigureData {
    /// A training series by name: `dos`, `doa` or `catches`.
    /// The curve of a run that figure data keeps (DoS, DoA, catches); the authors' curves are not kept,
    /// so they read as empty (a quantity of them gives NaN).
    pub(crate) fn curve(&self, curve: super::file::Curve) -> &[f64] {
        use super::file::Curve;
        match curve {
            Curve::Dos => &self.dos,
            Curve::Doa => &self.doa,
            Curve::Catches => &self.catches,
            Curve::AuthorsDos | Curve::AuthorsDoa => &[],
        }
    }
}

/// A run's key in the file.
pub(crate) fn key(run: &Run) -> String {
    format!("{}/{}/seed{}", run.preset, run.variant, run.seed)
}

fn path(exp: &Experiment) -> PathBuf {
    exp.root.join(FILE)
}

/// What the figures plot of a trained run: its loaded `data` and, from its folder, the perturbation
/// responses and the cross-play matrix.
pub(crate) fn of_run(exp: &Experiment, run: &Run, data: &RunData) -> crate::error::Result<FigureData> {
    let mut evals = BTreeMap::new();
    for (name, e) in &data.evals {
        let spec = exp.spec.evaluations.iter().find(|s| &s.name == name);
        let response = match spec.filter(|s| s.perturb.is_some()) {
            Some(_) => {
                let path = crate::io::beside(&eval_file(&run.dir, name), crate::store::PERTURBATION);
                response_by_lag(&path)?
            }
            None => None,
        };
        let figures = EvalFigures {
            dos: single::round(&e.series("dos").to_vec()),
            doa: single::round(&e.series("doa").to_vec()),
            confusion: single::round(&e.confusion),
            response: single::round(&response),
        };
        evals.insert(name.clone(), figures);
    }
    let crossplay = match (&exp.spec.crossplay, super::crossplay_matrix::only_pair(&run.scene)) {
        (Some(_), Some(pair)) => super::crossplay_matrix::read_matrix(&run.dir, &pair)?.map(|m| CrossplayCells {
            prey_episodes: m.prey_episodes,
            predator_episodes: m.predator_episodes,
            cells: single::round(&m.cells.iter().map(|row| row.iter().map(Cell::values).collect()).collect()),
        }),
        _ => None,
    };
    Ok(FigureData {
        dos: single::round(&data.dos),
        doa: single::round(&data.doa),
        catches: single::round(&data.catches),
        evals,
        crossplay,
    })
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
pub(crate) fn write(exp: &Experiment, data: &BTreeMap<usize, FigureData>) -> crate::error::Result<()> {
    let keyed: BTreeMap<String, &FigureData> = data.iter().map(|(i, d)| (key(&exp.runs[*i]), d)).collect();
    let text = ron::to_string(&keyed).map_err(|e| format!("{}: {e}", path(exp).display()))?;
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    gz.write_all(text.as_bytes()).and_then(|_| gz.finish()).map_or_else(
        |e| Err(format!("{}: {e}", path(exp).display()).into()),
        |bytes| crate::io::write_file(&path(exp), crate::io::Existing::Replace, &bytes),
    )
}

/// The experiment's figure data opened for reading: None without the file; an error where something
/// else is there (a folder, a FIFO, which opening would wait on forever) or it cannot be opened.
fn open(exp: &Experiment) -> crate::error::Result<Option<std::fs::File>> {
    let path = path(exp);
    match crate::io::open_input(&path) {
        Ok(file) => Ok(Some(file)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(format!("{}: {e}", path.display()).into()),
    }
}

/// Whether the experiment has its figure data ([`open`]'s checks).
pub(crate) fn present(exp: &Experiment) -> crate::error::Result<bool> {
    Ok(open(exp)?.is_some())
}

/// Reads an experiment's committed figure data, by run index: None without the file; an error when it
/// cannot be read or lacks one of `runs` (indices into the experiment's runs).
pub(crate) fn read(exp: &Experiment, runs: &[usize]) -> crate::error::Result<Option<BTreeMap<usize, FigureData>>> {
    let path = path(exp);
    let Some(file) = open(exp)? else { return Ok(None) };
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
    fn numbers_survive_the_file_at_single_precision_also_nan_and_infinities() {
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
        // What comes back is the f32 nearest each value, exactly: what `of_run` draws from.
        assert_eq!(
            back.dos[..3].iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            d.dos[..3].iter().map(|&x| (x as f32 as f64).to_bits()).collect::<Vec<_>>()
        );
        assert_eq!(back.evals["50 prey, blind"].dos, single::round(&d.evals["50 prey, blind"].dos));
        assert_ne!(back.evals["50 prey, blind"].dos, d.evals["50 prey, blind"].dos, "rounded to f32");
        let again: FigureData = ron::from_str(&ron::to_string(&back).unwrap()).unwrap();
        assert_eq!(bits(&again), bits(&back));
        assert_eq!(again.dos[..3], back.dos[..3], "a rounded value survives the file exactly");
        assert!(back.dos[3].is_nan() && back.evals["50 prey, blind"].confusion[0][0].is_nan());
        assert_eq!(back.catches[1], f64::INFINITY);
    }
}
