//! The statistics of the paper's figures: 100-episode running means, and the mean over seeds with its
//! 95 % confidence interval (Student t, n − 1 degrees of freedom).

pub use crate::sim::metrics::running_mean;

/// Mean of a slice (None when empty).
pub fn mean(values: &[f64]) -> Option<f64> {
    (!values.is_empty()).then(|| values.iter().sum::<f64>() / values.len() as f64)
}

/// The two-sided 95 % quantile of Student's t with `df` degrees of freedom.
pub fn t95(df: usize) -> f64 {
    const TABLE: [f64; 30] = [
        12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160, 2.145, 2.131, 2.120,
        2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042,
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
    let ci = (n >= 2).then(|| {
        let var = samples.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1) as f64;
        t95(n - 1) * (var / n as f64).sqrt()
    });
    Some(Estimate { mean: m, ci, n })
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
}
