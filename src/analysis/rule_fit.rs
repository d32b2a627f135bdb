//! Fitting a rule that is linear in its gains to what agents did, and saying how sure the fit is.
//!
//! Each action (thrust, turn) is fitted by least squares on its terms, a term being the sum of some
//! feature columns (a zone's members, say) and the first term of each action a constant. Rows come in
//! clusters, one agent in one episode, whose rows depend on each other; the intervals resample whole
//! clusters (a cluster bootstrap, [`BOOTSTRAP`] resamples, 95 % percentile intervals). They describe one
//! run and are narrower than a full account: the agents of one episode share their swarm, yet are
//! resampled as independent, and the zones chosen are held fixed. A resample in which a term never varied
//! gives it no value, and an interval needs at least half the resamples. Inference across runs is over
//! seeds, on each run's point values (the experiments' claims).
//!
//! What is reported of each term, so that no gain is zero because of how it was fitted and gains of
//! features in different units can be compared:
//! - its gain **per standard deviation** of the term over the fitted rows (the action's change for a
//!   one-SD change of the term), with its interval; none for a term that never varied (nothing to fit);
//! - its **held-out value**: how much of the action's variance the rule explains on the held-out
//!   episodes, less what the same rule refitted without the term explains there (ΔR², linear predictions),
//!   with its interval. A term that only fits noise has ΔR² at or below zero.

use rand::{Rng, SeedableRng};

/// Resamples of the cluster bootstrap.
pub(crate) const BOOTSTRAP: usize = 200;

/// The ridge added to every diagonal of the normal equations, per row: small enough not to shrink a
/// gain that has data (1e-9 of a unit feature's sum of squares), large enough to keep the equations
/// solvable when a term never varies in a resample.
const RIDGE: f64 = 1e-9;

/// A term of a rule: the action it moves (0 thrust, 1 turn), the parameter it estimates, and the feature
/// columns whose sum it weighs.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Term {
    pub(crate) action: usize,
    pub(crate) name: &'static str,
    pub(crate) columns: Vec<usize>,
}

/// The rows a rule is fitted to: per row its `k` feature columns, the action [thrust, turn] it took and
/// its cluster.
#[derive(Default)]
pub(crate) struct Design {
    pub(crate) k: usize,
    pub(crate) x: Vec<f64>,
    pub(crate) y: Vec<[f64; 2]>,
    pub(crate) cluster: Vec<usize>,
}

impl Design {
    pub(crate) fn new(k: usize) -> Design {
        Design { k, ..Default::default() }
    }

    pub(crate) fn push(&mut self, x: &[f64], y: [f64; 2], cluster: usize) {
        self.x.extend_from_slice(x);
        self.y.push(y);
        self.cluster.push(cluster);
    }

    pub(crate) fn rows(&self) -> usize {
        self.y.len()
    }

    fn row(&self, i: usize) -> &[f64] {
        &self.x[i * self.k..(i + 1) * self.k]
    }

    /// The normal equations every fit of a rule to these rows reads, made in one pass over them: over
    /// each of two folds of clusters (even and odd, for choosing the zones out of sample) and over all.
    pub(crate) fn normals(&self) -> Normals {
        let mut n = Normals { folds: [Normal::new(self.k), Normal::new(self.k)], whole: Normal::new(self.k) };
        for i in 0..self.rows() {
            n.folds[self.cluster[i] % 2].add(self.row(i), self.y[i]);
            n.whole.add(self.row(i), self.y[i]);
        }
        n
    }

    /// Per cluster (in order of first appearance), the sums of `terms` (one action's, constant first).
    fn cluster_sums(&self, terms: &[&Term]) -> Vec<Sums> {
        let mut index = std::collections::HashMap::new();
        let mut out: Vec<Sums> = vec![];
        let mut z = vec![0.0; terms.len()];
        for i in 0..self.rows() {
            let c = *index.entry(self.cluster[i]).or_insert_with(|| {
                out.push(Sums::new(terms.len()));
                out.len() - 1
            });
            let row = self.row(i);
            for (z, t) in z.iter_mut().zip(terms) {
                *z = t.columns.iter().map(|&c| row[c]).sum();
            }
            out[c].add(&z, self.y[i][terms[0].action]);
        }
        out
    }
}

/// A design's normal equations over two folds of its clusters and over all its rows ([`Design::normals`]).
pub(crate) struct Normals {
    folds: [Normal; 2],
    whole: Normal,
}

/// Sums over rows of x xᵀ, of x·y per action and of y² per action, for the k feature columns x.
pub(crate) struct Normal {
    k: usize,
    rows: f64,
    gram: Vec<f64>,
    cross: [Vec<f64>; 2],
    yy: [f64; 2],
}

impl Normal {
    fn new(k: usize) -> Normal {
        Normal { k, rows: 0.0, gram: vec![0.0; k * k], cross: [vec![0.0; k], vec![0.0; k]], yy: [0.0; 2] }
    }

    fn add(&mut self, f: &[f64], y: [f64; 2]) {
        self.rows += 1.0;
        for i in (0..self.k).filter(|&i| f[i] != 0.0) {
            for j in 0..self.k {
                self.gram[i * self.k + j] += f[i] * f[j];
            }
            for (cross, y) in self.cross.iter_mut().zip(y) {
                cross[i] += f[i] * y;
            }
        }
        for (yy, y) in self.yy.iter_mut().zip(y) {
            *yy += y * y;
        }
    }

    /// The sums of `terms` (one action's): each term the sum of its columns.
    pub(crate) fn sums(&self, terms: &[&Term]) -> Sums {
        let (m, a) = (terms.len(), terms.first().map_or(0, |t| t.action));
        let mut s = Sums::new(m);
        for (i, ti) in terms.iter().enumerate() {
            for (j, tj) in terms.iter().enumerate() {
                s.gram[i * m + j] = ti
                    .columns
                    .iter()
                    .flat_map(|&p| tj.columns.iter().map(move |&q| p * self.k + q))
                    .map(|at| self.gram[at])
                    .sum();
            }
            s.cross[i] = ti.columns.iter().map(|&p| self.cross[a][p]).sum();
        }
        (s.rows, s.yy) = (self.rows, self.yy[a]);
        s
    }
}

/// The normal equations of one action on m terms (the first a constant): Σ z zᵀ, Σ z·y, Σ y², rows.
#[derive(Clone, Debug)]
pub(crate) struct Sums {
    m: usize,
    rows: f64,
    gram: Vec<f64>,
    cross: Vec<f64>,
    yy: f64,
}

impl Sums {
    fn new(m: usize) -> Sums {
        Sums { m, rows: 0.0, gram: vec![0.0; m * m], cross: vec![0.0; m], yy: 0.0 }
    }

    fn add(&mut self, z: &[f64], y: f64) {
        self.rows += 1.0;
        for i in 0..self.m {
            for j in 0..self.m {
                self.gram[i * self.m + j] += z[i] * z[j];
            }
            self.cross[i] += z[i] * y;
        }
        self.yy += y * y;
    }

    fn add_sums(&mut self, other: &Sums) {
        self.rows += other.rows;
        self.gram.iter_mut().zip(&other.gram).for_each(|(a, b)| *a += b);
        self.cross.iter_mut().zip(&other.cross).for_each(|(a, b)| *a += b);
        self.yy += other.yy;
    }

    fn total(parts: &[Sums], which: impl Iterator<Item = usize>, m: usize) -> Sums {
        let mut s = Sums::new(m);
        which.for_each(|c| s.add_sums(&parts[c]));
        s
    }

    /// The least-squares gains of the terms `used` (the others held at zero).
    pub(crate) fn solve(&self, used: &[bool]) -> Vec<f64> {
        let idx: Vec<usize> = (0..self.m).filter(|&i| used[i]).collect();
        let k = idx.len();
        let mut a: Vec<f64> = idx
            .iter()
            .flat_map(|&i| idx.iter().map(move |&j| (i, j)))
            .map(|(i, j)| self.gram[i * self.m + j])
            .collect();
        for i in 0..k {
            a[i * k + i] += RIDGE * self.rows.max(1.0);
        }
        let b: Vec<f64> = idx.iter().map(|&i| self.cross[i]).collect();
        let solved = cholesky_solve(&a, &b);
        let mut beta = vec![0.0; self.m];
        idx.iter().zip(solved).for_each(|(&i, v)| beta[i] = v);
        beta
    }

    /// The sum of squared errors of gains `beta` on these rows.
    pub(crate) fn sse(&self, beta: &[f64]) -> f64 {
        let m = self.m;
        let fitted: f64 = (0..m).map(|i| beta[i] * self.cross[i]).sum();
        let quad: f64 = (0..m).map(|i| (0..m).map(|j| beta[i] * self.gram[i * m + j] * beta[j]).sum::<f64>()).sum();
        (self.yy - 2.0 * fitted + quad).max(0.0)
    }

    /// The action's sum of squares about its mean (the constant term is the first).
    fn sst(&self) -> f64 {
        (self.yy - self.cross[0] * self.cross[0] / self.rows.max(1.0)).max(0.0)
    }

    /// The standard deviation of term `j` over these rows.
    fn sd(&self, j: usize) -> f64 {
        let n = self.rows.max(1.0);
        let mean = self.gram[j] / n;
        (self.gram[j * self.m + j] / n - mean * mean).max(0.0).sqrt()
    }
}

/// Solves a x = b for symmetric positive definite a (k×k, row-major) by Cholesky.
fn cholesky_solve(a: &[f64], b: &[f64]) -> Vec<f64> {
    let k = b.len();
    let mut l = vec![0.0; k * k];
    for i in 0..k {
        for j in 0..=i {
            let sum: f64 = (0..j).map(|m| l[i * k + m] * l[j * k + m]).sum();
            l[i * k + j] = if i == j {
                (a[i * k + i] - sum).max(f64::MIN_POSITIVE).sqrt()
            } else {
                (a[i * k + j] - sum) / l[j * k + j]
            };
        }
    }
    let mut z = vec![0.0; k];
    for i in 0..k {
        z[i] = (b[i] - (0..i).map(|m| l[i * k + m] * z[m]).sum::<f64>()) / l[i * k + i];
    }
    let mut x = vec![0.0; k];
    for i in (0..k).rev() {
        x[i] = (z[i] - (i + 1..k).map(|m| l[m * k + i] * x[m]).sum::<f64>()) / l[i * k + i];
    }
    x
}

/// The terms of one action, in the order given.
fn of_action(terms: &[Term], action: usize) -> Vec<&Term> {
    terms.iter().filter(|t| t.action == action).collect()
}

/// The rows' sum of squared errors, over both actions, of `terms` fitted on `fit`, predicting `test`.
fn out_of_sample(terms: &[Term], fit: &Normal, test: &Normal) -> f64 {
    (0..2)
        .map(|a| {
            let t = of_action(terms, a);
            let beta = fit.sums(&t).solve(&vec![true; t.len()]);
            test.sums(&t).sse(&beta)
        })
        .sum()
}

/// Of `candidates` (each a rule's terms), the one that predicts best out of sample within the fitted rows
/// (`normals`): two folds by cluster, each fitted on one and scored on the other, the errors summed. Ties
/// go to the first.
pub(crate) fn choose(normals: &Normals, candidates: impl Iterator<Item = Vec<Term>>) -> Vec<Term> {
    let folds = &normals.folds;
    let mut best: Option<(f64, Vec<Term>)> = None;
    for terms in candidates {
        let error = out_of_sample(&terms, &folds[0], &folds[1]) + out_of_sample(&terms, &folds[1], &folds[0]);
        if best.as_ref().is_none_or(|(e, _)| error < *e) {
            best = Some((error, terms));
        }
    }
    best.expect("at least one candidate").1
}

/// The gains of `terms` fitted on all the fitted rows (`normals`), by term.
pub(crate) fn gains(terms: &[Term], normals: &Normals) -> Vec<f64> {
    let normal = &normals.whole;
    let mut out = vec![0.0; terms.len()];
    for a in 0..2 {
        let t = of_action(terms, a);
        let beta = normal.sums(&t).solve(&vec![true; t.len()]);
        let mut at = terms.iter().enumerate().filter(|(_, x)| x.action == a).map(|(i, _)| i);
        beta.into_iter().for_each(|b| out[at.next().expect("one gain per term")] = b);
    }
    out
}

/// What is reported of one term ([module docs](self)).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TermFit {
    /// The parameter the term estimates, as the rule names it (e.g. `turn.alignment`).
    pub name: String,
    /// Its gain per standard deviation of the term, and the 95 % interval; None when the term never
    /// varied over the fitted rows, and for a group of terms (a binned rule's bins: no single gain).
    pub per_sd: Option<f64>,
    pub per_sd_interval: Option<[f64; 2]>,
    /// Its held-out ΔR² (of the whole group), and the 95 % interval; None when the action never varied on
    /// the held-out rows.
    pub held_out_gain: Option<f64>,
    pub held_out_gain_interval: Option<[f64; 2]>,
}

/// Per group of terms (one term, or every term of one name: a binned rule's bins), the point values of
/// one resample (or of the data itself): the per-SD gain (of a group of one term only) and the held-out
/// ΔR² of leaving the whole group out.
fn term_values(fit: &Sums, held: &Sums, groups: &[Vec<usize>]) -> (Vec<Option<f64>>, Vec<Option<f64>>) {
    let all = vec![true; fit.m];
    let beta = fit.solve(&all);
    let varied = |j: usize| fit.sd(j) > 0.0;
    let per_sd = groups.iter().map(|g| match g[..] {
        [j] => varied(j).then(|| beta[j] * fit.sd(j)),
        _ => None,
    });
    let (sst, full) = (held.sst(), held.sse(&beta));
    // A group none of whose terms varied where it was fitted adds nothing by construction: no held-out
    // value, as no gain (never an equivalence to zero for free).
    let delta = groups.iter().map(|g| {
        let mut without = all.clone();
        g.iter().for_each(|&j| without[j] = false);
        (sst > 0.0 && g.iter().any(|&j| varied(j))).then(|| (held.sse(&fit.solve(&without)) - full) / sst)
    });
    (per_sd.collect(), delta.collect())
}

/// The 95 % percentile interval of the resamples that gave a value ([`super::stats::percentile_interval`]);
/// None when fewer than half of the [`BOOTSTRAP`] resamples did.
fn interval_of(values: &[f64]) -> Option<[f64; 2]> {
    (values.len() * 2 >= BOOTSTRAP).then(|| super::stats::percentile_interval(values, 0.05).into())
}

/// The per-term report of `terms` (the constants left out) fitted on `fit` and judged on `held`, with
/// cluster-bootstrap intervals drawn from `seed`. Terms of one action that share a name are one group,
/// reported once: a binned rule's bins of one kind.
pub(crate) fn term_fits(terms: &[Term], fit: &Design, held: &Design, seed: u64) -> Vec<TermFit> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut out = vec![];
    for a in 0..2 {
        let t = of_action(terms, a);
        let m = t.len();
        // By name in order of first appearance; the constant (the first term) has neither a spread nor a
        // held-out value of its own.
        let mut groups: Vec<Vec<usize>> = vec![];
        for j in 1..m {
            match groups.iter_mut().find(|g| t[g[0]].name == t[j].name) {
                Some(g) => g.push(j),
                None => groups.push(vec![j]),
            }
        }
        let n = groups.len();
        let (fit_parts, held_parts) = (fit.cluster_sums(&t), held.cluster_sums(&t));
        let whole = |parts: &[Sums]| Sums::total(parts, 0..parts.len(), m);
        let (per_sd, delta) = term_values(&whole(&fit_parts), &whole(&held_parts), &groups);
        let (mut sd_draws, mut delta_draws) = (vec![vec![]; n], vec![vec![]; n]);
        let draw = |parts: &[Sums], rng: &mut rand_chacha::ChaCha8Rng| {
            Sums::total(parts, (0..parts.len()).map(|_| rng.gen_range(0..parts.len())), m)
        };
        for _ in 0..BOOTSTRAP {
            let (f, h) = (draw(&fit_parts, &mut rng), draw(&held_parts, &mut rng));
            let (s, d) = term_values(&f, &h, &groups);
            for g in 0..n {
                sd_draws[g].extend(s[g]);
                delta_draws[g].extend(d[g]);
            }
        }
        for (g, group) in groups.iter().enumerate() {
            out.push(TermFit {
                name: t[group[0]].name.to_string(),
                per_sd: per_sd[g],
                per_sd_interval: per_sd[g].and(interval_of(&sd_draws[g])),
                held_out_gain: delta[g],
                held_out_gain_interval: delta[g].and(interval_of(&delta_draws[g])),
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// y_turn = 0.5 x1 + noise, x2 pure noise, over 40 clusters of 25 rows.
    fn data(seed: u64) -> Design {
        use rand_distr::{Distribution, Normal as Gauss};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let g = Gauss::new(0.0, 1.0).unwrap();
        let mut d = Design::new(3);
        for c in 0..40 {
            for _ in 0..25 {
                let (x1, x2): (f64, f64) = (g.sample(&mut rng) * 2.0, g.sample(&mut rng));
                d.push(&[1.0, x1, x2], [0.0, 0.5 * x1 + 0.3 * g.sample(&mut rng)], c);
            }
        }
        d
    }

    fn terms() -> Vec<Term> {
        let t = |action, name, c: usize| Term { action, name, columns: vec![c] };
        vec![t(1, "turn.bias", 0), t(1, "turn.x1", 1), t(1, "turn.x2", 2), t(0, "thrust.bias", 0)]
    }

    #[test]
    fn a_present_term_is_told_from_an_absent_one() {
        let (fit, held) = (data(1), data(2));
        let g = gains(&terms(), &fit.normals());
        assert!((g[1] - 0.5).abs() < 0.02 && g[2].abs() < 0.02, "{g:?}");
        let fits = term_fits(&terms(), &fit, &held, 3);
        let (x1, x2) = (&fits[0], &fits[1]);
        assert_eq!((x1.name.as_str(), x2.name.as_str()), ("turn.x1", "turn.x2"));
        // Per SD: 0.5 × 2 = 1 for x1; its interval excludes zero, x2's holds it.
        let [lo, hi] = x1.per_sd_interval.unwrap();
        assert!((x1.per_sd.unwrap() - 1.0).abs() < 0.05 && lo > 0.9 && hi < 1.1, "{x1:?}");
        let [lo, hi] = x2.per_sd_interval.unwrap();
        assert!(lo < 0.0 && hi > 0.0, "{x2:?}");
        // Held out: x1 explains almost all the variance (1 / (1 + 0.09)), x2 nothing.
        assert!((x1.held_out_gain.unwrap() - 1.0 / 1.09).abs() < 0.03, "{x1:?}");
        let [lo, hi] = x2.held_out_gain_interval.unwrap();
        assert!(x2.held_out_gain.unwrap().abs() < 0.005 && lo < 0.001 && hi < 0.005, "{x2:?}");
        // The thrust never varied: its bias alone, no terms reported.
        assert_eq!(fits.len(), 2);
    }

    #[test]
    fn terms_of_one_name_are_judged_as_one_group() {
        // x1 split by its sign into two columns of one name (two bins of one kind), x2 alone.
        let split = |d: Design| {
            let mut out = Design::new(4);
            for i in 0..d.rows() {
                let r = d.row(i);
                out.push(&[1.0, r[1].max(0.0), r[1].min(0.0), r[2]], d.y[i], d.cluster[i]);
            }
            out
        };
        let (fit, held) = (split(data(1)), split(data(2)));
        let t = |action, name, c: usize| Term { action, name, columns: vec![c] };
        let terms = vec![
            t(1, "turn.bias", 0),
            t(1, "turn.x1", 1),
            t(1, "turn.x1", 2),
            t(1, "turn.x2", 3),
            t(0, "thrust.bias", 0),
        ];
        let fits = term_fits(&terms, &fit, &held, 3);
        let (x1, x2) = (&fits[0], &fits[1]);
        assert_eq!((fits.len(), x1.name.as_str(), x2.name.as_str()), (2, "turn.x1", "turn.x2"));
        // The group as a whole: no single gain, the held-out value of leaving both columns out.
        assert!(x1.per_sd.is_none() && x1.per_sd_interval.is_none(), "{x1:?}");
        assert!((x1.held_out_gain.unwrap() - 1.0 / 1.09).abs() < 0.03, "{x1:?}");
        assert!(x2.per_sd.is_some() && x2.held_out_gain.unwrap().abs() < 0.005, "{x2:?}");
    }

    #[test]
    fn the_candidate_that_predicts_out_of_sample_is_chosen() {
        let fit = data(4);
        let t = |action, name, c: usize| Term { action, name, columns: vec![c] };
        let with = |c| vec![t(1, "turn.bias", 0), t(1, "turn.x", c), t(0, "thrust.bias", 0)];
        assert_eq!(choose(&fit.normals(), [with(2), with(1)].into_iter()), with(1));
    }

    #[test]
    fn cholesky_solves_a_known_system() {
        let x = cholesky_solve(&[4.0, 2.0, 2.0, 3.0], &[2.0, 1.0]);
        assert!((x[0] - 0.5).abs() < 1e-12 && x[1].abs() < 1e-12, "{x:?}");
    }
}
