//! An experiment's grid (`grid:` in its file): one or two axes of levels expanded into one variant per
//! cell, and the claims that read it (`GridTest`): a trend along an axis, the boundary where a quantity
//! crosses a value, and how that boundary moves with the other axis. The field maps collective states over
//! two parameters so (Couzin et al. 2002, Fig. 2; Tunstrøm et al. 2013), and a trend over every level
//! decides with fewer seeds than pairs of levels against a standard arm.

use super::file::{Axis, ExperimentFile, GridTest, Level, VariantFile};
use crate::scene::{parse_ron, ScenePatch};

/// At most this many axes: a map is drawn over two.
pub(crate) const MAX_AXES: usize = 2;

/// The patch that sets the scene number at `path` ("species.prey.max_speed") to `value`, as a scene file
/// would write it, so that a path naming no field is refused as a scene file's unknown field is.
fn patch_at(path: &str, value: f64) -> Result<ScenePatch, String> {
    fn fields(segments: &[&str], value: f64) -> Result<String, String> {
        match segments {
            [] => Err("is empty".into()),
            ["species"] => Err("names no species (species.NAME.FIELD)".into()),
            [field] => Ok(format!("{field}: {value}")),
            ["species", name, rest @ ..] => Ok(format!("species: [(name: {name:?}, {})]", fields(rest, value)?)),
            [field, rest @ ..] => Ok(format!("{field}: ({})", fields(rest, value)?)),
        }
    }
    let segments: Vec<&str> = path.split('.').collect();
    if segments.iter().any(|s| s.is_empty() || !s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')) {
        return Err(format!("path {path:?} is not a dotted path of scene fields (e.g. \"species.prey.max_speed\")"));
    }
    let text = format!("({})", fields(&segments, value).map_err(|m| format!("path {path:?} {m}"))?);
    parse_ron::<ScenePatch>(&text, path).map_err(|e| format!("path {path:?}: {}", e.message))
}

/// Resolves each axis to its levels (a `path` and `values` become levels labelled by the values) and
/// appends one variant per cell to the file's variants. Err is (field, message).
pub(crate) fn expand(spec: &mut ExperimentFile) -> Result<(), (String, String)> {
    if spec.grid.len() > MAX_AXES {
        return Err(("grid".into(), format!("at most {MAX_AXES} axes (got {})", spec.grid.len())));
    }
    for axis in &mut spec.grid {
        let field = |f: &str| format!("grid[{}].{f}", axis.name);
        if axis.name.trim().is_empty() {
            return Err(("grid".into(), "every axis needs a name".into()));
        }
        match (&axis.path, axis.values.is_empty(), axis.levels.is_empty()) {
            (Some(path), false, true) => {
                let path = path.clone();
                for &value in &axis.values {
                    if !value.is_finite() {
                        return Err((field("values"), format!("must be finite numbers (got {value})")));
                    }
                    let patch = patch_at(&path, value).map_err(|m| (field("path"), m))?;
                    axis.levels.push(Level { label: format!("{value}"), value, patch });
                }
            }
            (None, true, false) => {}
            _ => {
                return Err((
                    field("levels"),
                    "give either path and values, or levels (label, value, patch), and at least one level".into(),
                ))
            }
        }
        if let Some(level) = axis.levels.iter().find(|l| !l.value.is_finite() || l.label.trim().is_empty()) {
            return Err((field("levels"), format!("level {:?}: needs a label and a finite value", level.label)));
        }
        for pair in axis.levels.windows(2) {
            if pair[0].value >= pair[1].value {
                return Err((
                    field("levels"),
                    format!("values must increase along the axis ({} then {})", pair[0].value, pair[1].value),
                ));
            }
        }
    }
    if let [a, b] = &spec.grid[..] {
        if a.name == b.name {
            return Err(("grid".into(), format!("two axes named {:?}", a.name)));
        }
    }
    for cell in cells(&spec.grid) {
        let levels: Vec<&Level> = levels_of(&spec.grid, &cell).collect();
        spec.variants.push(VariantFile {
            name: levels.iter().map(|l| l.label.as_str()).collect::<Vec<_>>().join(", "),
            patch: ScenePatch::default(),
            shared_from: None,
            same_training_as: None,
            kernels: None,
            cell,
        });
    }
    Ok(())
}

/// The levels of a cell, axis by axis (none for a listed variant).
pub(crate) fn levels_of<'a>(grid: &'a [Axis], cell: &'a [usize]) -> impl Iterator<Item = &'a Level> {
    cell.iter().zip(grid).map(|(&i, axis)| &axis.levels[i])
}

/// The cell at level `i` of `axis` and, on a grid of two, the other axis at its level (`other`).
fn cell_at(axes: usize, axis: usize, i: usize, other: Option<(usize, usize)>) -> Vec<usize> {
    let mut cell = vec![0; axes];
    cell[axis] = i;
    if let Some((o, level)) = other {
        cell[o] = level;
    }
    cell
}

/// The variant of a grid's cell (its level indices).
pub(crate) fn variant_at<'a>(spec: &'a ExperimentFile, cell: &[usize]) -> Option<&'a VariantFile> {
    spec.variants.iter().find(|v| !v.cell.is_empty() && v.cell == cell)
}

/// Every cell of the axes, the first axis slowest (its level indices); none without axes.
fn cells(axes: &[Axis]) -> Vec<Vec<usize>> {
    if axes.is_empty() {
        return Vec::new();
    }
    axes.iter().fold(vec![Vec::new()], |cells, axis| {
        cells
            .into_iter()
            .flat_map(|cell| {
                (0..axis.levels.len()).map(move |i| {
                    let mut cell = cell.clone();
                    cell.push(i);
                    cell
                })
            })
            .collect()
    })
}

/// What a grid claim reads: the index of the axis it runs along, the cells along it (in the axis's
/// order), and for a shift the other axis. Err names what is wrong.
pub(crate) struct Along<'a> {
    pub(crate) axis: usize,
    /// The variant of each level along the axis, for a trend or a boundary (the other axis held at `at`),
    /// or for a shift, one such row per level of the other axis.
    pub(crate) rows: Vec<Vec<&'a VariantFile>>,
}

/// Checks a grid claim against the file's grid and finds the cells it reads.
pub(crate) fn along<'a>(spec: &'a ExperimentFile, test: &GridTest) -> Result<Along<'a>, String> {
    let (name, at, shift) = match test {
        GridTest::Trend { axis, at } => (axis, at.as_deref(), false),
        GridTest::Boundary { axis, at, crosses, .. } => {
            finite(*crosses)?;
            (axis, at.as_deref(), false)
        }
        GridTest::BoundaryShift { axis, crosses, .. } => {
            finite(*crosses)?;
            (axis, None, true)
        }
    };
    let Some(axis) = spec.grid.iter().position(|a| &a.name == name) else {
        let known: Vec<&str> = spec.grid.iter().map(|a| a.name.as_str()).collect();
        return Err(format!("no grid axis named {name:?} (the file's: {known:?})"));
    };
    if spec.grid[axis].levels.len() < 2 {
        return Err(format!("axis {name:?} has one level: a trend or a boundary needs two or more"));
    }
    let other = (spec.grid.len() == 2).then_some(1 - axis);
    let row = |level: Option<usize>| -> Vec<&'a VariantFile> {
        (0..spec.grid[axis].levels.len())
            .map(|i| {
                variant_at(spec, &cell_at(spec.grid.len(), axis, i, other.zip(level)))
                    .expect("every cell of the grid is a variant")
            })
            .collect()
    };
    let rows = match (other, at, shift) {
        (None, None, false) => vec![row(None)],
        (None, _, true) => return Err("BoundaryShift needs a grid of two axes".into()),
        (None, Some(_), false) => return Err("at: names a level of the other axis, and this grid has one".into()),
        (Some(o), None, false) => {
            return Err(format!("at: must name the level of {:?} the claim holds fixed", spec.grid[o].name))
        }
        (Some(o), Some(label), false) => match spec.grid[o].levels.iter().position(|l| l.label == label) {
            Some(level) => vec![row(Some(level))],
            None => return Err(format!("at: {:?} is no level of {:?}", label, spec.grid[o].name)),
        },
        (Some(o), _, true) => (0..spec.grid[o].levels.len()).map(|l| row(Some(l))).collect(),
    };
    Ok(Along { axis, rows })
}

/// What a grid claim reads, as the reports' quantity column says it after the quantity ("… of" this).
pub(crate) fn describe(test: &GridTest) -> String {
    let at = |at: &Option<String>| at.as_ref().map_or(String::new(), |l| format!(", the other axis at `{l}`"));
    match test {
        GridTest::Trend { axis, at: level } => {
            format!("the runs along `{axis}`{}: least-squares slope per unit of the axis (HC3, n − 2 df)", at(level))
        }
        GridTest::Boundary { axis, crosses, at: level, direction } => format!(
            "the runs along `{axis}`{}: where the mean first {} {crosses}, on the axis (bootstrap)",
            at(level),
            passes(*direction)
        ),
        GridTest::BoundaryShift { axis, crosses, direction } => format!(
            "the runs along `{axis}` at every level of the other axis: slope of where the mean first {} {crosses} on the other axis (bootstrap)",
            passes(*direction)
        ),
    }
}

/// How a boundary's quantity passes its value, in words.
fn passes(direction: super::file::Crossing) -> &'static str {
    match direction {
        super::file::Crossing::Falls => "falls through",
        super::file::Crossing::Rises => "rises through",
        super::file::Crossing::Either => "crosses",
    }
}

/// A quantity's name short enough for a figure's title (the reports name it in full).
fn short_name(q: &super::file::Quantity) -> String {
    use super::file::Quantity as Q;
    match q {
        Q::EvalDoa(e) => format!("DoA, {e}"),
        Q::EvalDos(e) => format!("DoS, {e}"),
        Q::EvalOrder(e, o) => format!("{o}, {e}"),
        Q::InteractionDoa(e) => format!("DoA seeing minus {e}"),
        Q::Interaction(e, o) => format!("{o} seeing minus {e}"),
        Q::DoaLast => "DoA, training, last 100".into(),
        Q::DosLast => "DoS, training, last 100".into(),
        Q::CatchesLast => "catches per episode, last 100".into(),
        q => super::quantity::quantity_name(q),
    }
}

fn finite(x: f64) -> Result<(), String> {
    match x.is_finite() {
        true => Ok(()),
        false => Err(format!("crosses must be a finite number (got {x})")),
    }
}

/// Bootstrap resamples of a boundary or its shift: enough that the 0.5 % and 99.5 % percentiles (Holm's
/// smallest levels in a family of ten) rest on ten resamples each.
pub(crate) const RESAMPLES: usize = 2000;

/// What a grid claim's test came to, before its family's adjustment: the estimate (a slope, or a
/// boundary's position on the axis's values), the p-value of its test, and for a bootstrap test its
/// resamples (sorted; +∞ or −∞ for a boundary beyond the axis's high or low end, NaN where a shift has no
/// boundary at some level), from which its interval is read at the level Holm's procedure tests it at.
pub(crate) struct Tested {
    pub(crate) estimate: Option<super::stats::Estimate>,
    pub(crate) p: Option<f64>,
    pub(crate) resamples: Option<Vec<f64>>,
    /// What the test read, to the bit, as `aggregate::adjust` compares tests (two claims of one family
    /// that read the same runs the same way are one test): every value along its cells, and its test.
    pub(crate) reads: Option<super::results::SameTest>,
}

/// Tests a grid claim on the per-run values `values(variant)` (on the claim's scale).
pub(crate) fn test(
    spec: &ExperimentFile,
    claim: &super::file::Claim,
    test: &GridTest,
    values: &dyn Fn(&str) -> Vec<f64>,
) -> Tested {
    let none = Tested { estimate: None, p: None, resamples: None, reads: None };
    let Ok(along) = along(spec, test) else { return none };
    let x: Vec<f64> = spec.grid[along.axis].levels.iter().map(|l| l.value).collect();
    let samples: Vec<Vec<Vec<f64>>> =
        along.rows.iter().map(|row| row.iter().map(|v| values(&v.name)).collect()).collect();
    if samples.iter().flatten().any(Vec::is_empty) {
        return none;
    }
    let read = samples.iter().flatten().flatten().map(|x| x.to_bits()).collect();
    let what =
        u64::from_le_bytes(blake3::hash(format!("{test:?}").as_bytes()).as_bytes()[..8].try_into().unwrap_or_default());
    let tested = match test {
        GridTest::Trend { .. } => {
            let estimate = slope(&x, &samples[0]);
            let p = estimate.and_then(|e| e.test_p(claim.margin));
            Tested { estimate, p, resamples: None, reads: None }
        }
        GridTest::Boundary { crosses, direction, .. } => {
            let point = crossing(&x, &means(&samples[0]), *crosses, *direction);
            let mut rng = resampler(claim);
            let mut resamples: Vec<f64> = (0..RESAMPLES)
                .map(|_| crossing(&x, &resample_means(&samples[0], &mut rng), *crosses, *direction))
                .collect();
            resamples.sort_by(f64::total_cmp);
            // H0: the mean does not cross within the axis; a resample beyond either end is one against.
            let beyond = resamples.iter().filter(|r| !r.is_finite()).count();
            let p = (1 + beyond) as f64 / (RESAMPLES + 1) as f64;
            let estimate = bootstrap_estimate(point, &resamples, samples[0].iter().map(Vec::len).min().unwrap_or(0));
            Tested { estimate, p: Some(p), resamples: Some(resamples), reads: None }
        }
        GridTest::BoundaryShift { crosses, direction, .. } => {
            let other = 1 - along.axis;
            let y: Vec<f64> = spec.grid[other].levels.iter().map(|l| l.value).collect();
            let shift = |rows: &[Vec<f64>]| {
                let at: Vec<f64> = rows.iter().map(|m| crossing(&x, m, *crosses, *direction)).collect();
                match at.iter().all(|b| b.is_finite()) {
                    true => super::stats::least_squares(&y, &at),
                    false => f64::NAN,
                }
            };
            let point = shift(&samples.iter().map(|row| means(row)).collect::<Vec<_>>());
            let mut rng = resampler(claim);
            let mut resamples: Vec<f64> = (0..RESAMPLES)
                .map(|_| shift(&samples.iter().map(|row| resample_means(row, &mut rng)).collect::<Vec<_>>()))
                .collect();
            resamples.sort_by(f64::total_cmp);
            // Two-sided: a resample without a boundary at some level counts against both directions.
            let undefined = resamples.iter().filter(|r| r.is_nan()).count();
            let below = resamples.iter().filter(|r| **r <= 0.0).count() + undefined;
            let above = resamples.iter().filter(|r| **r >= 0.0).count() + undefined;
            let p = (2.0 * (1 + below.min(above)) as f64 / (RESAMPLES + 1) as f64).min(1.0);
            let seeds = samples.iter().flatten().map(Vec::len).min().unwrap_or(0);
            let estimate = bootstrap_estimate(point, &resamples, seeds);
            Tested { estimate, p: Some(p), resamples: Some(resamples), reads: None }
        }
    };
    let reads = tested.p.map(|_| (read, Some(vec![what]), claim.margin.map(f64::to_bits)));
    Tested { reads, ..tested }
}

/// The mean of each level's runs.
fn means(levels: &[Vec<f64>]) -> Vec<f64> {
    levels.iter().map(|s| super::stats::mean(s).unwrap_or(f64::NAN)).collect()
}

/// The means of one bootstrap resample: each level's runs drawn with replacement, as many as it has (seeds
/// are resampled within each cell, the design's strata).
fn resample_means(levels: &[Vec<f64>], rng: &mut rand_chacha::ChaCha8Rng) -> Vec<f64> {
    use rand::Rng;
    levels.iter().map(|s| (0..s.len()).map(|_| s[rng.gen_range(0..s.len())]).sum::<f64>() / s.len() as f64).collect()
}

/// The bootstrap's generator, seeded by the claim's text: a report is a function of its runs.
fn resampler(claim: &super::file::Claim) -> rand_chacha::ChaCha8Rng {
    use rand::SeedableRng;
    let hash = blake3::hash(claim.text.as_bytes());
    rand_chacha::ChaCha8Rng::from_seed(*hash.as_bytes())
}

/// Where the means `m` at positions `x` first pass `value` along the axis the way `direction` says: the
/// first two neighbouring levels with the first at or above the value and the next below it (a fall), or
/// the reverse (a rise), linear between them; +∞ when no two neighbouring levels do (a boundary, if any,
/// beyond the axis).
pub(crate) fn crossing(x: &[f64], m: &[f64], value: f64, direction: super::file::Crossing) -> f64 {
    use super::file::Crossing;
    if m.iter().any(|v| !v.is_finite()) {
        return f64::NAN;
    }
    for i in 1..m.len() {
        let (a, b) = (m[i - 1] - value, m[i] - value);
        let falls = a >= 0.0 && b < 0.0;
        let rises = a <= 0.0 && b > 0.0;
        let passes = match direction {
            Crossing::Falls => falls,
            Crossing::Rises => rises,
            Crossing::Either => falls || rises,
        };
        if passes {
            return x[i - 1] + (x[i] - x[i - 1]) * a / (a - b);
        }
    }
    f64::INFINITY
}

/// The trend along an axis: the least-squares slope of every run's value on its level's position, each run
/// one observation, with the HC3 standard error (MacKinnon & White 1985; recommended for small samples by
/// Long & Ervin 2000), which holds when the spread differs between levels, as catches' does, and n − 2
/// degrees of freedom. None with fewer than three runs or one position.
pub(crate) fn slope(x: &[f64], levels: &[Vec<f64>]) -> Option<super::stats::Estimate> {
    let points: Vec<(f64, f64)> = x.iter().zip(levels).flat_map(|(&x, ys)| ys.iter().map(move |&y| (x, y))).collect();
    let n = points.len();
    let mx = points.iter().map(|p| p.0).sum::<f64>() / n as f64;
    let my = points.iter().map(|p| p.1).sum::<f64>() / n as f64;
    let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
    if n < 3 || sxx <= 0.0 {
        return None;
    }
    let (xs, ys): (Vec<f64>, Vec<f64>) = points.iter().copied().unzip();
    let b = super::stats::least_squares(&xs, &ys);
    let a = my - b * mx;
    let meat: f64 = points
        .iter()
        .map(|&(x, y)| {
            let h = 1.0 / n as f64 + (x - mx).powi(2) / sxx;
            let e = y - a - b * x;
            (x - mx).powi(2) * e * e / (1.0 - h).powi(2)
        })
        .sum();
    let se = meat.sqrt() / sxx;
    let df = (n - 2) as f64;
    let seeds = levels.iter().map(Vec::len).min().unwrap_or(0);
    Some(super::stats::Estimate {
        mean: b,
        ci: Some(super::stats::t_quantile(0.975, df) * se),
        n: seeds,
        se: Some(se),
        df: Some(df),
        design: super::stats::Design::Slope { levels: levels.len() },
    })
}

/// A bootstrap test's estimate: the point estimate, the standard deviation of its finite resamples as
/// its standard error (for the seeds that would decide it), no t interval (its interval is the resamples'
/// percentiles, [`super::stats::percentile_interval`]); None when the means do not cross within the axis (at every level).
fn bootstrap_estimate(point: f64, resamples: &[f64], seeds: usize) -> Option<super::stats::Estimate> {
    // No boundary (or none at some level): nothing to estimate, never ±∞ or NaN written as a result.
    if !point.is_finite() {
        return None;
    }
    let finite: Vec<f64> = resamples.iter().copied().filter(|r| r.is_finite()).collect();
    let se = (finite.len() >= 2).then(|| {
        let m = finite.iter().sum::<f64>() / finite.len() as f64;
        (finite.iter().map(|r| (r - m).powi(2)).sum::<f64>() / (finite.len() - 1) as f64).sqrt()
    });
    Some(super::stats::Estimate {
        mean: point,
        ci: None,
        n: seeds,
        se,
        df: None,
        design: super::stats::Design::Bootstrap,
    })
}

/// The verdict on a boundary or its shift, at the level Holm's procedure tested it at (`level`,
/// `p_holm`): located (or a shift detected) when its adjusted percentile interval holds neither an end
/// of the axis (nor zero).
pub(crate) fn bootstrap_verdict(
    claim: &super::file::Claim,
    estimate: Option<super::stats::Estimate>,
    resamples: &[f64],
    p_holm: Option<f64>,
    level: Option<f64>,
) -> super::verdict::Verdict {
    use super::verdict::{alpha_shown, p_shown, Outcome, Verdict};
    let Some(p_holm) = p_holm else {
        return Verdict::new(Outcome::NotRunYet, "not run yet");
    };
    let level = level.unwrap_or(super::verdict::ALPHA);
    let (lo, hi) = super::stats::percentile_interval(resamples, level);
    let shown = |x: f64| match x {
        x if x == f64::INFINITY => "beyond the axis's high end".to_string(),
        x if x == f64::NEG_INFINITY => "beyond the axis's low end".to_string(),
        x => format!("{x:.3}"),
    };
    let range = format!("[{}, {}] (bootstrap over seeds, α = {})", shown(lo), shown(hi), alpha_shown(level));
    let detected = p_holm < super::verdict::ALPHA;
    match claim.grid {
        Some(GridTest::Boundary { crosses, .. }) => {
            let share = resamples.iter().filter(|r| r.is_finite()).count() as f64 / resamples.len() as f64;
            match (detected, estimate) {
                (true, Some(e)) => Verdict::new(
                    Outcome::EffectDetected,
                    format!("located at {:.3}, adjusted interval {range} (Holm p = {})", e.mean, p_shown(p_holm)),
                ),
                (_, e) => Verdict::new(
                    Outcome::NoEffectDetected,
                    match e {
                        Some(e) => format!(
                            "not located (inconclusive): the mean over seeds crosses {crosses} at {:.3}, but only {:.0} % of resamples cross it within the axis; adjusted interval {range}",
                            e.mean,
                            100.0 * share
                        ),
                        None => format!(
                            "not located (inconclusive): the mean over seeds does not cross {crosses} within the axis, and {:.0} % of resamples do; adjusted interval {range}",
                            100.0 * share
                        ),
                    },
                ),
            }
        }
        _ => {
            let Some(e) = estimate else {
                return Verdict::new(
                    Outcome::NoEffectDetected,
                    format!("no effect detected (inconclusive): the mean does not cross within the axis at every level of the other axis, so the boundary has no slope; adjusted interval {range}"),
                );
            };
            let ours = claim.ours.then_some(claim.paper).flatten();
            match (detected, ours) {
                (true, Some(sign)) if sign.signum() == e.mean.signum() => Verdict::new(
                    Outcome::DetectedAsHypothesised,
                    format!(
                        "detected as hypothesised: {:+.3}, adjusted interval {range} (Holm p = {})",
                        e.mean,
                        p_shown(p_holm)
                    ),
                ),
                (true, Some(_)) => Verdict::new(
                    Outcome::DetectedOpposite,
                    format!(
                        "detected opposite to the hypothesis: {:+.3}, adjusted interval {range} (Holm p = {})",
                        e.mean,
                        p_shown(p_holm)
                    ),
                ),
                (true, None) => Verdict::new(
                    Outcome::EffectDetected,
                    format!(
                        "effect detected: {:+.3}, adjusted interval {range} (Holm p = {})",
                        e.mean,
                        p_shown(p_holm)
                    ),
                ),
                (false, _) => Verdict::new(
                    Outcome::NoEffectDetected,
                    format!("no effect detected (inconclusive): {:+.3}, adjusted interval {range}", e.mean),
                ),
            }
        }
    }
}

/// The figures of a grid on one preset (`figures/PRESET-grid-map` and `PRESET-grid-curves`): per quantity
/// a grid's claims read, a heat map of its mean over seeds per cell, each value written in its cell and
/// cells whose 95 % interval holds the reference value crossed out (a boundary's `crosses`, else 0 for an
/// effect; none for a level); and per quantity and axis, its mean against the axis's positions with 95 %
/// bands, one curve per level of the other axis, a boundary's value as a dashed line.
pub(crate) fn figures(
    exp: &super::file::Experiment,
    preset: &str,
    table: &super::summary::Summary,
    saved: &mut usize,
) -> crate::error::Result<()> {
    use super::plot::{Curve, Heatmap, Panel};
    let spec = &exp.spec;
    if spec.grid.is_empty() {
        return Ok(());
    }
    let mut quantities: Vec<&super::file::Quantity> = Vec::new();
    for c in spec.claims.iter().filter(|c| c.grid.is_some()) {
        if !quantities.contains(&&c.quantity) {
            quantities.push(&c.quantity);
        }
    }
    let cell = |row: usize, column: usize| match spec.grid.len() {
        1 => variant_at(spec, &[column]),
        _ => variant_at(spec, &[row, column]),
    };
    let (first, second) = (&spec.grid[0], spec.grid.get(1));
    let (rows, columns) = match second {
        Some(s) => (first.levels.len(), s.levels.len()),
        None => (1, first.levels.len()),
    };
    let estimate =
        |v: &VariantFile, q: &super::file::Quantity| super::stats::estimate(&table.values(exp, preset, &v.name, q));
    let reference = |q: &super::file::Quantity| {
        let boundary = spec.claims.iter().find_map(|c| match &c.grid {
            Some(GridTest::Boundary { crosses, .. } | GridTest::BoundaryShift { crosses, .. }) if &c.quantity == q => {
                Some(*crosses)
            }
            _ => None,
        });
        boundary.or_else(|| super::verdict::is_effect(&super::file::Claim::of("", "", q.clone())).then_some(0.0))
    };
    let mut maps = Vec::new();
    for q in &quantities {
        let r = reference(q);
        let mut values = vec![vec![f64::NAN; columns]; rows];
        let mut marked = vec![vec![false; columns]; rows];
        for (i, (row, marks)) in values.iter_mut().zip(&mut marked).enumerate() {
            for (j, (value, mark)) in row.iter_mut().zip(marks).enumerate() {
                let Some(e) = cell(i, j).and_then(|v| estimate(v, q)) else { continue };
                *value = e.mean;
                *mark = r.is_some_and(|r| e.ci.is_none_or(|ci| (e.mean - r).abs() <= ci));
            }
        }
        let crossed = match r {
            Some(r) => format!(" (× : 95 % CI holds {r})"),
            None => String::new(),
        };
        maps.push(Heatmap {
            title: format!("{}{crossed}", short_name(q)),
            x_label: second.map_or(first.name.clone(), |s| s.name.clone()),
            y_label: second.map_or(String::new(), |_| first.name.clone()),
            x_ticks: second.unwrap_or(first).levels.iter().map(|l| l.label.clone()).collect(),
            y_ticks: match second {
                Some(_) => first.levels.iter().map(|l| l.label.clone()).collect(),
                None => vec![String::new()],
            },
            values,
            log: false,
            diverging: r == Some(0.0),
            marked,
            annotate: true,
        });
    }
    let dir = exp.figures_dir();
    if !maps.is_empty() {
        super::plot::save_heatmaps_in(&dir.join(format!("{preset}-grid-map")), &maps, 3)?;
        *saved += 1;
    }
    let mut panels = Vec::new();
    for q in &quantities {
        for (a, axis) in spec.grid.iter().enumerate() {
            let other = (spec.grid.len() == 2).then_some(1 - a);
            let lines: Vec<Option<usize>> = match other {
                Some(o) => (0..spec.grid[o].levels.len()).map(Some).collect(),
                None => vec![None],
            };
            let mut curves = Vec::new();
            for line in lines {
                let at = |k: usize| variant_at(spec, &cell_at(spec.grid.len(), a, k, other.zip(line)));
                let e: Vec<Option<super::stats::Estimate>> =
                    (0..axis.levels.len()).map(|k| at(k).and_then(|v| estimate(v, q))).collect();
                let label = match (other, line) {
                    (Some(o), Some(l)) => format!("{} {}", spec.grid[o].name, spec.grid[o].levels[l].label),
                    _ => exp.name.clone(),
                };
                curves.push(Curve::of_estimates(label, axis.levels.iter().map(|l| l.value).collect(), &e));
            }
            let levels = reference(q)
                .filter(|_| spec.claims.iter().any(|c| &c.quantity == *q && matches!(&c.grid, Some(GridTest::Boundary { axis: n, .. } | GridTest::BoundaryShift { axis: n, .. }) if n == &axis.name)))
                .map(|y| super::plot::Level { label: format!("boundary value {y}"), y, x: None, chance: true, colour: 0 })
                .into_iter()
                .collect();
            let positions: Vec<String> = axis.levels.iter().map(|l| format!("{} at {:.2}", l.label, l.value)).collect();
            panels.push(Panel {
                title: short_name(q),
                x_label: format!("{} ({})", axis.name, positions.join(", ")),
                y_label: "mean over seeds, 95 % CI".into(),
                curves,
                levels,
            });
        }
    }
    if !panels.is_empty() {
        // One row per quantity: its curves along each axis side by side.
        super::plot::save_in(&dir.join(format!("{preset}-grid-curves")), &panels, spec.grid.len())?;
        *saved += 1;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn a_path_sets_one_scene_number_and_a_path_to_no_field_is_refused() {
        let patch = patch_at("species.prey.max_speed", 0.3).unwrap();
        assert_eq!(patch.species.unwrap()[0].max_speed, Some(0.3));
        assert_eq!(patch_at("episode_steps", 40.0).unwrap().episode_steps, Some(40));
        for bad in ["world.no_such_field", "species.prey.wings", "species", "", "species..x", "world.dt)"] {
            assert!(patch_at(bad, 1.0).is_err(), "{bad:?} was accepted");
        }
    }

    #[test]
    fn a_grid_has_one_cell_per_combination_of_levels_and_no_axes_no_cells() {
        let axis = |n: usize| Axis {
            name: format!("{n}"),
            path: None,
            values: vec![],
            levels: (0..n)
                .map(|i| Level { label: i.to_string(), value: i as f64, patch: ScenePatch::default() })
                .collect(),
        };
        assert!(cells(&[]).is_empty());
        assert_eq!(cells(&[axis(3)]), vec![vec![0], vec![1], vec![2]]);
        assert_eq!(cells(&[axis(2), axis(2)]), vec![vec![0, 0], vec![0, 1], vec![1, 0], vec![1, 1]]);
    }

    #[test]
    fn a_crossing_is_found_between_the_levels_that_bracket_it() {
        let x = [0.0, 1.0, 2.0, 3.0];
        use crate::claims::file::Crossing::{Either, Falls, Rises};
        assert_eq!(crossing(&x, &[0.4, 0.3, 0.1, 0.0], 0.2, Falls), 1.5);
        assert_eq!(crossing(&x, &[0.4, 0.2, 0.1, 0.0], 0.2, Falls), 1.0, "a level exactly at the value");
        assert_eq!(crossing(&x, &[0.0, 0.1, 0.3, 0.4], 0.2, Rises), 1.5, "rising through it");
        assert_eq!(crossing(&x, &[0.0, 0.1, 0.3, 0.4], 0.2, Falls), f64::INFINITY, "a rise is no fall");
        assert_eq!(crossing(&x, &[0.4, 0.3, 0.3, 0.3], 0.2, Either), f64::INFINITY, "no crossing within the axis");
        // Up and then down: a fall is the second crossing, either way the first.
        let (up_down, five) = ([0.0, 0.3, 0.3, 0.3, 0.0], [0.0, 1.0, 2.0, 3.0, 4.0]);
        assert!((crossing(&five, &up_down, 0.2, Falls) - 10.0 / 3.0).abs() < 1e-12);
        assert!((crossing(&five, &up_down, 0.2, Either) - 2.0 / 3.0).abs() < 1e-12);
    }

    /// Runs at `x` with means `mean(x)` and normal noise of SD `sd`, `seeds` per level.
    fn runs(x: &[f64], mean: impl Fn(f64) -> f64, sd: f64, seeds: usize, seed: u64) -> Vec<Vec<f64>> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let normal = rand_distr::Normal::new(0.0, sd).unwrap();
        x.iter().map(|&x| (0..seeds).map(|_| mean(x) + rng.sample(normal)).collect()).collect()
    }

    #[test]
    fn the_trend_recovers_a_known_slope_and_its_interval_covers_it_at_its_rate() {
        // A known answer: y = 0.3 − 0.08 x, noise SD 0.11 (the flocking share's), 5 seeds at 5 levels.
        let x = [-3.58, -2.58, -1.58, -1.0, 0.0];
        let mut covered = 0;
        for seed in 0..400 {
            let e = slope(&x, &runs(&x, |x| 0.3 - 0.08 * x, 0.11, 5, seed)).unwrap();
            covered += usize::from((e.mean + 0.08).abs() <= e.ci.unwrap());
            assert_eq!(e.df, Some(23.0));
        }
        // HC3 errs on the wide side: 95 % intervals cover at least ~93 % of 400 (binomial spread ±2 %).
        assert!(covered >= 372, "{covered} of 400 intervals cover the true slope");
        // Heteroscedastic noise (catches'): the coverage holds.
        let mut covered = 0;
        for seed in 0..400 {
            let sd = |x: f64| 0.05 + 0.2 * (x + 3.58);
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1000 + seed);
            let levels: Vec<Vec<f64>> = x
                .iter()
                .map(|&x| {
                    (0..5).map(|_| 1.0 + 0.5 * x + sd(x) * rng.sample::<f64, _>(rand_distr::StandardNormal)).collect()
                })
                .collect();
            let e = slope(&x, &levels).unwrap();
            covered += usize::from((e.mean - 0.5).abs() <= e.ci.unwrap());
        }
        assert!(covered >= 364, "{covered} of 400 intervals cover the true slope with unequal spreads");
    }

    #[test]
    fn a_boundary_is_located_where_the_means_cross_and_not_where_they_do_not() {
        use crate::claims::file::{Claim, Crossing::Falls};
        let x = [-3.58, -2.58, -1.58, -1.0, 0.0];
        let claim = Claim::of("known boundary", "", crate::claims::file::Quantity::DoaLast);
        let crossing_at = |levels: &[Vec<f64>]| {
            let mut rng = resampler(&claim);
            let mut r: Vec<f64> =
                (0..RESAMPLES).map(|_| crossing(&x, &resample_means(levels, &mut rng), 0.1, Falls)).collect();
            r.sort_by(f64::total_cmp);
            let beyond = r.iter().filter(|v| !v.is_finite()).count();
            (crossing(&x, &means(levels), 0.1, Falls), crate::analysis::stats::percentile_interval(&r, 0.05), beyond)
        };
        // The flocking share falling linearly from 0.3 to −0.03: it crosses 0.1 at x ≈ −1.41.
        let truth = -3.58 + (0.3 - 0.1) / (0.33 / 3.58);
        let (point, (lo, hi), beyond) = crossing_at(&runs(&x, |x| 0.3 - 0.33 * (x + 3.58) / 3.58, 0.11, 5, 7));
        assert!((point - truth).abs() < 0.7 && lo <= point && point <= hi, "{point} in [{lo}, {hi}], truth {truth}");
        assert!(lo.is_finite() && hi.is_finite() && beyond < RESAMPLES / 40, "located: {beyond} resamples beyond");
        // Flat at 0.2: no crossing; the resamples say so.
        let (point, (lo, hi), beyond) = crossing_at(&runs(&x, |_| 0.2, 0.02, 5, 8));
        assert!(point.is_infinite() && hi.is_infinite() && beyond > RESAMPLES / 2, "{point} [{lo}, {hi}]");
    }

    #[test]
    fn a_nan_resample_widens_both_ends_of_the_interval() {
        let mut r: Vec<f64> = (0..100).map(f64::from).collect();
        assert_eq!(crate::analysis::stats::percentile_interval(&r, 0.1), (5.0, 94.0));
        r[..10].fill(f64::NAN);
        let (lo, hi) = crate::analysis::stats::percentile_interval(&r, 0.1);
        assert!(lo == f64::NEG_INFINITY && hi == f64::INFINITY, "{lo} {hi}");
    }
}
