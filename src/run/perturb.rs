//! Information transfer (`coevo --eval RUN --perturb RADIANS`; not in the paper): the measure
//! neither a shared heading attractor nor herding by common predators can fake. A twin of the evaluated
//! world runs in lockstep with it (same scene, seed, spawn and actors); at `step` of every episode one prey
//! of the twin (the first of its species) is turned by a fixed angle, and for the following steps the
//! heading of every other prey in the twin is compared with the same prey in the untouched world. The
//! difference can only come from the turn: through what the others observe of the turned prey (and of
//! each other since), or through contacts. A response that spreads through conspecifics by topological
//! rank is flocking; without any observation there is none (`tests/it/perturb.rs`).

use crate::sim::components::Heading;
use crate::sim::perception::{Perceive, Population};
use crate::sim::space::Arena;
use crate::sim::Simulation;

/// Topological rank bins of the other prey, by distance to the turned prey at the turn (1 = nearest).
pub(crate) const RANK_BINS: [(usize, usize); 7] = [(1, 1), (2, 2), (3, 3), (4, 6), (7, 12), (13, 24), (25, usize::MAX)];

/// Steps after the turn over which the response is followed.
pub(crate) const LAGS: usize = 50;

#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Perturbation {
    /// The turn given to one prey, radians (positive: counter-clockwise).
    pub(crate) angle: f64,
    /// The step of each episode after which it is turned.
    pub(crate) step: usize,
}

/// The rows of a perturbation file ([`Response::csv`]) as (lag, first rank of the bin, mean |Δheading|,
/// samples); None without the file.
pub(crate) fn read_rows(path: &std::path::Path) -> crate::error::Result<Option<Vec<[f64; 4]>>> {
    if !path.exists() {
        return Ok(None);
    }
    let text = crate::io::read_text(path, crate::io::MAX_TEXT_BYTES)?;
    let rows = text.lines().skip(1).filter_map(|row| {
        let c: Vec<f64> = row.split(',').map(|x| x.parse().unwrap_or(f64::NAN)).collect();
        let [lag, from, _, mean, n] = c[..] else { return None };
        Some([lag, from, mean, n])
    });
    Ok(Some(rows.collect()))
}

/// The sample-weighted mean |Δheading| of the rows whose lag lies in `lags` and whose rank bin starts in
/// `ranks` (NaN without samples).
pub(crate) fn weighted_mean(
    rows: &[[f64; 4]],
    lags: std::ops::RangeInclusive<f64>,
    ranks: std::ops::RangeInclusive<f64>,
) -> f64 {
    let (sum, n) = rows
        .iter()
        .filter(|[lag, from, mean, _]| lags.contains(lag) && ranks.contains(from) && mean.is_finite())
        .fold((0.0, 0.0), |(s, c), [_, _, mean, n]| (s + mean * n, c + n));
    if n > 0.0 {
        sum / n
    } else {
        f64::NAN
    }
}

/// The response accumulated over episodes: Σ |Δheading| and samples per lag (1..=LAGS) and rank bin.
pub(crate) struct Response {
    pub(crate) perturbation: Perturbation,
    species: usize,
    sums: Vec<[(f64, u64); RANK_BINS.len()]>,
    /// Per slot of the species (other than the turned one), its rank bin in the current episode.
    bins: Vec<Option<usize>>,
}

fn angle_between(a: bevy::math::DVec2, b: bevy::math::DVec2) -> f64 {
    a.perp_dot(b).atan2(a.dot(b)).abs()
}

impl Response {
    pub(crate) fn new(perturbation: Perturbation, species: usize) -> Response {
        Response { perturbation, species, sums: vec![[(0.0, 0); RANK_BINS.len()]; LAGS], bins: vec![] }
    }

    /// After both worlds simulated `step` of an episode: turns the twin's prey at the perturbation step,
    /// and afterwards adds the differences of headings. Err when the two worlds' agents differ (they are
    /// built alike, so they never should).
    pub(crate) fn step(&mut self, world: &Simulation, twin: &mut Simulation, step: usize) -> crate::error::Result<()> {
        let p = self.perturbation;
        if step == p.step {
            let (entity, ranks) = {
                let pop = twin.world().resource::<Population>();
                let arena = twin.world().resource::<Arena>();
                let range = pop.ranges[self.species].clone();
                if range.len() < 2 {
                    return Err("--perturb: needs two or more prey".into());
                }
                let turned = range.start;
                let mut others: Vec<(f64, usize)> = range
                    .clone()
                    .filter(|&j| j != turned)
                    .map(|j| (arena.delta(pop.position[turned], pop.position[j]).length(), j - range.start))
                    .collect();
                others.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                let mut bins = vec![None; range.len()];
                for (rank, (_, j)) in others.iter().enumerate() {
                    bins[*j] = RANK_BINS.iter().position(|&(lo, hi)| lo <= rank + 1 && rank < hi);
                }
                (pop.entity[turned], bins)
            };
            self.bins = ranks;
            let w = twin.world_mut();
            if let Some(mut h) = w.get_mut::<Heading>(entity) {
                h.0 += p.angle;
            }
            w.run_schedule(Perceive);
            return Ok(());
        }
        let lag = step.wrapping_sub(p.step);
        if step < p.step || lag > LAGS || self.bins.is_empty() {
            return Ok(());
        }
        let (a, b) = (world.world().resource::<Population>(), twin.world().resource::<Population>());
        let range = a.ranges[self.species].clone();
        if a.id[range.clone()] != b.id[range.clone()] {
            return Err("--perturb: the twin world's prey differ from the evaluated world's".into());
        }
        for (k, bin) in self.bins.iter().enumerate() {
            if let Some(bin) = bin {
                let s = &mut self.sums[lag - 1][*bin];
                s.0 += angle_between(a.heading[range.start + k], b.heading[range.start + k]);
                s.1 += 1;
            }
        }
        Ok(())
    }

    /// The mean |Δheading| (radians) at `lag` over the rank bin `bin`, None without samples.
    pub(crate) fn mean(&self, lag: usize, bin: usize) -> Option<f64> {
        let (sum, n) = self.sums.get(lag.checked_sub(1)?)?[bin];
        (n > 0).then(|| sum / n as f64)
    }

    /// The file `OUT-perturbation.csv`: one row per lag and rank bin.
    pub(crate) fn csv(&self) -> String {
        let mut out = String::from("lag,rank_from,rank_to,mean_abs_heading_change,samples\n");
        for lag in 1..=LAGS {
            for (bin, (lo, hi)) in RANK_BINS.iter().enumerate() {
                let to = if *hi == usize::MAX { String::new() } else { hi.to_string() };
                let (_, n) = self.sums[lag - 1][bin];
                let mean = self.mean(lag, bin).map_or(String::new(), |m| m.to_string());
                out.push_str(&format!("{lag},{lo},{to},{mean},{n}\n"));
            }
        }
        out
    }

    /// The response in words: near (ranks 1–6) against far (ranks 25 and beyond) at lags 1 and 10.
    pub(crate) fn summary(&self) -> String {
        let near = |lag: usize| {
            let (s, n) = (0..4).map(|b| self.sums[lag - 1][b]).fold((0.0, 0), |(a, c), (s, n)| (a + s, c + n));
            (n > 0).then(|| s / n as f64)
        };
        let shown = |x: Option<f64>| x.map_or("–".to_string(), |x| format!("{x:.4}"));
        format!(
            "perturbation (one prey turned by {} rad after step {}): mean |Δheading| of the others at lag 1 / 10: ranks 1–6 {} / {}, ranks 25+ {} / {} rad",
            self.perturbation.angle,
            self.perturbation.step,
            shown(near(1)),
            shown(near(10.min(LAGS))),
            shown(self.mean(1, 6)),
            shown(self.mean(10.min(LAGS), 6)),
        )
    }
}
