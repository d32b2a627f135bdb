//! From the runs' CSV files alone (never retraining): per-run summaries, means with 95 % confidence
//! intervals over seeds, the figures, and the paper's claims checked against them.

use super::claims::{
    chance_level, column, derive, is_effect, quantity, values, verdict, window_mean, ClaimResult, EvalData, RunData,
    SETTLED_STEPS, WINDOW,
};
use super::figure_data::{self, FigureData};
use super::file::{slug, Experiment, Quantity};
use super::plot::{self, Curve, EstimatePanel, Panel, Row};
use super::runner::{eval_file, stage, Stage};
use super::stats::{difference, estimate, holm, mean, running_mean};
use crate::run::schema::{self, Table};
use crate::run::RunDir;
use crate::sim::metrics::Swarming;
use crate::sim::species::SpeciesRegistry;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// The first species' rows of a confusion curve file (`species,prey_in_view,samples,mean_abs_turn,
/// mean_speed_fraction,catches_per_step`); empty when there is no file.
fn read_confusion(path: &Path) -> crate::error::Result<Vec<[f64; 3]>> {
    if !path.exists() {
        return Ok(vec![]);
    }
    let text = crate::io::read_text(path, crate::io::MAX_TEXT_BYTES).map_err(|e| format!("{}: {e}", path.display()))?;
    let rows: Vec<Vec<&str>> =
        text.lines().skip(1).map(|l| l.split(',').collect()).filter(|r: &Vec<&str>| r.len() == 6).collect();
    let first = rows.first().map(|r| r[0]).unwrap_or_default();
    let cell = |c: &str| c.parse::<f64>().unwrap_or(f64::NAN);
    Ok(rows.iter().filter(|r| r[0] == first).map(|r| [cell(r[3]), cell(r[4]), cell(r[5])]).collect())
}

/// The near and far responses of a perturbation file (`run::perturb`): the sample-weighted mean
/// |Δheading| of ranks 1–6 over lags 1–10, and of ranks 25+ over the same lags; NaN without the file.
fn read_response(path: &Path) -> crate::error::Result<[f64; 2]> {
    use crate::run::perturb::{read_rows, weighted_mean};
    Ok(match read_rows(path)? {
        Some(rows) => {
            [weighted_mean(&rows, 1.0..=10.0, 1.0..=6.0), weighted_mean(&rows, 1.0..=10.0, 25.0..=f64::INFINITY)]
        }
        None => [f64::NAN; 2],
    })
}

/// The species whose DoS/DoA an experiment reports (prey in the paper's scenes).
fn headline(exp: &Experiment) -> String {
    let scene = &exp.runs[0].scene;
    scene.species[SpeciesRegistry::from_scene(scene).headline()].name.clone()
}

/// The data of every finished run, by run index.
pub fn load(exp: &Experiment) -> crate::error::Result<BTreeMap<usize, RunData>> {
    let prey = headline(exp);
    let mut data = BTreeMap::new();
    for (i, run) in exp.runs.iter().enumerate() {
        if stage(run)? != Stage::Trained {
            continue;
        }
        let (metrics, _) = RunDir::new(&run.dir).checked_metrics(false)?;
        let mut d = RunData {
            dos: metrics.column(&schema::of("dos", &prey))?,
            doa: metrics.column(&schema::of("doa", &prey))?,
            catches: metrics.column(schema::CATCHES)?,
            returns: metrics.column(&schema::of("return", &prey))?,
            wall_seconds: metrics.column(schema::WALL_SECONDS)?.last().copied().unwrap_or(0.0),
            orders: super::file::EVAL_ORDER
                .iter()
                .map(|q| {
                    (
                        q.to_string(),
                        metrics.column(&schema::of(q, &prey)).unwrap_or_else(|_| vec![f64::NAN; metrics.rows.len()]),
                    )
                })
                .collect(),
            evals: BTreeMap::new(),
            crossplay: super::crossplay::read_readouts(&run.dir, &prey)?,
            binaries: match RunDir::new(&run.dir).read_provenance()? {
                Some(p) => p.binaries().into_iter().map(String::from).collect(),
                None => vec!["unknown".into()],
            },
        };
        for e in &exp.spec.evaluations {
            let path = eval_file(&run.dir, &e.name);
            if !path.exists() {
                continue;
            }
            if let Some(stale) = super::runner::stale(run, e) {
                return Err(format!("{stale}; run `coevo --experiment {}` to redo it", exp.file.display()).into());
            }
            let table = Table::read_eval(&path)?;
            let step = table.column(schema::STEP)?;
            let steps = step.iter().fold(0.0f64, |a, &b| a.max(b)) as usize;
            let per_step = |values: &[f64]| -> Vec<f64> {
                (1..=steps)
                    .map(|s| {
                        mean(
                            &step
                                .iter()
                                .zip(values)
                                .filter(|(t, v)| **t as usize == s && v.is_finite())
                                .map(|(_, v)| *v)
                                .collect::<Vec<_>>(),
                        )
                        .unwrap_or(f64::NAN)
                    })
                    .collect()
            };
            // DoS and DoA must be there; the other order parameters only since the collective measures.
            let series = |name: &str| -> crate::error::Result<Vec<f64>> {
                match table.column(&schema::of(name, &prey)) {
                    Ok(values) => Ok(per_step(&values)),
                    Err(_) if !matches!(name, "dos" | "doa") => Ok(vec![f64::NAN; steps]),
                    Err(e) => Err(e),
                }
            };
            let per_step = Swarming::NAMES.iter().map(|n| series(n)).collect::<crate::error::Result<Vec<_>>>()?;
            let ranks = table.column(&schema::of(schema::EDGE_RANK, &prey)).unwrap_or_default();
            let edge_rank = mean(&ranks.into_iter().filter(|x| x.is_finite()).collect::<Vec<_>>()).unwrap_or(f64::NAN);
            let confusion = read_confusion(&crate::io::beside(&path, "confusion"))?;
            let response = read_response(&crate::io::beside(&path, crate::run::PERTURBATION))?;
            d.evals.insert(e.name.clone(), EvalData { per_step, edge_rank, confusion, response });
        }
        data.insert(i, d);
    }
    check_one_binary(exp, &data)?;
    Ok(data)
}

/// Refuses runs (training, resumes, evaluations) made by more than one executable, unless the experiment
/// file says `mixed_binaries: true`: its numbers would not come from one program.
fn check_one_binary(exp: &Experiment, data: &BTreeMap<usize, RunData>) -> crate::error::Result<()> {
    if exp.spec.mixed_binaries {
        return Ok(());
    }
    let mut first: Option<(&str, &std::path::Path)> = None;
    for (&i, d) in data {
        let dir = &exp.runs[i].dir;
        for b in &d.binaries {
            match first {
                None => first = Some((b, dir)),
                Some((a, other)) if a != b => {
                    return Err(format!(
                        "{}: runs of more than one binary ({} by {a}, {} by {b}); rerun them with one coevo or set mixed_binaries: true",
                        exp.file.display(),
                        other.display(),
                        dir.display()
                    )
                    .into())
                }
                Some(_) => {}
            }
        }
    }
    Ok(())
}

/// Refuses to aggregate unless every run of the experiment's committed `summary.csv` (that the experiment
/// file still has) is among the run folders here, unless there are none: run folders are not committed, so
/// after some runs were moved away, or while an experiment is re-run, aggregating would replace the
/// committed summaries and figures with a part of them (also when the part holds as many runs, of other
/// variants). Nothing is written then. With no run folder at all (a fresh clone) the committed
/// summary.csv is read as it is and nothing of it is rewritten.
pub fn check_complete(exp: &Experiment, data: &BTreeMap<usize, RunData>) -> crate::error::Result<()> {
    let path = exp.root.join("summary.csv");
    let Some(summary) = Summary::read(&path)? else { return Ok(()) };
    if data.is_empty() {
        return Ok(());
    }
    let held: Vec<usize> = summary.runs(exp).into_iter().map(|(i, _)| i).collect();
    let missing: Vec<String> =
        held.iter().filter(|i| !data.contains_key(i)).map(|&i| super::figure_data::key(&exp.runs[i])).collect();
    if let Some(first) = missing.first() {
        return Err(format!(
            "{}: holds {} runs but only {} of their run folders are here (missing {first}{}; run folders are not committed); nothing written: run `coevo --experiment {}` to rebuild them, or move the summary away",
            path.display(),
            held.len(),
            held.len() - missing.len(),
            if missing.len() > 1 { format!(" and {} more", missing.len() - 1) } else { String::new() },
            exp.file.display()
        )
        .into());
    }
    Ok(())
}

/// Checks an experiment's claims on the `data` of its finished runs ([`load`]) and, when there are any,
/// writes its summaries and figures. Claims with no run yet say so.
pub fn aggregate(exp: &Experiment, data: &BTreeMap<usize, RunData>) -> crate::error::Result<Aggregated> {
    check_complete(exp, data)?;
    let written = !data.is_empty();
    let prey = headline(exp);
    let evals: Vec<String> = exp.spec.evaluations.iter().map(|e| e.name.clone()).collect();
    // One column per primitive quantity (named by `claims::column`), and beside every control how much
    // of the seeing actors' alignment it removes (derived, for reading).
    let mut primitives = vec![Quantity::DosFirst, Quantity::DosLast, Quantity::DoaFirst, Quantity::DoaLast];
    for order in super::file::EVAL_ORDER {
        primitives.push(Quantity::TrainingFirst(order.into()));
        primitives.push(Quantity::TrainingLast(order.into()));
    }
    primitives.push(Quantity::Reach90("dos".into()));
    primitives.push(Quantity::Reach90("doa".into()));
    let named = |q: Quantity| (column(&q).expect("a primitive quantity has a column"), q);
    let mut quantities: Vec<(String, Quantity)> = primitives.into_iter().map(named).collect();
    for e in &evals {
        quantities.push(named(Quantity::EvalDos(e.clone())));
        quantities.push(named(Quantity::EvalDoa(e.clone())));
        quantities.extend(super::file::EVAL_ORDER.iter().map(|o| named(Quantity::EvalOrder(e.clone(), o.to_string()))));
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
        quantities.extend(super::crossplay::READOUTS.iter().map(|r| named(Quantity::Crossplay(r.to_string()))));
    }
    quantities.extend([named(Quantity::CatchesFirst), named(Quantity::CatchesLast)]);
    let mut summary = String::from("preset,variant,seed,episodes");
    for (name, _) in &quantities {
        write!(summary, ",{name}").unwrap();
    }
    summary.push_str(",return_first100,return_last100,wall_seconds,binary,shared_from\n");
    for (i, d) in data {
        let r = &exp.runs[*i];
        write!(summary, "{},{},{},{}", csv_text(&r.preset), csv_text(&r.variant), r.seed, d.dos.len()).unwrap();
        for (_, q) in &quantities {
            // Blank, never NaN, where a run has no value (an evaluation without a catch has no edge rank).
            let v = quantity(exp, d, q);
            write!(summary, ",{}", if v.is_finite() { v.to_string() } else { String::new() }).unwrap();
        }
        let (r0, r1) = (window_mean(&d.returns, true), window_mean(&d.returns, false));
        let shared = r.shared_from.as_deref().unwrap_or("");
        writeln!(summary, ",{r0},{r1},{},{},{shared}", d.wall_seconds, csv_text(&d.binaries.join(" "))).unwrap();
    }

    // The claims are computed from the per-run values alone (summary.csv), so that a clone without run
    // folders recomputes them from the committed summary exactly.
    let table = if written {
        Summary::parse(&summary, &exp.root.join("summary.csv"))?
    } else {
        Summary::read(&exp.root.join("summary.csv"))?.unwrap_or_default()
    };
    // What the figures plot: from the run folders (and kept in figure-data.ron.gz), or in a clone from
    // that committed file, so both draw the same figures byte for byte.
    let drawn: Option<BTreeMap<usize, FigureData>> = if written {
        let of_runs = data.iter().map(|(i, d)| Ok((*i, figure_data::of_run(exp, &exp.runs[*i], d)?)));
        Some(of_runs.collect::<crate::error::Result<_>>()?)
    } else {
        let committed = table.runs(exp);
        let indices: Vec<usize> = committed.iter().map(|(i, _)| *i).collect();
        let read = if indices.is_empty() { None } else { figure_data::read(exp, &indices)? };
        // The committed figure data must be of the committed summary's runs (each run's training length).
        if let Some(read) = &read {
            for (i, row) in &committed {
                let (episodes, d) = (table.value(row, "episodes"), &read[i]);
                if episodes != d.dos.len() as f64 {
                    return Err(format!(
                        "{}: run {} has {} training episodes but summary.csv says {episodes}; the two files are of different runs",
                        exp.root.join(figure_data::FILE).display(),
                        figure_data::key(&exp.runs[*i]),
                        d.dos.len(),
                    )
                    .into());
                }
            }
        }
        read
    };
    if drawn.is_some() {
        crate::io::own_dir(&exp.root.join("figures"))?;
    }
    let mut means = String::from("preset,variant,quantity,seeds,mean,ci95\n");
    let mut results = Vec::new();
    let mut saved = 0;
    for preset in &exp.spec.presets {
        let of_variant = |variant: &str| -> Vec<&RunData> {
            data.iter()
                .filter(|(i, _)| exp.runs[**i].preset == *preset && exp.runs[**i].variant == variant)
                .map(|(_, d)| d)
                .collect()
        };
        for v in &exp.spec.variants {
            let runs = of_variant(&v.name);
            for (name, q) in &quantities {
                if let Some(e) = estimate(&values(exp, &runs, q)) {
                    let ci = e.ci.map_or(String::new(), |c| c.to_string());
                    writeln!(means, "{},{},{name},{},{},{ci}", csv_text(preset), csv_text(&v.name), e.n, e.mean)
                        .unwrap();
                }
            }
        }
        for claim in &exp.spec.claims {
            let samples = |variant: &str| table.values(exp, preset, variant, &claim.quantity);
            let (ours, theirs) = (samples(&claim.variant), claim.versus.as_deref().map(samples));
            // Two variants whose runs are identical (a deterministic re-run, e.g. a switch that never acts)
            // are one sample, not two: no comparison, no p-value.
            let identical = theirs.as_ref().is_some_and(|t| t.len() >= 2 && *t == ours);
            // A change over training needs a first and a last window that do not overlap.
            let overlap = super::claims::compares_windows(&claim.quantity)
                && std::iter::once(&claim.variant)
                    .chain(&claim.versus)
                    .any(|v| table.episodes(preset, v).is_some_and(|n| n < 2 * WINDOW));
            let identical = identical || overlap;
            let e = match &theirs {
                Some(t) => difference(&ours, t),
                None => estimate(&ours),
            };
            let scene = exp.runs.iter().find(|r| r.preset == *preset && r.variant == claim.variant).map(|r| &r.scene);
            results.push(ClaimResult {
                experiment: exp.name.clone(),
                preset: preset.clone(),
                claim: claim.clone(),
                estimate: e,
                p: e.filter(|_| is_effect(claim) && !identical).and_then(|e| e.p_value()),
                p_holm: None,
                baseline: chance_level(exp, claim, scene),
                verdict: match (overlap, identical) {
                    (true, _) => OVERLAP.into(),
                    (false, true) => IDENTICAL.into(),
                    _ => String::new(),
                },
            });
        }
        if let Some(drawn) = &drawn {
            let of_variant = |variant: &str| -> Vec<&FigureData> {
                drawn
                    .iter()
                    .filter(|(i, _)| exp.runs[**i].preset == *preset && exp.runs[**i].variant == variant)
                    .map(|(_, d)| d)
                    .collect()
            };
            figures(exp, preset, &prey, &table, &of_variant, &mut saved)?;
            if exp.spec.crossplay.is_some() {
                crossplay_figures(exp, preset, drawn, &mut saved)?;
            }
            perturbation_figures(exp, preset, &of_variant, &mut saved)?;
        }
    }
    // One family per experiment: every effect's p-value, all presets, adjusted together (Holm).
    let tested: Vec<usize> = (0..results.len()).filter(|&i| results[i].p.is_some()).collect();
    let adjusted = holm(&tested.iter().map(|&i| results[i].p.unwrap_or(1.0)).collect::<Vec<_>>());
    for (&i, p) in tested.iter().zip(adjusted) {
        results[i].p_holm = Some(p);
    }
    for r in results.iter_mut().filter(|r| r.verdict != IDENTICAL && r.verdict != OVERLAP) {
        r.verdict = verdict(&r.claim, r.estimate, r.p_holm, r.baseline);
    }
    if written {
        // The figure data before the summary it must match: a write that fails between them leaves the
        // old summary, which the next aggregation finds incomplete, never a new summary beside old curves.
        figure_data::write(exp, drawn.as_ref().expect("drawn from the run folders"))?;
        crate::io::write_file(&exp.root.join("summary.csv"), crate::io::Existing::Replace, summary.as_bytes())?;
        crate::io::write_file(&exp.root.join("summary-mean.csv"), crate::io::Existing::Replace, means.as_bytes())?;
    }
    Ok(Aggregated { results, summary: table, figures: drawn.is_some().then_some(saved), from_folders: written })
}

/// What [`aggregate`] found, and what it wrote.
pub struct Aggregated {
    pub results: Vec<ClaimResult>,
    /// The per-run values the claims were computed from (written now, or the committed summary.csv).
    pub summary: Summary,
    /// How many figures it drew (each as .svg and .png): from the run folders, or in a clone from the
    /// committed figure data. None when it drew none (a clone of a commit without figure data).
    pub figures: Option<usize>,
    /// Whether the run folders were here, so summary.csv, summary-mean.csv and figure-data.ron.gz were
    /// written from them (else the committed ones were read and left as they are).
    pub from_folders: bool,
}

/// An experiment's per-run values as `summary.csv` holds them: one row per run (preset, variant, seed,
/// then one column per quantity), read with the `csv` crate (variant names may hold commas). The claims
/// are computed from it alone.
#[derive(Clone, Debug, Default)]
pub struct Summary {
    pub columns: Vec<String>,
    pub rows: Vec<SummaryRow>,
}

#[derive(Clone, Debug)]
pub struct SummaryRow {
    pub preset: String,
    pub variant: String,
    pub seed: u64,
    /// Every column's value (NaN where blank or not a number), in `columns` order.
    pub values: Vec<f64>,
    /// The executables that made the run (`binary` column; "unknown" for runs before provenance files).
    pub binary: String,
    /// The experiment that trained the run, when this experiment shares it (`shared_from`); empty else.
    pub shared_from: String,
}

impl Summary {
    /// The committed summary of an experiment, None when it has none.
    pub fn read(path: &Path) -> crate::error::Result<Option<Summary>> {
        match crate::io::read_text(path, crate::io::MAX_TEXT_BYTES) {
            Ok(text) => Ok(Some(Summary::parse(&text, path)?)),
            Err(_) if !path.exists() => Ok(None),
            Err(e) => Err(format!("{}: {e}", path.display()).into()),
        }
    }

    pub fn parse(text: &str, path: &Path) -> crate::error::Result<Summary> {
        let bad = |e: csv::Error| format!("{}: {e}", path.display());
        let mut reader = csv::Reader::from_reader(text.as_bytes());
        let columns: Vec<String> = reader.headers().map_err(bad)?.iter().map(str::to_string).collect();
        let at = |name: &str| columns.iter().position(|c| c == name);
        let (Some(preset), Some(variant), Some(seed)) = (at("preset"), at("variant"), at("seed")) else {
            return Err(format!("{}: no preset, variant and seed columns", path.display()).into());
        };
        let (binary, shared) = (at("binary"), at("shared_from"));
        let mut rows = vec![];
        for record in reader.records() {
            let record = record.map_err(bad)?;
            rows.push(SummaryRow {
                preset: record[preset].to_string(),
                variant: record[variant].to_string(),
                seed: record[seed].parse().map_err(|_| format!("{}: seed {:?}", path.display(), &record[seed]))?,
                values: record.iter().map(|c| c.parse().unwrap_or(f64::NAN)).collect(),
                binary: binary.map_or("unknown", |b| &record[b]).to_string(),
                shared_from: shared.map_or("", |c| &record[c]).to_string(),
            });
        }
        Ok(Summary { columns, rows })
    }

    /// The rows of runs the experiment file still has, each with its index into the experiment's runs.
    pub fn runs<'a>(&'a self, exp: &Experiment) -> Vec<(usize, &'a SummaryRow)> {
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

    pub fn value(&self, row: &SummaryRow, column: &str) -> f64 {
        self.columns.iter().position(|c| c == column).map_or(f64::NAN, |i| row.values[i])
    }

    /// A run's value of a quantity, from its row ([`super::claims::quantity`] computes the same from the
    /// run's own files; both through [`derive`]).
    pub fn quantity(&self, exp: &Experiment, row: &SummaryRow, q: &Quantity) -> f64 {
        derive(exp, q, &|p| column(p).map_or(f64::NAN, |c| self.value(row, &c)))
    }

    /// The fewest episodes any run of one preset and variant trained, None without a run.
    pub fn episodes(&self, preset: &str, variant: &str) -> Option<usize> {
        self.rows
            .iter()
            .filter(|r| r.preset == preset && r.variant == variant)
            .map(|r| self.value(r, "episodes"))
            .filter(|x| x.is_finite())
            .map(|x| x as usize)
            .min()
    }

    /// The finite values of a quantity over the runs of one preset and variant (one per seed).
    pub fn values(&self, exp: &Experiment, preset: &str, variant: &str, q: &Quantity) -> Vec<f64> {
        self.rows
            .iter()
            .filter(|r| r.preset == preset && r.variant == variant)
            .map(|r| self.quantity(exp, r, q))
            .filter(|x| x.is_finite())
            .collect()
    }
}

/// The verdict on a change over training of runs shorter than two windows.
const OVERLAP: &str = "not measured: runs shorter than 200 episodes, so the first and last 100 episodes overlap";

/// The verdict on a comparison of two variants whose runs are identical.
const IDENTICAL: &str = "not a comparison: the two variants' runs are identical (one training, run twice)";

/// A name as one CSV field: quoted (RFC 4180) when it holds a comma or a quote, as variant names may
/// ("body frame, no predators").
fn csv_text(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// Mean and 95 % band over seeds, point by point, of equally long series (cut to the shortest).
fn band(series: &[Vec<f64>], label: &str, x0: f64) -> Option<Curve> {
    let len = series.iter().map(Vec::len).min()?;
    let (mut m, mut lo, mut hi) = (vec![], vec![], vec![]);
    for t in 0..len {
        let e = estimate(&series.iter().map(|s| s[t]).filter(|x| x.is_finite()).collect::<Vec<_>>());
        let (mean, ci) = e.map_or((f64::NAN, 0.0), |e| (e.mean, e.ci.unwrap_or(0.0)));
        m.push(mean);
        lo.push(mean - ci);
        hi.push(mean + ci);
    }
    let seeds = series.len();
    let label = format!("{label} ({seeds} seed{})", if seeds == 1 { "" } else { "s" });
    Some(Curve { label, x: (0..len).map(|t| x0 + t as f64).collect(), mean: m, band: (seeds > 1).then_some((lo, hi)) })
}

/// Per evaluation with `perturb:`, the response of the other prey to the turned one against the lag,
/// nearest six and ranks 25+, each variant's mean over its seeds with the 95 % band
/// (`figures/<preset>-perturbation-<evaluation>.png`).
fn perturbation_figures<'a>(
    exp: &Experiment,
    preset: &str,
    of_variant: &dyn Fn(&str) -> Vec<&'a FigureData>,
    saved: &mut usize,
) -> crate::error::Result<()> {
    for e in exp.spec.evaluations.iter().filter(|e| e.perturb.is_some()) {
        let mut panels = vec![];
        for (k, (which, _)) in figure_data::RESPONSE_RANKS.iter().enumerate() {
            let mut curves = vec![];
            for v in &exp.spec.variants {
                let series: Vec<Vec<f64>> = of_variant(&v.name)
                    .iter()
                    .filter_map(|d| d.evals.get(&e.name)?.response.as_ref()?.get(k).cloned())
                    .collect();
                curves.extend(band(&series, &v.name, 1.0));
            }
            panels.push(Panel {
                title: format!("{}, {preset}: {}, response of {which}", exp.name, e.name),
                x_label: "steps after the turn".into(),
                y_label: "mean |Δheading| (rad)".into(),
                curves,
            });
        }
        if panels.iter().any(|p| !p.curves.is_empty()) {
            plot::save(&exp.root.join("figures").join(format!("{preset}-perturbation-{}", slug(&e.name))), &panels)?;
            *saved += 1;
        }
    }
    Ok(())
}

/// Per variant, the cross-play matrix averaged over its seeds, as heat maps
/// (`figures/<preset>-<variant>-crossplay.png`).
fn crossplay_figures(
    exp: &Experiment,
    preset: &str,
    drawn: &BTreeMap<usize, FigureData>,
    saved: &mut usize,
) -> crate::error::Result<()> {
    for v in &exp.spec.variants {
        let runs: Vec<(&super::file::Run, &FigureData)> = drawn
            .iter()
            .map(|(&i, d)| (&exp.runs[i], d))
            .filter(|(r, _)| r.preset == preset && r.variant == v.name)
            .collect();
        let Some(pair) = runs.first().and_then(|(r, _)| super::crossplay::only_pair(&r.scene)) else { continue };
        let matrices: Vec<_> =
            runs.iter().filter_map(|(_, d)| d.crossplay.as_ref()).map(|c| c.matrix(pair.clone())).collect();
        if let Some(mean) = super::crossplay::mean_matrix(&matrices) {
            let what = format!("{}, {preset}, {} seeds: ", v.name, matrices.len());
            let stem = exp.root.join("figures").join(format!("{preset}-{}-crossplay", slug(&v.name)));
            plot::save_heatmaps(&stem, &super::crossplay::heatmaps(&mean, &what))?;
            *saved += 1;
        }
    }
    Ok(())
}

/// The training curves, the variants compared (from the per-run values of `table`), catches, and per
/// evaluation its per-step curves and confusion curve.
fn figures<'a>(
    exp: &Experiment,
    preset: &str,
    prey: &str,
    table: &Summary,
    of_variant: &dyn Fn(&str) -> Vec<&'a FigureData>,
    saved: &mut usize,
) -> crate::error::Result<()> {
    let dir = exp.root.join("figures");
    let curves = |pick: &dyn Fn(&FigureData) -> Vec<f64>, x0: f64| -> Vec<Curve> {
        exp.spec
            .variants
            .iter()
            .filter_map(|v| {
                band(
                    &of_variant(&v.name).iter().map(|d| pick(d)).filter(|s| !s.is_empty()).collect::<Vec<_>>(),
                    &v.name,
                    x0,
                )
            })
            .collect()
    };
    let title = |what: &str| format!("{}, {preset}: {what}", exp.name);
    let training = [
        Panel {
            title: title(&format!("DoS of {prey}")),
            x_label: "episode".into(),
            y_label: format!("DoS ({WINDOW}-episode mean)"),
            curves: curves(&|d| running_mean(&d.dos, WINDOW), 1.0),
        },
        Panel {
            title: title(&format!("DoA of {prey}")),
            x_label: "episode".into(),
            y_label: format!("DoA ({WINDOW}-episode mean)"),
            curves: curves(&|d| running_mean(&d.doa, WINDOW), 1.0),
        },
    ];
    if training.iter().all(|p| p.curves.is_empty()) {
        return Ok(());
    }
    plot::save(&dir.join(format!("{preset}-training")), &training)?;
    *saved += 1;
    // Variants side by side: what each change does to the learning and to the interaction-driven part of
    // the alignment (seeing minus each control), mean over seeds with its 95 % CI; the ablations' answer to
    // "which differences decide".
    if exp.spec.variants.len() > 1 {
        let mut compared = vec![
            (
                format!("DoA of {prey}: change over training"),
                format!("DoA, last − first {WINDOW} episodes"),
                Quantity::DoaChange,
            ),
            (
                format!("DoS of {prey}: change over training"),
                format!("DoS, last − first {WINDOW} episodes"),
                Quantity::DosChange,
            ),
            (
                "catches: change over training".into(),
                format!("catches per episode, last − first {WINDOW} episodes"),
                Quantity::CatchesChange,
            ),
        ];
        for e in &exp.spec.evaluations {
            if let Some(seeing) = super::file::seeing_partner(&exp.spec.evaluations, &e.name) {
                let title = format!("{}: DoA seeing − {}", seeing.name, e.name);
                compared.push((
                    title,
                    format!("DoA difference, last {SETTLED_STEPS} steps"),
                    Quantity::InteractionDoa(e.name.clone()),
                ));
            }
        }
        let panels: Vec<EstimatePanel> = compared
            .into_iter()
            .map(|(what, x_label, q)| {
                let rows = exp.spec.variants.iter().map(|v| {
                    let e = estimate(&table.values(exp, preset, &v.name, &q));
                    let label = format!("{} ({})", v.name, e.map_or(0, |e| e.n));
                    Row { label, mean: e.map_or(f64::NAN, |e| e.mean), ci: e.and_then(|e| e.ci) }
                });
                EstimatePanel { title: title(&what), x_label, rows: rows.collect() }
            })
            .collect();
        plot::save_estimates(&dir.join(format!("{preset}-variants")), &panels)?;
        *saved += 1;
    }
    let catches = [Panel {
        title: title("catches per episode"),
        x_label: "episode".into(),
        y_label: format!("catches ({WINDOW}-episode mean)"),
        curves: curves(&|d| running_mean(&d.catches, WINDOW), 1.0),
    }];
    plot::save(&dir.join(format!("{preset}-catches")), &catches)?;
    *saved += 1;
    for e in &exp.spec.evaluations {
        let panels = [
            Panel {
                title: title(&format!("{}: DoS per step", e.name)),
                x_label: "time step".into(),
                y_label: "DoS".into(),
                curves: curves(&|d| d.evals.get(&e.name).map_or(vec![], |x| x.dos.clone()), 1.0),
            },
            Panel {
                title: title(&format!("{}: DoA per step", e.name)),
                x_label: "time step".into(),
                y_label: "DoA".into(),
                curves: curves(&|d| d.evals.get(&e.name).map_or(vec![], |x| x.doa.clone()), 1.0),
            },
        ];
        if panels.iter().any(|p| !p.curves.is_empty()) {
            plot::save(&dir.join(format!("{preset}-eval-{}", slug(&e.name))), &panels)?;
            *saved += 1;
        }
        // The confusion curve: what a predator does, and catches, against the prey it has in view.
        let bins = (0..crate::sim::collective::CONFUSION_BINS.len())
            .map(crate::sim::collective::confusion_bin_label)
            .collect::<Vec<_>>()
            .join(", ");
        let x_label = format!("prey in view, bins {bins}");
        let confusion = |k: usize| {
            curves(&|d| d.evals.get(&e.name).map_or(vec![], |x| x.confusion.iter().map(|b| b[k]).collect()), 0.0)
        };
        let panels = [
            Panel {
                title: title(&format!("{}: predator |turn|", e.name)),
                x_label: x_label.clone(),
                y_label: "mean |turn command| / max".into(),
                curves: confusion(0),
            },
            Panel {
                title: title(&format!("{}: predator speed", e.name)),
                x_label: x_label.clone(),
                y_label: "mean speed / max".into(),
                curves: confusion(1),
            },
            Panel {
                title: title(&format!("{}: catch rate", e.name)),
                x_label,
                y_label: "catches per predator-step".into(),
                curves: confusion(2),
            },
        ];
        if panels.iter().any(|p| p.curves.iter().any(|c| c.mean.iter().any(|v| v.is_finite()))) {
            plot::save(&dir.join(format!("{preset}-confusion-{}", slug(&e.name))), &panels)?;
            *saved += 1;
        }
    }
    Ok(())
}

/// One run's learning curves (DoS and DoA of the headline species, 100-episode running means) into
/// `RUN/figures/training.png`, from its `metrics.csv`, checked whole ([`RunDir::checked_metrics`]);
/// with `partial` a run stopped after its last checkpoint is drawn too, its titles saying so.
pub fn plot_run(dir: &Path, partial: bool) -> crate::error::Result<std::path::PathBuf> {
    let run = RunDir::new(dir);
    run.refuse_if_shipped()?;
    let scene = crate::scene::Scene::load(&run.scene())?;
    let prey = scene.species[SpeciesRegistry::from_scene(&scene).headline()].name.clone();
    let (metrics, note) = run.checked_metrics(partial)?;
    let note = note.map_or(String::new(), |n| format!(" ({n})"));
    let curve = |name: &str| -> crate::error::Result<Vec<Curve>> {
        let values = running_mean(&metrics.column(name)?, WINDOW);
        Ok(vec![Curve {
            label: dir.display().to_string(),
            x: (1..=values.len()).map(|x| x as f64).collect(),
            mean: values,
            band: None,
        }])
    };
    let panels = [
        Panel {
            title: format!("DoS of {prey}{note}"),
            x_label: "episode".into(),
            y_label: format!("DoS ({WINDOW}-episode mean)"),
            curves: curve(&schema::of("dos", &prey))?,
        },
        Panel {
            title: format!("DoA of {prey}{note}"),
            x_label: "episode".into(),
            y_label: format!("DoA ({WINDOW}-episode mean)"),
            curves: curve(&schema::of("doa", &prey))?,
        },
    ];
    let figures = crate::run::RunDir::new(dir).figures();
    crate::io::own_dir(&figures)?;
    plot::save(&figures.join("training"), &panels)?;
    Ok(figures.join("training.png"))
}

#[cfg(test)]
mod tests {
    #[test]
    fn names_with_commas_stay_one_csv_field() {
        assert_eq!(super::csv_text("5:3"), "5:3");
        assert_eq!(super::csv_text("body frame, no predators"), "\"body frame, no predators\"");
        assert_eq!(super::csv_text("a \"b\", c"), "\"a \"\"b\"\", c\"");
    }
}
