//! `summary.csv` and `summary-mean.csv`: an experiment's per-run values and their means over seeds,
//! written and read by one definition of their columns ([`columns`]). The claims are computed from
//! `summary.csv` alone, so a clone without run folders recomputes them exactly.

use super::curves::{curve_shape, Shape};
use super::file::{slug, Curve, Experiment, Order, Quantity};
use super::quantity::{column, derive, quantity};
use super::results::{window_mean, RunData};
use super::stats::estimate;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// The columns of `summary.csv` after preset, variant, seed and episodes: one per primitive quantity
/// (named by [`column`]), beside every control how much of the seeing actors' alignment it removes
/// (derived, for reading), then the catches; the one definition the summary is written by ([`text`]) and
/// read back by ([`Summary`]).
pub fn columns(exp: &Experiment) -> Vec<(String, Quantity)> {
    let evals: Vec<String> = exp.spec.evaluations.iter().map(|e| e.name.clone()).collect();
    let mut primitives = vec![Quantity::DosFirst, Quantity::DosLast, Quantity::DoaFirst, Quantity::DoaLast];
    for order in super::file::EVAL_ORDER {
        primitives.push(Quantity::TrainingFirst(order));
        primitives.push(Quantity::TrainingLast(order));
    }
    primitives.push(Quantity::Reach90(Curve::Dos));
    primitives.push(Quantity::Reach90(Curve::Doa));
    // The authors' DoS and DoA, in experiments whose runs measure them (`authors_metrics`): their first
    // and last 100 episodes and their untrained start. Other experiments' columns are unchanged.
    if exp.runs.iter().any(|r| r.scene.authors_metrics) {
        for (order, curve) in [(Order::AuthorsDos, Curve::AuthorsDos), (Order::AuthorsDoa, Curve::AuthorsDoa)] {
            primitives.push(Quantity::TrainingFirst(order));
            primitives.push(Quantity::TrainingLast(order));
            primitives.push(Quantity::Start(curve));
        }
    }
    let named = |q: Quantity| (column(&q).expect("a primitive quantity has a column"), q);
    let mut quantities: Vec<(String, Quantity)> = primitives.into_iter().map(named).collect();
    for e in &evals {
        quantities.push(named(Quantity::EvalDos(e.clone())));
        quantities.push(named(Quantity::EvalDoa(e.clone())));
        quantities.extend(super::file::EVAL_ORDER.iter().map(|o| named(Quantity::EvalOrder(e.clone(), *o))));
        if super::file::seeing_partner(&exp.spec.evaluations, e).is_some() {
            quantities.push((format!("eval_{}_doa_interaction", slug(e)), Quantity::InteractionDoa(e.clone())));
        }
    }
    for e in exp.spec.evaluations.iter().filter(|e| e.perturb.is_some()) {
        for which in ["near", "far"] {
            quantities.push(named(Quantity::Response(e.name.clone(), which.into())));
        }
    }
    if exp.spec.crossplay.is_some() {
        quantities
            .extend(super::crossplay_readouts::READOUTS.iter().map(|r| named(Quantity::Crossplay(r.to_string()))));
    }
    if let (Some(d), Some(run)) = (&exp.spec.distill, exp.runs.first()) {
        let columns = super::distill::columns(&run.scene, &d.forms);
        quantities.extend(columns.into_iter().map(|(s, f, n)| named(Quantity::Distilled(s, f, n))));
    }
    quantities.extend([named(Quantity::CatchesFirst), named(Quantity::CatchesLast)]);
    // A level some claim times a curve against (`Reaches`), a fitted approach (`Fitted`) or a predators'
    // tactic (`Tactic`): a column only in the experiments that ask for one, so every other summary keeps
    // its columns.
    for claim in &exp.spec.claims {
        let read = claim.quantity.asked_columns(&exp.spec.evaluations);
        for q in read {
            if !quantities.iter().any(|(_, known)| *known == q) {
                quantities.push(named(q));
            }
        }
    }
    // Likewise an evaluation's catches per prey: in the experiments whose claims read them (directly or
    // as a difference of two evaluations), and for every evaluation of a group-size series (evaluations
    // that set `arena_edge`), whose figure draws them.
    let series = exp.spec.evaluations.iter().any(|e| e.arena_edge.is_some());
    let mut caught: Vec<String> = if series { evals.clone() } else { Vec::new() };
    for claim in &exp.spec.claims {
        caught.extend(claim.quantity.catches_of(&exp.spec.evaluations));
    }
    for e in caught {
        let q = Quantity::EvalCatches(e);
        if !quantities.iter().any(|(_, have)| *have == q) {
            quantities.push(named(q));
        }
    }
    quantities
}

/// The columns of `summary.csv` after `shared_from`: the shape of each training curve (its start, and
/// DoS's trough and DoA's peak with where they were and how far the curve moved back after them). Kept
/// last because they came last (df7bc45): a summary written before them is extended ([`extend`]) from
/// the committed figure data, which holds the curves, without rewriting a byte of what it held.
pub fn curve_columns() -> Vec<(String, Quantity)> {
    let mut quantities = Vec::new();
    for curve in super::results::CURVES {
        quantities.push(Quantity::Start(curve));
    }
    for curve in [Curve::Dos, Curve::Doa] {
        quantities.push(Quantity::Extreme(curve));
        quantities.push(Quantity::ExtremeEpisode(curve));
        quantities.push(Quantity::AfterExtreme(curve));
    }
    for curve in [Curve::Dos, Curve::Doa] {
        quantities.push(Quantity::Halfway(curve));
    }
    quantities.into_iter().map(|q| (column(&q).expect("a curve quantity has a column"), q)).collect()
}

/// The header of `summary.csv` for `quantities` ([`columns`]): preset, variant, seed, episodes, the
/// quantities, returns, wall time, binaries, the experiment a run is shared from, then the
/// [`curve_columns`].
pub(crate) fn header(quantities: &[(String, Quantity)]) -> Vec<String> {
    let mut header: Vec<String> = ["preset", "variant", "seed", "episodes"].map(String::from).into();
    header.extend(quantities.iter().map(|(name, _)| name.clone()));
    header.extend(["return_first100", "return_last100", "wall_seconds", "binary", "shared_from"].map(String::from));
    header.extend(curve_columns().into_iter().map(|(name, _)| name));
    header
}

/// `summary.csv`: one row per finished run, in the order of the experiment's runs: each run of `data`
/// (its folder here) with its values of `quantities` ([`columns`]), blank where a run has none, then its
/// returns, wall time, binaries and the experiment it is shared from, then its [`curve_columns`]; and
/// the `carried` lines of runs finished elsewhere ([`super::carry`]), as committed.
pub(crate) fn text(
    exp: &Experiment,
    data: &BTreeMap<usize, RunData>,
    quantities: &[(String, Quantity)],
    carried: &BTreeMap<usize, String>,
) -> String {
    let mut lines: BTreeMap<usize, String> = carried.clone();
    let curves = curve_columns();
    for (i, d) in data {
        let r = &exp.runs[*i];
        let mut line = format!("{},{},{},{}", csv_text(&r.preset), csv_text(&r.variant), r.seed, d.dos.len());
        for (_, q) in quantities {
            line.push_str(&field(quantity(exp, d, q)));
        }
        let (r0, r1) = (window_mean(&d.returns, true), window_mean(&d.returns, false));
        let shared = csv_text(r.shared_from.as_deref().unwrap_or(""));
        for v in [r0, r1, d.wall_seconds] {
            line.push_str(&field(v));
        }
        write!(line, ",{},{shared}", csv_text(&d.binaries.join(" "))).unwrap();
        for (_, q) in &curves {
            line.push_str(&field(quantity(exp, d, q)));
        }
        lines.insert(*i, line);
    }
    let mut summary = header(quantities).join(",");
    summary.push('\n');
    for line in lines.into_values() {
        summary.push_str(&line);
        summary.push('\n');
    }
    summary
}

/// One value as a field of summary.csv, with its comma: blank, never NaN, where a run has no value (an
/// evaluation without a catch has no edge rank).
fn field(v: f64) -> String {
    if v.is_finite() {
        format!(",{v}")
    } else {
        ",".into()
    }
}

/// A summary.csv `text` written before its [`curve_columns`] existed, extended with them from the
/// committed figure data's training curves (`curves`, by run index): every byte it held is kept, and each
/// row gains the values a summary written from the run folders has. None when it has them already.
pub(crate) fn extend(
    exp: &Experiment,
    text: &str,
    table: &Summary,
    curves: &BTreeMap<usize, super::figure_data::FigureData>,
) -> Option<String> {
    // The curve columns it lacks: all of them, or those added after it was written (they come last).
    let added: Vec<(String, Quantity)> =
        curve_columns().into_iter().filter(|(name, _)| !table.columns.contains(name)).collect();
    if added.is_empty() || !text.ends_with('\n') {
        return None;
    }
    let of_run: BTreeMap<(&str, &str, u64), usize> =
        table.runs(exp).into_iter().map(|(i, r)| ((r.preset.as_str(), r.variant.as_str(), r.seed), i)).collect();
    let mut lines = text.lines();
    let mut out = lines.next().unwrap_or_default().to_string();
    for (name, _) in &added {
        write!(out, ",{name}").unwrap();
    }
    out.push('\n');
    for (line, row) in lines.zip(&table.rows) {
        out.push_str(line);
        let run = of_run.get(&(row.preset.as_str(), row.variant.as_str(), row.seed)).and_then(|i| curves.get(i));
        for (_, q) in &added {
            // The shapes the figure data gives to the same bits (a fitted approach or a common level was
            // never extended this way: those summaries had their columns from the start).
            let v = run.map_or(f64::NAN, |d| match q.shape() {
                Some((
                    curve,
                    shape @ (Shape::Start
                    | Shape::Extreme
                    | Shape::ExtremeEpisode
                    | Shape::AfterExtreme
                    | Shape::Halfway),
                )) => curve_shape(shape, curve, d.curve(curve)),
                Some((_, Shape::Reaches(_) | Shape::Fitted(_))) | None => f64::NAN,
            });
            out.push_str(&field(v));
        }
        out.push('\n');
    }
    Some(out)
}

/// `summary-mean.csv`: per preset, variant and quantity, the mean over seeds and its 95 % interval.
/// From the summary's rows (`table`), so runs carried from elsewhere count as the run folders here do.
pub fn means_text(exp: &Experiment, table: &Summary, quantities: &[(String, Quantity)]) -> String {
    let mut means = String::from("preset,variant,quantity,seeds,mean,ci95\n");
    for preset in &exp.spec.presets {
        for v in &exp.spec.variants {
            for (name, q) in quantities.iter().chain(&curve_columns()) {
                if let Some(e) = estimate(&table.values(exp, preset, &v.name, q)) {
                    let ci = e.ci.map_or(String::new(), |c| c.to_string());
                    writeln!(means, "{},{},{name},{},{},{ci}", csv_text(preset), csv_text(&v.name), e.n, e.mean)
                        .unwrap();
                }
            }
        }
    }
    means
}

/// An experiment's per-run values as `summary.csv` holds them: one row per run (preset, variant, seed,
/// then one column per quantity), read with the `csv` crate (variant names may hold commas). The claims
/// are computed from it alone.
#[derive(Clone, Debug, Default)]
pub struct Summary {
    pub(crate) columns: Vec<String>,
    pub(crate) rows: Vec<SummaryRow>,
}

#[derive(Clone, Debug)]
pub(crate) struct SummaryRow {
    pub(crate) preset: String,
    pub(crate) variant: String,
    pub(crate) seed: u64,
    /// Every column's value (NaN where blank or not a number), in `columns` order.
    pub(crate) values: Vec<f64>,
    /// The executables that made the run (`binary` column; "unknown" for runs before provenance files).
    pub(crate) binary: String,
    /// The experiment that trained the run, when this experiment shares it (`shared_from`); empty else.
    pub(crate) shared_from: String,
}

impl Summary {
    /// The committed summary of an experiment, None when it has none.
    pub fn read(path: &Path) -> crate::error::Result<Option<Summary>> {
        match crate::io::read_text(path, crate::io::MAX_TEXT_BYTES) {
            Ok(text) => Ok(Some(Summary::parse(&text, path)?)),
            Err(_) if !path.exists() => Ok(None),
            Err(e) => Err(e),
        }
    }

    pub(crate) fn parse(text: &str, path: &Path) -> crate::error::Result<Summary> {
        let bad = |e: csv::Error| format!("{}: {e}", path.display());
        let mut reader = csv::Reader::from_reader(text.as_bytes());
        let columns: Vec<String> = reader.headers().map_err(bad)?.iter().map(str::to_string).collect();
        let at = |name: &str| columns.iter().position(|c| c == name);
        let (Some(preset), Some(variant), Some(seed)) = (at("preset"), at("variant"), at("seed")) else {
            return Err(format!("{}: no preset, variant and seed columns", path.display()).into());
        };
        let (binary, shared) = (at("binary"), at("shared_from"));
        let words = [Some(preset), Some(variant), binary, shared];
        let mut rows = vec![];
        for (k, record) in reader.records().enumerate() {
            let record = record.map_err(bad)?;
            // A value is a finite number or blank (a run without it): a NaN or an infinity written into a
            // summary would leave its run out of every estimate without a word.
            let mut values = Vec::with_capacity(record.len());
            for (i, cell) in record.iter().enumerate() {
                values.push(match cell.parse::<f64>() {
                    Ok(v) if !v.is_finite() && !words.contains(&Some(i)) => {
                        return Err(format!(
                            "{}: line {}, column {}: {cell:?} is not a finite number (a summary holds finite values, or a blank where a run has none)",
                            path.display(),
                            k + 2,
                            columns.get(i).map_or("?", String::as_str)
                        )
                        .into())
                    }
                    Ok(v) => v,
                    Err(_) => f64::NAN,
                });
            }
            rows.push(SummaryRow {
                preset: record[preset].to_string(),
                variant: record[variant].to_string(),
                seed: record[seed].parse().map_err(|_| format!("{}: seed {:?}", path.display(), &record[seed]))?,
                values,
                binary: binary.map_or("unknown", |b| &record[b]).to_string(),
                shared_from: shared.map_or("", |c| &record[c]).to_string(),
            });
        }
        Ok(Summary { columns, rows })
    }

    /// The rows of runs the experiment file still has, each with its index into the experiment's runs.
    pub(crate) fn runs<'a>(&'a self, exp: &Experiment) -> Vec<(usize, &'a SummaryRow)> {
        self.rows
            .iter()
            .filter_map(|row| {
                let i = exp
                    .runs
                    .iter()
                    .position(|r| r.preset == row.preset && r.variant == row.variant && r.seed == row.seed)?;
                Some((i, row))
            })
            .collect()
    }

    pub(crate) fn value(&self, row: &SummaryRow, column: &str) -> f64 {
        self.columns.iter().position(|c| c == column).map_or(f64::NAN, |i| row.values[i])
    }

    /// A run's value of a quantity, from its row ([`super::quantity::quantity`] computes the same from the
    /// run's own files; both through [`derive`]).
    pub(crate) fn quantity(&self, exp: &Experiment, row: &SummaryRow, q: &Quantity) -> f64 {
        derive(&exp.spec.evaluations, q, &|p| column(p).map_or(f64::NAN, |c| self.value(row, &c)))
    }

    /// The fewest episodes any run of one preset and variant trained, None without a run.
    pub(crate) fn episodes(&self, preset: &str, variant: &str) -> Option<usize> {
        self.rows
            .iter()
            .filter(|r| r.preset == preset && r.variant == variant)
            .map(|r| self.value(r, "episodes"))
            .filter(|x| x.is_finite())
            .map(|x| x as usize)
            .min()
    }

    /// The finite values of a quantity over the runs of one preset and variant (one per seed).
    pub(crate) fn values(&self, exp: &Experiment, preset: &str, variant: &str, q: &Quantity) -> Vec<f64> {
        self.rows
            .iter()
            .filter(|r| r.preset == preset && r.variant == variant)
            .map(|r| self.quantity(exp, r, q))
            .filter(|x| x.is_finite())
            .collect()
    }
}

/// A name as one CSV field: quoted (RFC 4180) when it holds a comma or a quote, as variant names may
/// ("body frame, no predators").
pub(crate) fn csv_text(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::super::figure_data::FigureData;
    use super::super::file::Experiment;
    use super::super::results::RunData;
    use std::collections::BTreeMap;

    #[test]
    fn every_claim_of_every_experiment_file_reads_columns_its_summary_has() {
        // A claim whose quantity needs a column the summary does not write would read as "not run yet"
        // for ever: every primitive its value is derived from must be a column.
        let mut files: Vec<_> = std::fs::read_dir("experiments").unwrap().flatten().map(|e| e.path()).collect();
        files.retain(|p| p.extension().is_some_and(|x| x == "ron"));
        files.sort();
        assert!(files.len() > 20);
        for file in files {
            let exp = Experiment::load(&file, std::path::Path::new("results")).unwrap();
            let mut have: Vec<_> = super::columns(&exp).into_iter().map(|(_, q)| q).collect();
            have.extend(super::curve_columns().into_iter().map(|(_, q)| q));
            for claim in &exp.spec.claims {
                let asked = std::cell::RefCell::new(vec![]);
                super::super::quantity::derive(&exp.spec.evaluations, &claim.quantity, &|p| {
                    asked.borrow_mut().push(p.clone());
                    0.0
                });
                for p in asked.into_inner() {
                    assert!(
                        have.contains(&p),
                        "{}: {:?} reads {p:?}, which its summary has no column of",
                        file.display(),
                        claim.text
                    );
                }
            }
        }
    }

    #[test]
    fn a_non_finite_value_in_a_summary_is_an_error_naming_its_line_and_column() {
        let path = std::path::Path::new("results/x/summary.csv");
        let text = "preset,variant,seed,episodes,dos_last100,binary\npaper,a,1,2000,0.2,abc\npaper,a,2,2000,,abc\n";
        assert!(super::Summary::parse(text, path).unwrap().rows[1].values[4].is_nan(), "a blank is a run without it");
        for bad in ["NaN", "inf", "-inf"] {
            let e = super::Summary::parse(&text.replacen("0.2", bad, 1), path).unwrap_err().to_string();
            assert!(
                e.starts_with("results/x/summary.csv: line 2, column dos_last100: ") && e.contains("not a finite"),
                "{e}"
            );
        }
        // Words are not numbers: a binary called "inf" is a name.
        assert!(super::Summary::parse(&text.replace("abc", "inf"), path).is_ok());
    }

    #[test]
    fn an_old_summary_gains_the_curve_columns_a_new_one_is_written_with() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("old.ron");
        std::fs::write(
            &file,
            r#"(base: "scenes/paper.ron", seeds: [1, 2], variants: [(name: "a"), (name: "b, c")], claims: [])"#,
        )
        .unwrap();
        let exp = Experiment::load(&file, dir.path()).unwrap();
        // Four runs of 250 episodes, each curve its own wave, one run too short for an extreme.
        let data: BTreeMap<usize, RunData> = (0..exp.runs.len())
            .map(|i| {
                let episodes = if i == 3 { 150 } else { 250 };
                let curve = |phase: f64| {
                    (0..episodes).map(|e| 0.5 + 0.3 * (e as f64 / 40.0 + phase + i as f64).sin()).collect()
                };
                let d = RunData {
                    dos: curve(0.0),
                    doa: curve(1.0),
                    catches: curve(2.0),
                    binaries: vec!["x".into()],
                    ..Default::default()
                };
                (i, d)
            })
            .collect();
        let written = super::text(&exp, &data, &super::columns(&exp), &BTreeMap::new());
        // The same summary as a coevo before the curve columns wrote it.
        let added = super::curve_columns().len();
        let old: String = written
            .lines()
            .map(|l| {
                let keep = l.split(',').count() - added;
                format!("{}\n", l.split(',').take(keep).collect::<Vec<_>>().join(","))
            })
            .collect();
        assert!(written.starts_with(old.lines().next().unwrap()) && old.len() < written.len());
        let table = super::Summary::parse(&old, &file).unwrap();
        // The curves through the figure-data file itself (which keeps them at single precision), as a
        // clone reads them.
        let full: BTreeMap<usize, FigureData> = data
            .iter()
            .map(|(i, d)| {
                let f = FigureData {
                    dos: d.dos.clone(),
                    doa: d.doa.clone(),
                    catches: d.catches.clone(),
                    ..Default::default()
                };
                (*i, f)
            })
            .collect();
        std::fs::create_dir_all(&exp.root).unwrap();
        super::super::figure_data::write(&exp, &full).unwrap();
        let indices: Vec<usize> = full.keys().copied().collect();
        let curves = super::super::figure_data::read(&exp, &indices).unwrap().unwrap();
        assert_ne!(curves[&0].doa, full[&0].doa, "the file rounds");
        let extended = super::extend(&exp, &old, &table, &curves).expect("extended");
        assert_eq!(extended, written, "the same bytes as written from the run folders");
        let table = super::Summary::parse(&written, &file).unwrap();
        let value =
            |row: usize, name: &str| table.rows[row].values[table.columns.iter().position(|c| c == name).unwrap()];
        assert!(value(0, "doa_halfway").is_finite() && value(3, "doa_halfway").is_finite());
        assert!(value(3, "dos_trough").is_nan(), "too short for an extreme: blank");
        assert_eq!(super::extend(&exp, &written, &table, &curves), None, "extended once");
        // A summary written with the first curve columns but before the halfway episodes gains only those.
        let halfway = ["dos_halfway", "doa_halfway"];
        assert!(super::curve_columns().iter().rev().take(2).all(|(c, _)| halfway.contains(&c.as_str())));
        let older: String = written.lines().map(|l| format!("{}\n", l.rsplitn(3, ',').nth(2).unwrap())).collect();
        let table = super::Summary::parse(&older, &file).unwrap();
        assert!(
            !table.columns.iter().any(|c| halfway.contains(&c.as_str()))
                && table.columns.contains(&"dos_trough".into())
        );
        assert_eq!(super::extend(&exp, &older, &table, &curves).expect("extended"), written);
    }

    #[test]
    fn names_with_commas_stay_one_csv_field() {
        assert_eq!(super::csv_text("5:3"), "5:3");
        assert_eq!(super::csv_text("body frame, no predators"), "\"body frame, no predators\"");
        assert_eq!(super::csv_text("a \"b\", c"), "\"a \"\"b\"\", c\"");
    }
}
