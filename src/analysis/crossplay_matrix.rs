//! The cross-play matrix (`--crossplay`, [`super::crossplay`]): its cells, the predator–prey pairs it is
//! played for, and `crossplay.csv` written and read back.

use crate::scene::{Policy, Scene};
use crate::sim::species::SpeciesRegistry;
use crate::store::RunDir;

/// A pair of learning species: `prey` (the matrix's rows) caught by `predator` (its columns).
#[derive(Clone, Debug)]
pub struct Pair {
    pub(crate) prey: usize,
    pub(crate) predator: usize,
    pub prey_name: String,
    pub predator_name: String,
}

/// One cell: means over its episodes of the per-episode means (as `metrics.csv` has them), of the prey.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Cell {
    /// Catches of the prey by the predator species, per episode.
    pub catches: f64,
    pub(crate) dos: f64,
    pub doa: f64,
    pub(crate) nn_correlation: f64,
    pub(crate) polarization: f64,
}

impl Cell {
    pub(crate) const NAMES: [&'static str; 5] = ["catches", "dos", "doa", "nn_correlation", "polarization"];

    /// The cell's values in [`Cell::NAMES`] order.
    pub(crate) fn values(&self) -> [f64; 5] {
        [self.catches, self.dos, self.doa, self.nn_correlation, self.polarization]
    }

    /// The cell of values in [`Cell::NAMES`] order.
    pub(crate) fn from_values([catches, dos, doa, nn_correlation, polarization]: [f64; 5]) -> Cell {
        Cell { catches, dos, doa, nn_correlation, polarization }
    }
}

/// The cross-play matrix of a pair: `cells[i][j]` is prey snapshot `prey_episodes[i]` against predator
/// snapshot `predator_episodes[j]`.
#[derive(Clone, Debug)]
pub struct Matrix {
    pub pair: Pair,
    pub prey_episodes: Vec<usize>,
    pub predator_episodes: Vec<usize>,
    pub cells: Vec<Vec<Cell>>,
}

/// The predator–prey pairs among the learning species.
pub(crate) fn pairs(registry: &SpeciesRegistry) -> Vec<Pair> {
    let learned = |s: usize| matches!(registry.policy(s), Policy::Learned);
    (0..registry.len())
        .filter(|&prey| learned(prey))
        .flat_map(|prey| registry.predators_of(prey).filter(move |&p| learned(p) && p != prey).map(move |p| (prey, p)))
        .map(|(prey, predator)| Pair {
            prey,
            predator,
            prey_name: registry.defs[prey].name.clone(),
            predator_name: registry.defs[predator].name.clone(),
        })
        .collect()
}

/// The cells of a matrix as CSV, one row per cell.
pub(crate) fn cells_csv(m: &Matrix) -> String {
    let mut out = format!(
        "{}_episode,{}_episode,{}\n",
        m.pair.prey_name,
        m.pair.predator_name,
        Cell::NAMES.map(|n| if n == "catches" { n.to_string() } else { format!("{n}_{}", m.pair.prey_name) }).join(",")
    );
    for (i, row) in m.cells.iter().enumerate() {
        for (j, c) in row.iter().enumerate() {
            let values: Vec<String> = c.values().iter().map(f64::to_string).collect();
            out.push_str(&format!("{},{},{}\n", m.prey_episodes[i], m.predator_episodes[j], values.join(",")));
        }
    }
    out
}

/// A run's cross-play matrix as written in `crossplay.csv` (the scene's only pair), None without one.
pub fn read_matrix(run: &std::path::Path, pair: &Pair) -> crate::error::Result<Option<Matrix>> {
    let path = RunDir::new(run).crossplay(crate::store::CROSSPLAY);
    let Ok(text) = crate::io::read_text(&path, crate::io::MAX_TEXT_BYTES) else { return Ok(None) };
    let bad = |e: csv::Error| format!("{}: {e}", path.display());
    let mut reader = csv::Reader::from_reader(text.as_bytes());
    let mut rows: Vec<(usize, usize, Cell)> = vec![];
    for record in reader.records() {
        let record = record.map_err(bad)?;
        let number = |i: usize| record.get(i).and_then(|c| c.parse::<f64>().ok()).unwrap_or(f64::NAN);
        let (i, j) = (number(0) as usize, number(1) as usize);
        let cell = Cell {
            catches: number(2),
            dos: number(3),
            doa: number(4),
            nn_correlation: number(5),
            polarization: number(6),
        };
        rows.push((i, j, cell));
    }
    let mut prey_episodes: Vec<usize> = rows.iter().map(|r| r.0).collect();
    let mut predator_episodes: Vec<usize> = rows.iter().map(|r| r.1).collect();
    for v in [&mut prey_episodes, &mut predator_episodes] {
        v.sort_unstable();
        v.dedup();
    }
    let mut cells =
        vec![vec![Cell { catches: f64::NAN, ..Cell::default() }; predator_episodes.len()]; prey_episodes.len()];
    for (i, j, cell) in rows {
        let (a, b) = (prey_episodes.binary_search(&i), predator_episodes.binary_search(&j));
        if let (Ok(a), Ok(b)) = (a, b) {
            cells[a][b] = cell;
        }
    }
    Ok(Some(Matrix { pair: pair.clone(), prey_episodes, predator_episodes, cells }))
}

/// The cell-by-cell mean of matrices over the same snapshots (seeds of one variant), None when there are
/// none or their snapshots differ.
pub fn mean_matrix(matrices: &[Matrix]) -> Option<Matrix> {
    let first = matrices.first()?;
    let same = |m: &Matrix| m.prey_episodes == first.prey_episodes && m.predator_episodes == first.predator_episodes;
    if !matrices.iter().all(same) {
        return None;
    }
    let mut mean = first.clone();
    for (i, row) in mean.cells.iter_mut().enumerate() {
        for (j, cell) in row.iter_mut().enumerate() {
            let values: Vec<[f64; 5]> = matrices.iter().map(|m| m.cells[i][j].values()).collect();
            let [catches, dos, doa, nn_correlation, polarization] =
                std::array::from_fn(|k| values.iter().map(|v| v[k]).sum::<f64>() / values.len() as f64);
            *cell = Cell { catches, dos, doa, nn_correlation, polarization };
        }
    }
    Some(mean)
}

/// The pair a scene's cross-play is of, when it has exactly one.
pub(crate) fn only_pair(scene: &Scene) -> Option<Pair> {
    let found = pairs(&SpeciesRegistry::from_scene(scene));
    (found.len() == 1).then(|| found[0].clone())
}
