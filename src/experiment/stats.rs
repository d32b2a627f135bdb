//! The statistics of the paper's figures: 100-episode running means, and the mean over seeds with its
//! 95 % confidence interval (Student t, n − 1 degrees of freedom); and the difference of two variants'
//! means with Welch's interval (unequal variances), for comparing a variant with the one it changes.

pub use crate::sim::metrics::running_mean;

/// Mean of a slice (None when empty).
pub fn mean(values: &[f64]) -> Option<f64> {
    (!values.is_empty()).then(|| values.iter().sum::<f64>() / values.len() as f64)
}

/// The two-sided 95 % quantile of Student's t with `df` degrees of freedom.
pub fn t95(df: usize) -> f64 {
    const TABLE: [f64; 30] = [
        12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160, 2.145, 2.131,
        2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042,
    ];
    match df {
        0 => f64::NAN,
        1..=30 => TABLE[df - 1],
        31..=60 => 2.000,
        61..=120 => 1.980,
        _ => 1.960,
    }
}

/// Mean and half-width of the 95 % confidence interval of the mean of independent samples (one per seed).
/// The half-width is None with a single sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    pub mean: f64,
    pub ci: Option<f64>,
    pub n: usize,
}

pub fn estimate(samples: &[f64]) -> Option<Estimate> {
    let n = samples.len();
    let m = mean(samples)?;
    let ci = (n >= 2).then(|| t95(n - 1) * (variance(samples, m) / n as f64).sqrt());
    Some(Estimate { mean: m, ci, n })
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
    let ci = (n >= 2).then(|| {
        let (qa, qb) = (variance(a, ma) / a.len() as f64, variance(b, mb) / b.len() as f64);
        let se2 = qa + qb;
        let df = se2 * se2 / (qa * qa / (a.len() - 1) as f64 + qb * qb / (b.len() - 1) as f64);
        // Identical samples on both sides (no spread at all) leave df undefined: the interval is zero.
        let df = if df.is_finite() { (df.floor() as usize).max(1) } else { a.len() + b.len() - 2 };
        t95(df) * se2.sqrt()
    });
    Some(Estimate { mean: ma - mb, ci, n })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn running_means_and_intervals_of_known_data() {
        assert_eq!(running_mean(&[1.0, 3.0, 5.0, 7.0], 2), vec![1.0, 2.0, 4.0, 6.0]);
        let e = estimate(&[1.0, 2.0, 3.0]).unwrap();
        assert_eq!(e.mean, 2.0);
        // s = 1, n = 3: 4.303 / √3.
        assert!((e.ci.unwrap() - 4.303 / 3f64.sqrt()).abs() < 1e-12);
        assert_eq!(estimate(&[5.0]).unwrap().ci, None);
        assert!(estimate(&[]).is_none());
        assert_eq!(t95(1000), 1.96);
    }

    #[test]
    fn welch_difference_of_known_data() {
        // Means 2 and 6, variances 1 and 4, n = 3 each: se² = 5/3, df = (5/3)² / ((1/3)²/2 + (4/3)²/2) =
        // 2.94, rounded down to 2.
        let d = difference(&[1.0, 2.0, 3.0], &[4.0, 6.0, 8.0]).unwrap();
        assert_eq!(d.mean, -4.0);
        assert!((d.ci.unwrap() - 4.303 * (5.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert_eq!(d.n, 3);
        assert_eq!(difference(&[1.0, 2.0], &[3.0]).unwrap().ci, None);
        assert_eq!(difference(&[1.0, 1.0], &[1.0, 1.0]).unwrap().ci, Some(0.0));
        assert!(difference(&[], &[1.0]).is_none());
    }
}
