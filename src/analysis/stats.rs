//! The statistics of the paper's figures and of the verdicts on its claims: 100-episode running means; the
//! mean over seeds with its 95 % confidence interval (Student t, n − 1 degrees of freedom); the difference
//! of two variants' means with Welch's interval (unequal variances); their two-sided p-values, Holm's
//! adjustment for a family of comparisons, the 90 % interval of an equivalence test (TOST), and the power
//! of a design (the smallest effect its seeds detect with 80 % power, the seeds an effect needs).
//! Student t quantiles and distribution functions come from `statrs`.

pub(crate) use crate::sim::metrics::running_mean;

/// Mean of a slice (None when empty).
pub(crate) fn mean(values: &[f64]) -> Option<f64> {
    (!values.is_empty()).then(|| values.iter().sum::<f64>() / values.len() as f64)
}

/// The percentile interval of bootstrap `resamples` at `level` (two-sided; as many resamples left out below
/// as above): a NaN resample counts at both ends, as −∞ for the lower bound and +∞ for the upper.
pub(crate) fn percentile_interval(resamples: &[f64], level: f64) -> (f64, f64) {
    let b = resamples.len();
    let mut low: Vec<f64> = resamples.iter().map(|r| if r.is_nan() { f64::NEG_INFINITY } else { *r }).collect();
    let mut high: Vec<f64> = resamples.iter().map(|r| if r.is_nan() { f64::INFINITY } else { *r }).collect();
    low.sort_by(f64::total_cmp);
    high.sort_by(f64::total_cmp);
    let k = ((level / 2.0) * b as f64).floor() as usize;
    (low[k.min(b - 1)], high[(b - 1).saturating_sub(k)])
}

/// The least-squares slope of `y` on `x` (NaN when `x` does not vary).
pub(crate) fn least_squares(x: &[f64], y: &[f64]) -> f64 {
    let (mx, my) = (mean(x).unwrap_or(f64::NAN), mean(y).unwrap_or(f64::NAN));
    let sxx: f64 = x.iter().map(|a| (a - mx).powi(2)).sum();
    x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum::<f64>() / sxx
}

/// The `p` quantile of Student's t with `df` degrees of freedom (NaN for df ≤ 0).
pub(crate) fn t_quantile(p: f64, df: f64) -> f64 {
    use statrs::distribution::{ContinuousCDF, StudentsT};
    StudentsT::new(0.0, 1.0, df).map_or(f64::NAN, |t| t.inverse_cdf(p))
}

/// The two-sided 95 % quantile of Student's t with `df` degrees of freedom.
pub(crate) fn t95(df: usize) -> f64 {
    t_quantile(0.975, df as f64)
}

/// Mean and half-width of the 95 % confidence interval of the mean of independent samples (one per seed),
/// or of a difference of two variants' means (Welch). The interval, standard error and degrees of freedom
/// are None with a single sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    pub mean: f64,
    pub ci: Option<f64>,
    /// Samples: seeds, or for a difference the smaller of the two counts.
    pub n: usize,
    /// Standard error of the mean (or of the difference) and its degrees of freedom.
    pub(crate) se: Option<f64>,
    pub df: Option<f64>,
    /// What was estimated, for the seeds a design would need ([`Estimate::seeds_for`]).
    pub(crate) design: Design,
}

/// What an [`Estimate`] estimates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Design {
    /// One group's mean (n seeds).
    Mean,
    /// A difference of two independent groups (Welch; n the smaller).
    Difference,
    /// A least-squares slope over `levels` levels of n seeds each (a grid's trend).
    Slope { levels: usize },
    /// A statistic of a bootstrap over n seeds per cell (a grid's boundary), its standard error the
    /// resamples' spread.
    Bootstrap,
}

pub fn estimate(samples: &[f64]) -> Option<Estimate> {
    let n = samples.len();
    let m = mean(samples)?;
    let se = (n >= 2).then(|| (variance(samples, m) / n as f64).sqrt());
    let df = (n >= 2).then(|| (n - 1) as f64);
    let ci = se.map(|se| t95(n - 1) * se);
    Some(Estimate { mean: m, ci, n, se, df, design: Design::Mean })
}

/// The sample variance (n − 1 in the denominator) about the samples' mean `m`.
fn variance(samples: &[f64], m: f64) -> f64 {
    samples.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (samples.len() - 1) as f64
}

/// Mean of `a` minus mean of `b`, with the half-width of Welch's 95 % interval: standard error
/// √(s²_a/n_a + s²_b/n_b), Student t at the Welch–Satterthwaite degrees of freedom rounded down (the
/// conservative side). `n` is the smaller sample; the interval is None unless both have two or more.
pub fn difference(a: &[f64], b: &[f64]) -> Option<Estimate> {
    let (ma, mb) = (mean(a)?, mean(b)?);
    let n = a.len().min(b.len());
    let (se, df) = if n >= 2 {
        let (qa, qb) = (variance(a, ma) / a.len() as f64, variance(b, mb) / b.len() as f64);
        let se2 = qa + qb;
        let df = se2 * se2 / (qa * qa / (a.len() - 1) as f64 + qb * qb / (b.len() - 1) as f64);
        // Identical samples on both sides (no spread at all) leave df undefined: the interval is zero.
        let df = if df.is_finite() { df.floor().max(1.0) } else { (a.len() + b.len() - 2) as f64 };
        (Some(se2.sqrt()), Some(df))
    } else {
        (None, None)
    };
    let ci = se.zip(df).map(|(se, df)| t_quantile(0.975, df) * se);
    Some(Estimate { mean: ma - mb, ci, n, se, df, design: Design::Difference })
}

impl Estimate {
    /// A claim's own test of this estimate: TOST's p-value of equivalence within ±`margin` for a claim of
    /// no effect, else the two-sided test of none ([`Estimate::p_value`]).
    pub(crate) fn test_p(&self, margin: Option<f64>) -> Option<f64> {
        match margin {
            Some(m) => self.tost_p(m),
            None => self.p_value(),
        }
    }

    /// Two-sided p-value of "the mean (or difference) is zero" (Student / Welch t test). None without an
    /// interval; 1 when there is no spread and the mean is 0, 0 when there is no spread and it is not.
    pub fn p_value(&self) -> Option<f64> {
        use statrs::distribution::{ContinuousCDF, StudentsT};
        let (se, df) = (self.se?, self.df?);
        if se == 0.0 {
            return Some(if self.mean == 0.0 { 1.0 } else { 0.0 });
        }
        let t = StudentsT::new(0.0, 1.0, df).ok()?;
        Some((2.0 * (1.0 - t.cdf((self.mean / se).abs()))).clamp(0.0, 1.0))
    }

    /// The 90 % interval [lo, hi] of the two one-sided tests (TOST) at α = 0.05: equivalence within ±m
    /// holds when it lies inside (−m, m).
    #[cfg(test)]
    pub(crate) fn tost_interval(&self) -> Option<(f64, f64)> {
        let half = t_quantile(0.95, self.df?) * self.se?;
        Some((self.mean - half, self.mean + half))
    }

    /// The smallest |effect| this design detects with 80 % power in a two-sided test at α = 0.05:
    /// (t₀.₉₇₅ + t₀.₈₀) · standard error, the standard approximation of the noncentral t.
    #[cfg(test)]
    pub(crate) fn detectable(&self) -> Option<f64> {
        let (se, df) = (self.se?, self.df?);
        Some((t_quantile(0.975, df) + t_quantile(0.80, df)) * se)
    }

    /// Seeds (per group, for a difference) that detect `effect` with 80 % power in a two-sided test at
    /// `alpha` given the spread seen here: the smallest m with |effect|·√m / σ ≥ t₁₋α/₂ + t₀.₈₀ at m − 1
    /// degrees of freedom (one group), or |effect|·√(m/2) / σ at 2m − 2 (two groups of m, σ the pooled
    /// SD). None without spread or beyond 10 000.
    pub(crate) fn seeds_for(&self, alpha: f64, effect: f64) -> Option<usize> {
        let se = self.se.filter(|&se| se > 0.0)?;
        // The standard error with m seeds: σ·√(scale/m), at these degrees of freedom.
        let (sigma, scale, df): (f64, f64, Box<dyn Fn(usize) -> f64>) = match self.design {
            // se² = (s²_a + s²_b) / n with n per group: the pooled σ² = se²·n/2.
            Design::Difference => (se * (self.n as f64 / 2.0).sqrt(), 0.5, Box::new(|m| (2 * m - 2) as f64)),
            Design::Mean => (se * (self.n as f64).sqrt(), 1.0, Box::new(|m| (m - 1) as f64)),
            // A slope's and a bootstrap statistic's standard error shrink as 1/√seeds per level.
            Design::Slope { levels } => (se * (self.n as f64).sqrt(), 1.0, Box::new(move |m| (levels * m - 2) as f64)),
            Design::Bootstrap => (se * (self.n as f64).sqrt(), 1.0, Box::new(|_| 1e6)),
        };
        (2..=10_000).find(|&m| {
            let df = df(m);
            effect.abs() * (scale * m as f64).sqrt() / sigma >= t_quantile(1.0 - alpha / 2.0, df) + t_quantile(0.80, df)
        })
    }
}

/// Holm's step-down adjustment of a family of p-values (same order as given): the k-th smallest becomes
/// max over j ≤ k of min(1, (m − j + 1)·p₍ⱼ₎). Controls the family-wise error rate at α without assuming
/// independence.
pub fn holm(p: &[f64]) -> Vec<f64> {
    let m = p.len();
    let mut order: Vec<usize> = (0..m).collect();
    order.sort_by(|&a, &b| p[a].total_cmp(&p[b]));
    let mut adjusted = vec![0.0; m];
    let mut running: f64 = 0.0;
    for (k, &i) in order.iter().enumerate() {
        running = running.max(((m - k) as f64 * p[i]).min(1.0));
        adjusted[i] = running;
    }
    adjusted
}

/// The level α_k at which each test of a family is shown as an interval so that its interval excludes zero
/// exactly when Holm's procedure at `alpha` rejects it (same order as `p`). Holm tests the k-th smallest
/// p-value (k from 0) at α/(m − k) and stops at the first that fails; a rejected test is shown at its own
/// step's level, every test from the first failure on at the failed step's level (its p-value is at least
/// the failed one's, so its interval holds zero). Bonferroni's α/m for the smallest p-value, and never
/// wider than Bonferroni's interval for a rejected test.
pub(crate) fn holm_levels(p: &[f64], alpha: f64) -> Vec<f64> {
    let m = p.len();
    // The decisions are holm()'s own (so a p-value one rounding away from a step boundary is judged the
    // same way in both); a NaN p-value counts as 1.
    let p: Vec<f64> = p.iter().map(|&x| if x.is_nan() { 1.0 } else { x }).collect();
    let adjusted = holm(&p);
    let mut order: Vec<usize> = (0..m).collect();
    order.sort_by(|&a, &b| p[a].total_cmp(&p[b]));
    let mut levels = vec![alpha; m];
    let mut failed: Option<f64> = None;
    for (k, &i) in order.iter().enumerate() {
        let step = alpha / (m - k) as f64;
        levels[i] = match failed {
            Some(level) => level,
            None if adjusted[i] < alpha => step,
            None => *failed.insert(step),
        };
    }
    levels
}

impl Estimate {
    /// The two-sided (1 − `alpha`) interval's half-width: Student (one group) or Welch (two), at this
    /// estimate's degrees of freedom. None without spread information (one sample).
    pub(crate) fn half_width(&self, alpha: f64) -> Option<f64> {
        Some(t_quantile(1.0 - alpha / 2.0, self.df?) * self.se?)
    }

    /// The p-value of the two one-sided tests (TOST) of equivalence within ±`margin`: the larger of the
    /// p-values of "effect ≤ −margin" and "effect ≥ +margin". Equivalence holds at level α when it is
    /// below α, which is when the (1 − 2α) interval lies inside (−margin, margin).
    pub(crate) fn tost_p(&self, margin: f64) -> Option<f64> {
        use statrs::distribution::{ContinuousCDF, StudentsT};
        let (se, df) = (self.se?, self.df?);
        if se == 0.0 {
            return Some(if self.mean.abs() < margin { 0.0 } else { 1.0 });
        }
        let t = StudentsT::new(0.0, 1.0, df).ok()?;
        let lower = 1.0 - t.cdf((self.mean + margin) / se);
        let upper = t.cdf((self.mean - margin) / se);
        Some(lower.max(upper))
    }

    /// The smallest |effect| a two-sided test at `alpha` detects with 80 % power:
    /// (t_{1−α/2} + t₀.₈₀) · standard error.
    pub(crate) fn detectable_at(&self, alpha: f64) -> Option<f64> {
        let (se, df) = (self.se?, self.df?);
        Some((t_quantile(1.0 - alpha / 2.0, df) + t_quantile(0.80, df)) * se)
    }
}

/// Kendall's rank correlation τ_b of paired values (ties counted as in τ_b): +1 when `y` rises with `x`
/// in every pair, −1 when it always falls. None with fewer than two pairs, a non-finite value, or no
/// untied pair in `x` or in `y`.
pub(crate) fn kendall_tau(x: &[f64], y: &[f64]) -> Option<f64> {
    let n = x.len().min(y.len());
    if n < 2 || x[..n].iter().chain(&y[..n]).any(|v| !v.is_finite()) {
        return None;
    }
    let (mut score, mut untied_x, mut untied_y) = (0.0, 0.0, 0.0);
    for i in 0..n {
        for j in i + 1..n {
            let (dx, dy) = (x[j] - x[i], y[j] - y[i]);
            score += (dx.signum() * dy.signum()) * f64::from(u8::from(dx != 0.0 && dy != 0.0));
            untied_x += f64::from(u8::from(dx != 0.0));
            untied_y += f64::from(u8::from(dy != 0.0));
        }
    }
    (untied_x > 0.0 && untied_y > 0.0).then(|| score / (untied_x * untied_y).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn holm_levels_agree_with_holm_and_bonferroni() {
        // Textbook Bonferroni: a family of 5 at α = 0.05, 9 degrees of freedom: t at 1 − 0.005 is 3.2498.
        let e = Estimate { mean: 1.0, ci: None, n: 10, se: Some(0.1), df: Some(9.0), design: Design::Mean };
        assert!((e.half_width(0.05 / 5.0).unwrap() - 0.32498).abs() < 1e-4);
        assert!((e.half_width(0.05).unwrap() - 0.2262).abs() < 1e-4, "the plain 95 % interval");
        // The interval at each test's level excludes zero exactly when Holm rejects it.
        let cases: [&[f64]; 4] = [
            &[0.001, 0.012, 0.02, 0.04],
            &[0.04, 0.001, 0.3, 0.011],
            &[0.2, 0.5, 0.9],
            &[0.0126, 0.0124, 0.02, 0.03, 0.049],
        ];
        for p in cases {
            let (levels, adjusted) = (holm_levels(p, 0.05), holm(p));
            for i in 0..p.len() {
                assert_eq!(p[i] < levels[i], adjusted[i] < 0.05, "p {p:?}, test {i}: level {}", levels[i]);
            }
            let smallest = (0..p.len()).min_by(|&a, &b| p[a].total_cmp(&p[b])).unwrap();
            assert_eq!(levels[smallest], 0.05 / p.len() as f64, "Bonferroni's level first");
        }
        // A p-value below its own step but after a failed step is not rejected, and its level says so:
        // 0.04 fails the first step (0.05/3), so 0.049 < 0.05/1 is never reached.
        let p = [0.04, 0.045, 0.049];
        assert!(holm_levels(&p, 0.05).iter().zip(&p).all(|(l, p)| p >= l));
        // Ties, a p-value exactly at its step (not below it: not rejected), and a NaN (counted as 1).
        let p = [0.01, 0.01, 0.0125, f64::NAN];
        let (levels, adjusted) = (holm_levels(&p, 0.05), holm(&[0.01, 0.01, 0.0125, 1.0]));
        for i in 0..4 {
            assert_eq!(p[i] < levels[i], adjusted[i] < 0.05, "test {i}: level {}", levels[i]);
        }
    }

    #[test]
    fn tost_of_a_known_example() {
        // Mean 0.01, se 0.02, 20 df, margin 0.05: t = (0.05 − 0.01)/0.02 = 2 on the upper side (the larger
        // p) and 3 on the lower: p = P(T₂₀ > 2) = 0.02963.
        let e = Estimate { mean: 0.01, ci: None, n: 11, se: Some(0.02), df: Some(20.0), design: Design::Difference };
        assert!((e.tost_p(0.05).unwrap() - 0.029633).abs() < 1e-5, "{:?}", e.tost_p(0.05));
        // Below α = 0.05 exactly when the 90 % interval lies inside the margin.
        let (lo, hi) = e.tost_interval().unwrap();
        assert!(-0.05 < lo && hi < 0.05);
        assert!(e.tost_p(0.04).unwrap() > 0.05 && e.tost_interval().unwrap().1 > 0.04);
        // The same, mirrored: a negative mean gives the same p-value.
        let mirrored = Estimate { mean: -0.01, ..e };
        assert!((mirrored.tost_p(0.05).unwrap() - e.tost_p(0.05).unwrap()).abs() < 1e-12);
        // No spread: equivalent exactly when the mean is inside the margin.
        let exact = Estimate { se: Some(0.0), ..e };
        assert_eq!((exact.tost_p(0.05), exact.tost_p(0.005)), (Some(0.0), Some(1.0)));
    }

    #[test]
    fn kendall_tau_of_known_orders() {
        let x = [0.0, 1.0, 2.0, 3.0];
        assert_eq!(kendall_tau(&x, &[1.0, 2.0, 3.0, 9.0]), Some(1.0));
        assert_eq!(kendall_tau(&x, &[9.0, 3.0, 2.0, 1.0]), Some(-1.0));
        // 5 concordant, 1 discordant of 6 pairs: (5 - 1) / 6.
        let tau = kendall_tau(&x, &[1.0, 3.0, 2.0, 4.0]).unwrap();
        assert!((tau - 4.0 / 6.0).abs() < 1e-12, "{tau}");
        // τ_b with a tie in y: 4 concordant, 1 discordant, 1 tied in y: 3 / sqrt(6 * 5).
        let tau = kendall_tau(&x, &[1.0, 2.0, 2.0, 0.5]).unwrap();
        let expected = (2.0 - 3.0) / (6.0f64 * 5.0).sqrt();
        assert!((tau - expected).abs() < 1e-12, "{tau} vs {expected}");
        assert_eq!(kendall_tau(&x, &[2.0; 4]), None, "no order in y");
        assert_eq!(kendall_tau(&x[..1], &[1.0]), None);
        assert_eq!(kendall_tau(&x, &[1.0, f64::NAN, 2.0, 3.0]), None);
    }

    #[test]
    fn running_means_and_intervals_of_known_data() {
        assert_eq!(running_mean(&[1.0, 3.0, 5.0, 7.0], 2), vec![1.0, 2.0, 4.0, 6.0]);
        let e = estimate(&[1.0, 2.0, 3.0]).unwrap();
        assert_eq!(e.mean, 2.0);
        // s = 1, n = 3: 4.303 / √3.
        assert!((e.ci.unwrap() - 4.303 / 3f64.sqrt()).abs() < 1e-3);
        assert_eq!(estimate(&[5.0]).unwrap().ci, None);
        assert!(estimate(&[]).is_none());
        // Textbook quantiles: t₀.₉₇₅ at 1, 10 and 1000 degrees of freedom.
        for (df, t) in [(1, 12.706), (10, 2.228), (1000, 1.962)] {
            assert!((t95(df) - t).abs() < 1e-3, "df {df}: {}", t95(df));
        }
    }

    #[test]
    fn welch_difference_of_known_data() {
        // Means 2 and 6, variances 1 and 4, n = 3 each: se² = 5/3, df = (5/3)² / ((1/3)²/2 + (4/3)²/2) =
        // 2.94, rounded down to 2.
        let d = difference(&[1.0, 2.0, 3.0], &[4.0, 6.0, 8.0]).unwrap();
        assert_eq!(d.mean, -4.0);
        assert!((d.ci.unwrap() - 4.303 * (5.0f64 / 3.0).sqrt()).abs() < 1e-3);
        assert_eq!(d.n, 3);
        assert_eq!(difference(&[1.0, 2.0], &[3.0]).unwrap().ci, None);
        assert_eq!(difference(&[1.0, 1.0], &[1.0, 1.0]).unwrap().ci, Some(0.0));
        assert!(difference(&[], &[1.0]).is_none());
    }

    #[test]
    fn p_values_of_known_data() {
        // One sample 1, 2, 3: t = 2 / (1/√3) = 3.464 at 2 df, two-sided p = 0.0742.
        let e = estimate(&[1.0, 2.0, 3.0]).unwrap();
        assert!((e.p_value().unwrap() - 0.0742).abs() < 1e-4, "{:?}", e.p_value());
        // A difference of −4 with se √(5/3) at 2 df: t = −3.098, p = 0.0903.
        let d = difference(&[1.0, 2.0, 3.0], &[4.0, 6.0, 8.0]).unwrap();
        assert!((d.p_value().unwrap() - 0.0903).abs() < 1e-4, "{:?}", d.p_value());
        assert_eq!(estimate(&[2.0, 2.0]).unwrap().p_value(), Some(0.0));
        assert_eq!(estimate(&[0.0, 0.0]).unwrap().p_value(), Some(1.0));
    }

    #[test]
    fn holm_on_a_known_family() {
        // m = 4, sorted p 0.01, 0.02, 0.03, 0.04: 0.04, 0.06, 0.06 (monotone), 0.06; in the given order.
        let adjusted = holm(&[0.03, 0.01, 0.04, 0.02]);
        let expected = [0.06, 0.04, 0.06, 0.06];
        for (a, e) in adjusted.iter().zip(expected) {
            assert!((a - e).abs() < 1e-12, "{adjusted:?}");
        }
        assert_eq!(holm(&[0.5, 0.9]), vec![1.0, 1.0]);
        assert!(holm(&[]).is_empty());
    }

    #[test]
    fn power_against_textbook_sample_sizes() {
        // Cohen's d = 0.5, α = 0.05 two-sided, power 0.8: 34 for a one-sample (or paired) t test and 64
        // per group for two independent groups (G*Power's and Cohen's tables).
        let sd1 = |n: usize| Estimate {
            mean: 0.0,
            ci: None,
            n,
            se: Some(1.0 / (n as f64).sqrt()),
            df: Some((n - 1) as f64),
            design: Design::Mean,
        };
        assert_eq!(sd1(10).seeds_for(0.05, 0.5), Some(34));
        let sd2 = |n: usize| Estimate {
            mean: 0.0,
            ci: None,
            n,
            se: Some((2.0 / n as f64).sqrt()),
            df: Some((2 * n - 2) as f64),
            design: Design::Difference,
        };
        assert_eq!(sd2(10).seeds_for(0.05, 0.5), Some(64));
        // The detectable effect of 34 seeds at σ = 1 is about 0.5.
        let d = sd1(34).detectable().unwrap();
        assert!((d - 0.5).abs() < 0.01, "{d}");
        // The TOST interval is the 90 % one: t₀.₉₅ at 9 df = 1.833.
        let (lo, hi) = sd1(10).tost_interval().unwrap();
        assert!((hi - lo - 2.0 * 1.833 / 10f64.sqrt()).abs() < 1e-3);
    }
}
