//! The shape of a training curve (per-episode DoS, DoA or catches of one run) as one number: where it
//! starts ([`START`] episodes), the episode it completes half or 90 % of its change or first reaches a
//! level, its extreme and how far it falls back: the convergence quantities of the experiment files.

use super::file::{Curve, Fit};
use super::stats::mean;
use crate::sim::metrics::WINDOW;

/// The mean of a curve's first or last [`WINDOW`] values (its finite ones; NaN without any).
pub(crate) fn window_mean(values: &[f64], first: bool) -> f64 {
    let n = values.len().min(WINDOW);
    let part = if first { &values[..n] } else { &values[values.len() - n..] };
    mean(&part.iter().copied().filter(|v| v.is_finite()).collect::<Vec<_>>()).unwrap_or(f64::NAN)
}

/// The episode (from 1) at which the 100-episode running mean of `series` first completes 90 % of its
/// change from the first 100 episodes to the last 100; NaN when there is no change to complete.
pub(crate) fn reach90(series: &[f64]) -> f64 {
    first_completing(series, (window_mean(series, true), window_mean(series, false)), 0.9, WINDOW)
}

/// The episode (from 1) at which the `window`-episode running mean of `series`, from its first whole
/// window on, first completes `fraction` of the change from `start` to `end`; NaN when there is none.
fn first_completing(series: &[f64], (start, end): (f64, f64), fraction: f64, window: usize) -> f64 {
    if !(start.is_finite() && end.is_finite()) || start == end {
        return f64::NAN;
    }
    let target = start + fraction * (end - start);
    let running = super::stats::running_mean(series, window);
    running
        .iter()
        .enumerate()
        .skip(window.min(series.len()).saturating_sub(1))
        // A running sum carries rounding: within 1e-9 of the change counts as reached.
        .find(|(_, m)| (**m - target) * (end - start).signum() >= -1e-9 * (end - start).abs())
        .map_or(f64::NAN, |(t, _)| (t + 1) as f64)
}

/// The longest time constant [`fit_approach`] gives, in multiples of the curve's episodes: a curve that
/// still moves linearly at its end fits any long time about equally well, so its time is censored here
/// (a run ten times as long would be needed to see it settle).
pub(crate) const FIT_LONGEST: f64 = 10.0;

/// The least-squares fit of y(e) = end + (start − end)·exp(−(e − 1)/time) to a per-episode `series`
/// (episode e from 1; non-finite values left out): `[start, end, time]`, None for fewer than
/// [`WINDOW`] finite values or no change (start = end, so no time). For a fixed time the model is linear
/// in (end, start − end), solved exactly; the time is searched on a log grid from 1 episode to
/// [`FIT_LONGEST`] × the episodes (240 steps, each ≤ 5 % apart), then refined by golden-section search
/// between the grid point's neighbours. A rise and a fall are the same model; its sum of squares is
/// smooth in log time, and the grid keeps the search off a far local minimum.
pub(crate) fn fit_approach(series: &[f64]) -> Option<[f64; 3]> {
    let points: Vec<(f64, f64)> =
        series.iter().enumerate().filter(|(_, y)| y.is_finite()).map(|(e, &y)| (e as f64, y)).collect();
    if points.len() < WINDOW {
        return None;
    }
    // For one time: the exact (end, start − end) and the sum of squares left, each exponential taken once.
    let solve = |time: f64| -> (f64, f64, f64) {
        let n = points.len() as f64;
        let xs: Vec<f64> = points.iter().map(|&(e, _)| (-e / time).exp()).collect();
        let (mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0);
        for (&x, &(_, y)) in xs.iter().zip(&points) {
            (sx, sy, sxx, sxy) = (sx + x, sy + y, sxx + x * x, sxy + x * y);
        }
        let det = n * sxx - sx * sx;
        let b = if det > 0.0 { (n * sxy - sx * sy) / det } else { 0.0 };
        let a = (sy - b * sx) / n;
        let sse = xs.iter().zip(&points).map(|(&x, &(_, y))| (y - a - b * x).powi(2)).sum();
        (a, b, sse)
    };
    const STEPS: usize = 240;
    let longest = (FIT_LONGEST * series.len() as f64).ln();
    let at = |i: f64| (longest * i / STEPS as f64).exp();
    let best = (0..=STEPS)
        .map(|i| (i, solve(at(i as f64)).2))
        .fold((0, f64::INFINITY), |b, c| if c.1 < b.1 { c } else { b })
        .0;
    // Golden-section search on the grid index between the best point's neighbours.
    let (mut lo, mut hi) = (best.saturating_sub(1) as f64, (best + 1).min(STEPS) as f64);
    let g = (5f64.sqrt() - 1.0) / 2.0;
    for _ in 0..60 {
        let (m1, m2) = (hi - g * (hi - lo), lo + g * (hi - lo));
        if solve(at(m1)).2 <= solve(at(m2)).2 {
            hi = m2;
        } else {
            lo = m1;
        }
    }
    let time = at((lo + hi) / 2.0);
    let (end, change, _) = solve(time);
    (change != 0.0).then_some([end + change, end, time])
}

/// The training episodes whose mean is a curve's start ([`Quantity::Start`]).
pub(crate) const START: usize = 10;

/// The running mean's window of [`Quantity::Halfway`], in episodes: long enough to average a DoS
/// episode's noise (its SD ~0.015 at 10 prey) down to a few thousandths, short enough to resolve
/// curves that finish half their change within the first 100 episodes (most paper-preset DoA curves:
/// a 100-episode window's first value, at episode 100, is already past half).
pub(crate) const HALFWAY_WINDOW: usize = 20;

/// [`Quantity::Halfway`] of a per-episode `series`: the episode (from 1) at which its
/// [`HALFWAY_WINDOW`]-episode running mean first completes half of the change from its first [`START`]
/// episodes to its last 100; NaN when there is no change, or the run is shorter than 100 episodes.
fn halfway(series: &[f64]) -> f64 {
    if series.len() < WINDOW {
        return f64::NAN;
    }
    first_completing(series, (start(series), window_mean(series, false)), 0.5, HALFWAY_WINDOW)
}

/// [`Quantity::Reaches`] of a per-episode `series`: the episode (from 1) at which its
/// [`HALFWAY_WINDOW`]-episode running mean, from its first whole window on, first gets to `level` (to it
/// or below when `falling`, to it or above otherwise); the series' length + 1 when it never does; NaN when
/// the run is shorter than one window.
fn reaches(series: &[f64], level: f64, falling: bool) -> f64 {
    if series.len() < HALFWAY_WINDOW {
        return f64::NAN;
    }
    let running = super::stats::running_mean(series, HALFWAY_WINDOW);
    let sign = if falling { -1.0 } else { 1.0 };
    running
        .iter()
        .enumerate()
        .skip(HALFWAY_WINDOW - 1)
        // A running sum carries rounding: within 1e-9 of the level counts as there.
        .find(|(_, m)| (**m - level) * sign >= -1e-9)
        .map_or((series.len() + 1) as f64, |(t, _)| (t + 1) as f64)
}

/// [`Quantity::Start`] of a per-episode `series`: the mean of its first [`START`] finite values; NaN
/// when it is shorter.
fn start(series: &[f64]) -> f64 {
    if series.len() < START {
        return f64::NAN;
    }
    super::stats::mean(&series[..START].iter().copied().filter(|x| x.is_finite()).collect::<Vec<_>>())
        .unwrap_or(f64::NAN)
}

/// The per-episode training series a curve quantity reads: `dos`, `doa` or `catches`.
pub(crate) const CURVES: [Curve; 3] = [Curve::Dos, Curve::Doa, Curve::Catches];

/// The training series of the authors' DoS and DoA (`metrics.csv`'s `authors_dos_<prey>` and
/// `authors_doa_<prey>`, written with the scene's `authors_metrics`; differences 9–11 of docs/src/results/authors-code.md): besides
/// [`CURVES`], what [`Quantity::Start`], [`Quantity::FromStart`], [`Quantity::TrainingFirst`] and
/// [`Quantity::TrainingLast`] read, so the paper's numbers can be judged as the shipped code measures them.
pub(crate) const AUTHORS_CURVES: [&str; 2] = crate::store::schema::AUTHORS;

/// Which number of a training curve's shape a quantity reads (`Quantity::shape` says which curve and
/// which shape): where it starts, when it gets halfway or to a level, its fitted approach, its extreme.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Shape {
    /// [`Quantity::Start`].
    Start,
    /// [`Quantity::Halfway`].
    Halfway,
    /// [`Quantity::Reaches`] a level.
    Reaches(f64),
    /// A part of [`Quantity::Fitted`].
    Fitted(Fit),
    /// [`Quantity::Extreme`].
    Extreme,
    /// [`Quantity::ExtremeEpisode`].
    ExtremeEpisode,
    /// [`Quantity::AfterExtreme`].
    AfterExtreme,
}

/// A number of the shape of `curve`'s per-episode `series` as the figure data keeps it (single
/// precision), so that a summary written before these quantities existed is extended from the committed
/// figure data to the same bits as from the run folders. NaN where a run is too short: a start needs
/// [`START`] episodes, an extreme two windows, a halfway episode one window of 100.
pub(crate) fn curve_shape(shape: Shape, curve: Curve, series: &[f64]) -> f64 {
    let mean = |v: &mut dyn Iterator<Item = f64>| super::stats::mean(&v.filter(|x| x.is_finite()).collect::<Vec<_>>());
    match shape {
        Shape::Halfway => halfway(series),
        Shape::Reaches(level) => reaches(series, level, curve == Curve::Dos),
        Shape::Start => start(series),
        Shape::Fitted(part) => fit_approach(series).map_or(f64::NAN, |[start, end, time]| match part {
            Fit::Start => start,
            Fit::End => end,
            Fit::Time => time,
        }),
        // An extreme of a run too short for two windows.
        Shape::Extreme | Shape::ExtremeEpisode | Shape::AfterExtreme if series.len() < 2 * WINDOW => f64::NAN,
        Shape::Extreme | Shape::ExtremeEpisode | Shape::AfterExtreme => {
            // Windows end at episode t (1-based) for t in WINDOW..=len; within one, the odd episodes choose
            // and the even ones measure. Episode e (1-based) is series[e - 1].
            let half = |end: usize, odd: bool| {
                mean(&mut (end + 1 - WINDOW..=end).filter(|e| (e % 2 == 1) == odd).map(|e| series[e - 1]))
                    .unwrap_or(f64::NAN)
            };
            let peak = curve == Curve::Doa;
            let better = |a: f64, b: f64| if peak { a > b } else { a < b };
            let mut best = WINDOW;
            for end in WINDOW + 1..=series.len() {
                if better(half(end, true), half(best, true)) {
                    best = end;
                }
            }
            match shape {
                Shape::Extreme => half(best, false),
                Shape::ExtremeEpisode => best as f64,
                _ => half(series.len(), false) - half(best, false),
            }
        }
    }
}

/// What a curve's extreme is called: DoA's peak, DoS's trough.
pub(crate) fn extreme_word(curve: Curve) -> &'static str {
    if curve == Curve::Doa {
        "peak"
    } else {
        "trough"
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::claims::file::Quantity;

    /// A curve quantity's value, as `quantity` reads it.
    fn curve_shape(q: &Quantity, series: &[f64]) -> f64 {
        crate::claims::quantity::shape_of(q, series)
    }

    fn curve_argument_error(q: &Quantity) -> Option<String> {
        q.curve_argument_error()
    }

    #[test]
    fn a_curves_start_extreme_and_fall_back_are_cross_fitted() {
        let q = |f: fn(Curve) -> Quantity, curve: &str, series: &[f64]| {
            curve_shape(&f(Curve::parse(curve).unwrap()), series)
        };
        // Constant: the start and the extreme are the constant, the first window wins ties, no fall back.
        let flat = vec![0.75; 250];
        assert_eq!(q(Quantity::Start, "doa", &flat), 0.75);
        assert_eq!(q(Quantity::Extreme, "doa", &flat), 0.75);
        assert_eq!(q(Quantity::ExtremeEpisode, "doa", &flat), WINDOW as f64);
        assert_eq!(q(Quantity::AfterExtreme, "doa", &flat), 0.0);
        // Odd episodes choose, even ones measure: a curve whose odd episodes sit 0.5 above its even ones
        // has an extreme of the even level, not of the odd one.
        let zigzag: Vec<f64> = (1..=250).map(|e| if e % 2 == 1 { 1.0 } else { 0.5 }).collect();
        assert_eq!(q(Quantity::Extreme, "doa", &zigzag), 0.5);
        // A ramp e (episode e holds e): DoA's peak is chosen on the odd episodes 151, …, 249, which the
        // windows ending at 249 and 250 share: the first, 150–249, wins, measured on 150, …, 248 (mean
        // 199), 2 below the last window's even episodes. DoS's trough is the first window, episodes
        // 1–100, measured on its even episodes 2, 4, …, 100 (mean 51).
        let ramp: Vec<f64> = (1..=250).map(f64::from).collect();
        assert_eq!(q(Quantity::ExtremeEpisode, "doa", &ramp), 249.0);
        assert_eq!(q(Quantity::Extreme, "doa", &ramp), 199.0);
        assert_eq!(q(Quantity::AfterExtreme, "doa", &ramp), 2.0);
        assert_eq!(q(Quantity::ExtremeEpisode, "dos", &ramp), 100.0);
        assert_eq!(q(Quantity::Extreme, "dos", &ramp), 51.0);
        // Last window's even episodes 152, …, 250 (mean 201) minus 51.
        assert_eq!(q(Quantity::AfterExtreme, "dos", &ramp), 150.0);
        assert_eq!(q(Quantity::Start, "dos", &ramp), 5.5);
        // Too short: a start needs ten episodes, an extreme two windows.
        assert!(q(Quantity::Start, "doa", &ramp[..9]).is_nan());
        assert!(q(Quantity::Extreme, "doa", &ramp[..199]).is_nan());
        assert!(q(Quantity::Extreme, "doa", &ramp[..200]).is_finite());
    }

    #[test]
    fn the_episode_that_completes_half_a_change_from_the_start() {
        let halfway = |series: &[f64]| curve_shape(&Quantity::Halfway(Curve::Dos), series);
        // 0 for 60 episodes, then 1 for 240: the start is 0, the end 1; the 20-episode running mean at
        // episode t (from 1) is (t − 60)/20 past 60, so it first reaches 0.5 at episode 70; the same falling.
        let step: Vec<f64> = (0..300).map(|t| if t < 60 { 0.0 } else { 1.0 }).collect();
        assert_eq!(halfway(&step), 70.0);
        let falling: Vec<f64> = step.iter().map(|x| 1.0 - x).collect();
        assert_eq!(halfway(&falling), 70.0);
        // No window before the first whole one: a change at episode 13 is half done in the window of
        // episodes 3–22 (the mean of 1–20 is 0.4), so episode 22.
        let early: Vec<f64> = (0..300).map(|t| if t < 12 { 0.0 } else { 1.0 }).collect();
        assert_eq!(halfway(&early), 22.0);
        // The start is the first ten episodes, not the first window: a curve that starts at 1 and settles
        // at 0 after episode 10 has all its change done by episode 20 (the mean of 1–20 is 0.5).
        let drop: Vec<f64> = (0..300).map(|t| if t < 10 { 1.0 } else { 0.0 }).collect();
        assert_eq!(halfway(&drop), 20.0);
        assert!(halfway(&[0.5; 300]).is_nan(), "no change, no episode");
        assert!(halfway(&step[..99]).is_nan(), "shorter than the last window");
        let bad = curve_argument_error(&Quantity::Halfway(Curve::Catches)).unwrap();
        assert!(bad.contains("Halfway takes \"dos\" or \"doa\""), "{bad}");
    }

    #[test]
    fn the_episode_a_curve_gets_to_a_common_level() {
        let reaches = |curve: &str, level: f64, series: &[f64]| {
            curve_shape(&Quantity::Reaches(Curve::parse(curve).unwrap(), level), series)
        };
        // DoA 0 for 60 episodes, then 1: the 20-episode running mean at episode t (from 1) is (t − 60)/20
        // past 60, so it rises to 0.25 at episode 65 and to 0.75 at 75, whatever the run's own change.
        let step: Vec<f64> = (0..300).map(|t| if t < 60 { 0.0 } else { 1.0 }).collect();
        assert_eq!(reaches("doa", 0.25, &step), 65.0);
        assert_eq!(reaches("doa", 0.75, &step), 75.0);
        // DoS falls to its level: the same step mirrored.
        let falling: Vec<f64> = step.iter().map(|x| 1.0 - x).collect();
        assert_eq!(reaches("dos", 0.75, &falling), 65.0);
        // Never there: one episode after the run (300 episodes), not dropped.
        assert_eq!(reaches("doa", 0.75, &[0.5; 300]), 301.0);
        assert_eq!(reaches("dos", 0.25, &[0.5; 300]), 301.0);
        // Already there: the first whole window, episode 20.
        assert_eq!(reaches("doa", 0.25, &[0.5; 300]), 20.0);
        assert!(reaches("doa", 0.25, &[0.5; 19]).is_nan(), "shorter than one window");
        for (bad, says) in [
            (Quantity::Reaches(Curve::Catches, 0.5), "Reaches takes \"dos\" or \"doa\""),
            (Quantity::Reaches(Curve::Doa, 1.5), "a level in (0, 1]"),
            (Quantity::Reaches(Curve::Doa, f64::NAN), "a level in (0, 1]"),
        ] {
            let message = curve_argument_error(&bad).unwrap();
            assert!(message.contains(says), "{message}");
        }
    }

    /// Noise for the fits below: uniform in [−0.5, 0.5) × `size`, from a fixed linear congruential
    /// sequence (the test's answer must not depend on a generator's version).
    fn noise(n: usize, size: f64) -> Vec<f64> {
        let mut x: u64 = 12345;
        (0..n)
            .map(|_| {
                x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                ((x >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * size
            })
            .collect()
    }

    #[test]
    fn the_fit_recovers_a_known_approach_its_rate_apart_from_its_level() {
        let part = |p: Fit, series: &[f64]| curve_shape(&Quantity::Fitted(Curve::Doa, p), series);
        // A DoA curve rising from 0.6 to 0.9 with a time constant of 150 episodes over 2000, plus noise of
        // SD ~0.09 per episode (as large as a 10-prey DoA episode's): recovered within 10 % and 0.01.
        let curve_with = |size: f64, start: f64, end: f64, time: f64| -> Vec<f64> {
            let wiggle = noise(2000, size);
            (0..2000).map(|e| end + (start - end) * (-(e as f64) / time).exp() + wiggle[e]).collect()
        };
        let curve = |start, end, time| curve_with(0.3, start, end, time);
        // Without noise: exact, to the search's resolution.
        let exact = curve_with(0.0, 0.6, 0.9, 150.0);
        assert!((part(Fit::Time, &exact) - 150.0).abs() < 1e-3, "{}", part(Fit::Time, &exact));
        assert!((part(Fit::End, &exact) - 0.9).abs() < 1e-9 && (part(Fit::Start, &exact) - 0.6).abs() < 1e-9);
        let slow = curve(0.6, 0.9, 150.0);
        assert!((part(Fit::Time, &slow) / 150.0 - 1.0).abs() < 0.1, "{}", part(Fit::Time, &slow));
        assert!((part(Fit::End, &slow) - 0.9).abs() < 0.01, "{}", part(Fit::End, &slow));
        assert!((part(Fit::Start, &slow) - 0.6).abs() < 0.05, "{}", part(Fit::Start, &slow));
        // Faster to a lower level: a faster time and a lower end, each read apart from the other (the
        // change of 0.2 spans ~30 noisy episodes, so its time is known to ~15 %).
        let fast = curve(0.6, 0.8, 30.0);
        assert!((part(Fit::Time, &fast) / 30.0 - 1.0).abs() < 0.2, "{}", part(Fit::Time, &fast));
        assert!((part(Fit::End, &fast) - 0.8).abs() < 0.01);
        // A fall is the same model.
        let fall: Vec<f64> = slow.iter().map(|y| 1.5 - y).collect();
        assert!((part(Fit::Time, &fall) / 150.0 - 1.0).abs() < 0.1);
        // A curve still moving linearly at its end: its time is censored at FIT_LONGEST × its episodes.
        let ramp: Vec<f64> = (0..500).map(|e| e as f64 / 500.0).collect();
        assert!(part(Fit::Time, &ramp) > 0.9 * FIT_LONGEST * 500.0, "{}", part(Fit::Time, &ramp));
        // Missing episodes are left out; fewer than a window of values, or no change, gives no fit.
        let mut gaps = slow.clone();
        gaps.iter_mut().step_by(7).for_each(|y| *y = f64::NAN);
        assert!((part(Fit::Time, &gaps) / 150.0 - 1.0).abs() < 0.1);
        assert!(part(Fit::Time, &slow[..99]).is_nan());
        assert!(part(Fit::Time, &[0.5; 300]).is_nan());
        let bad = curve_argument_error(&Quantity::Fitted(Curve::AuthorsDoa, Fit::Time)).unwrap();
        assert!(bad.contains("Fitted takes"), "{bad}");
    }

    #[test]
    fn the_episode_that_completes_ninety_percent_of_a_change() {
        // 0 for 200 episodes, then 1 for 200: the 100-episode running mean at episode t (from 1) is
        // (t − 200)/100 past 200, so it first reaches 0.9 at episode 290; the same falling.
        let step: Vec<f64> = (0..400).map(|t| if t < 200 { 0.0 } else { 1.0 }).collect();
        assert_eq!(reach90(&step), 290.0);
        let falling: Vec<f64> = step.iter().map(|x| 1.0 - x).collect();
        assert_eq!(reach90(&falling), 290.0);
        assert!(reach90(&[0.5; 300]).is_nan(), "no change, no episode");
    }
}
