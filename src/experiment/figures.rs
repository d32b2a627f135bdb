//! An experiment's figures (drawn by `plot.rs`) and a run's training curves (`--plot RUN`).

use super::curves::Shape;
use super::data::headline;
use super::figure_data::{self, FigureData};
use super::file::{slug, Experiment, Order, Quantity};
use super::plot::{self, Curve, EstimatePanel, Level, Panel, Row};
use super::results::{RunData, SETTLED_STEPS, WINDOW};
use super::stats::{estimate, running_mean};
use super::summary::Summary;
use crate::sim::species::SpeciesRegistry;
use crate::store::schema;
use crate::store::RunDir;
use std::collections::BTreeMap;
use std::path::Path;

/// What the figures plot: from the run folders when `written` (and kept in figure-data.ron.gz), with the
/// `carried` figure data of the runs finished elsewhere ([`super::carry`]), or in a clone from that
/// committed file, checked against the committed summary `table`, so both draw the same
/// figures byte for byte. None when there is nothing to draw.
pub(crate) fn data(
    exp: &Experiment,
    data: &BTreeMap<usize, RunData>,
    carried: BTreeMap<usize, FigureData>,
    table: &Summary,
    written: bool,
) -> crate::error::Result<Option<BTreeMap<usize, FigureData>>> {
    Ok(if written {
        let mut of_runs = carried;
        for (i, d) in data {
            of_runs.insert(*i, figure_data::of_run(exp, &exp.runs[*i], d)?);
        }
        Some(of_runs)
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
    })
}

/// Every figure of one preset: the training curves, the variants compared, catches, each evaluation's
/// curves, the cross-play heat maps and the perturbation responses; `saved` counts them.
pub(crate) fn draw(
    exp: &Experiment,
    preset: &str,
    table: &Summary,
    drawn: &BTreeMap<usize, FigureData>,
    saved: &mut usize,
) -> crate::error::Result<()> {
    let prey = headline(exp);
    let of_variant = |variant: &str| -> Vec<&FigureData> {
        drawn
            .iter()
            .filter(|(i, _)| exp.runs[**i].preset == *preset && exp.runs[**i].variant == variant)
            .map(|(_, d)| d)
            .collect()
    };
    figures(exp, preset, &prey, table, &of_variant, saved)?;
    if exp.spec.crossplay.is_some() {
        crossplay_figures(exp, preset, drawn, saved)?;
    }
    perturbation_figures(exp, preset, &of_variant, saved)?;
    super::grid::figures(exp, preset, table, saved)?;
    series_figures(exp, preset, table, saved)?;
    Ok(())
}

/// Refuses a figure `stem` whose SVG or PNG exists already (a user's file, never overwritten), before
/// any work: one line naming the flag and the file.
pub(crate) fn check_new_figure(stem: &std::path::Path, flag: &str) -> crate::error::Result<()> {
    match plot::files(stem).into_iter().find(|f| f.exists()) {
        Some(f) => {
            Err(format!("{flag} {}: {} exists; name another file or move it away", stem.display(), f.display()).into())
        }
        None => Ok(()),
    }
}

/// `coevo --bench --bench-figure FILE`: the cost of a learned step of the default scene against group size
/// at one density (`run::bench::group_size`), as FILE.svg and FILE.png: log10 of the time per step and
/// per agent-step against log10 of the prey, with the least-squares exponent of the time per step over
/// the groups of 200 prey and more printed (how it grows).
pub(crate) fn group_size_cost(stem: &std::path::Path, budget: std::time::Duration) -> crate::error::Result<()> {
    let steps = crate::run::bench::group_size_steps(budget);
    let n: Vec<f64> = steps.iter().map(|(prey, ..)| (*prey as f64).log10()).collect();
    let per_step: Vec<f64> = steps.iter().map(|(_, _, f)| (1e6 / f.per_second).log10()).collect();
    let per_agent: Vec<f64> =
        steps.iter().map(|(prey, predators, f)| (1e6 / f.per_second / (prey + predators) as f64).log10()).collect();
    let large: Vec<usize> = (0..steps.len()).filter(|&i| steps[i].0 >= 200).collect();
    let exponent = {
        let (x, y): (Vec<f64>, Vec<f64>) = large.iter().map(|&i| (n[i], per_step[i])).unzip();
        super::stats::least_squares(&x, &y)
    };
    let curve = |label: &str, y: Vec<f64>| Curve { label: label.into(), x: n.clone(), mean: y, band: None };
    let panels = [
        Panel {
            title: format!("time per step against group size (exponent {exponent:.2} from 200 prey on)"),
            x_label: "log10 prey (predators 3 per 50, one density)".into(),
            y_label: "log10 µs per step".into(),
            curves: vec![curve("learned step", per_step)],
            levels: vec![],
        },
        Panel {
            title: "time per agent-step against group size".into(),
            x_label: "log10 prey (predators 3 per 50, one density)".into(),
            y_label: "log10 µs per agent-step".into(),
            curves: vec![curve("learned step", per_agent)],
            levels: vec![],
        },
    ];
    plot::save_in(stem, &panels, 2)?;
    crate::outln!(
        "group size: time per step grows as N^{exponent:.2} over 200 to {} prey; figure in {}.svg and .png",
        steps.last().map_or(0, |(p, ..)| *p),
        stem.display()
    )
}

/// A group-size series (the evaluations that set `arena_edge`, a group at one density): DoA, polarization,
/// milling, C_nn and catches per prey against log10 of the prey deployed, each variant's mean over its
/// seeds with the 95 % band (`figures/<preset>-group-size`), from `summary.csv`'s values.
fn series_figures(exp: &Experiment, preset: &str, table: &Summary, saved: &mut usize) -> crate::error::Result<()> {
    let prey = headline(exp);
    let mut series: Vec<(usize, &super::file::Evaluation)> = exp
        .spec
        .evaluations
        .iter()
        .filter(|e| e.arena_edge.is_some() && e.control.is_seeing() && !e.untrained)
        .filter_map(|e| {
            let run = exp.runs.iter().find(|r| r.preset == preset)?;
            let mut scene = run.scene.clone();
            e.overrides().apply(&mut scene, std::path::Path::new(&e.name)).ok()?;
            Some((scene.species.iter().find(|s| s.name == prey)?.count, e))
        })
        .collect();
    series.sort_by_key(|(n, _)| *n);
    if series.len() < 2 {
        return Ok(());
    }
    let quantities = [
        ("DoA", Quantity::EvalDoa as fn(String) -> Quantity),
        ("polarization", |e| Quantity::EvalOrder(e, Order::Polarization)),
        ("milling", |e| Quantity::EvalOrder(e, Order::Milling)),
        ("C_nn", |e| Quantity::EvalOrder(e, Order::NnCorrelation)),
        ("catches per prey per episode", Quantity::EvalCatches),
    ];
    let mut panels = Vec::new();
    for (label, quantity) in quantities {
        let mut curves = Vec::new();
        for v in &exp.spec.variants {
            let e: Vec<Option<super::stats::Estimate>> = series
                .iter()
                .map(|(_, e)| estimate(&table.values(exp, preset, &v.name, &quantity(e.name.clone()))))
                .collect();
            let seeds = e.iter().flatten().map(|e| e.n).max().unwrap_or(0);
            let x = series.iter().map(|(n, _)| (*n as f64).log10()).collect();
            curves.push(Curve::of_estimates(format!("{} ({seeds} seeds)", v.name), x, &e));
        }
        let counts: Vec<String> = series.iter().map(|(n, _)| n.to_string()).collect();
        panels.push(Panel {
            title: format!("{label} against group size, {preset}"),
            x_label: format!("log10 {prey} ({})", counts.join(", ")),
            y_label: format!("{label}, mean over seeds, 95 % CI"),
            curves,
            levels: vec![],
        });
    }
    plot::save_in(&exp.figures_dir().join(format!("{preset}-group-size")), &panels, 3)?;
    *saved += 1;
    Ok(())
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
                levels: vec![],
            });
        }
        if panels.iter().any(|p| !p.curves.is_empty()) {
            plot::save(&exp.figures_dir().join(format!("{preset}-perturbation-{}", slug(&e.name))), &panels)?;
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
        let Some(pair) = runs.first().and_then(|(r, _)| super::crossplay_matrix::only_pair(&r.scene)) else { continue };
        let matrices: Vec<_> =
            runs.iter().filter_map(|(_, d)| d.crossplay.as_ref()).map(|c| c.matrix(pair.clone())).collect();
        if let Some(mean) = super::crossplay_matrix::mean_matrix(&matrices) {
            let what = format!("{}, {preset}, {} seeds: ", v.name, matrices.len());
            let stem = exp.figures_dir().join(format!("{preset}-{}-crossplay", slug(&v.name)));
            plot::save_heatmaps(&stem, &super::crossplay::heatmaps(&mean, &what))?;
            *saved += 1;
        }
    }
    Ok(())
}

/// An experiment that distills its runs (`distill:`): every evaluation side by side (the learned agents,
/// the rules in their place, the ablations), and the numbers of the fitted rules across seeds; mean over
/// seeds with its 95 % CI, for the first variant.
fn distilled_figures(
    exp: &Experiment,
    preset: &str,
    table: &super::summary::Summary,
    dir: &Path,
    title: &dyn Fn(&str) -> String,
) -> crate::error::Result<()> {
    use crate::scene::RuleForm;
    let variant = exp.spec.variants.first().map(|v| v.name.clone()).unwrap_or_default();
    let row = |label: &str, q: Quantity| {
        let e = estimate(&table.values(exp, preset, &variant, &q));
        Row {
            label: format!("{label} ({})", e.map_or(0, |e| e.n)),
            mean: e.map_or(f64::NAN, |e| e.mean),
            ci: e.and_then(|e| e.ci),
        }
    };
    let orders =
        [("DoA", Order::Doa), ("DoS", Order::Dos), ("polarization", Order::Polarization), ("milling", Order::Milling)];
    // Evaluations named "50 prey", "50 prey, distilled prey", ...: the rows drop the common "50 prey, ".
    let first = exp.spec.evaluations.first().map(|e| format!("{}, ", e.name)).unwrap_or_default();
    let short = |name: &str| name.strip_prefix(first.as_str()).unwrap_or(name).to_string();
    let panels: Vec<EstimatePanel> = orders
        .iter()
        .map(|(shown, order)| {
            let rows = exp.spec.evaluations.iter().map(|e| {
                let q = match *order {
                    Order::Doa => Quantity::EvalDoa(e.name.clone()),
                    Order::Dos => Quantity::EvalDos(e.name.clone()),
                    other => Quantity::EvalOrder(e.name.clone(), other),
                };
                row(&short(&e.name), q)
            });
            EstimatePanel {
                title: title(&format!("{shown} by evaluation ({} ...)", first.trim_end_matches(", "))),
                x_label: format!("{shown}, last {SETTLED_STEPS} steps"),
                rows: rows.collect(),
            }
        })
        .collect();
    plot::save_estimates(&dir.join(format!("{preset}-evaluations")), &panels)?;
    // The rules: per species and form, its gains; then how much of each action each explains.
    let forms = exp.spec.distill.as_ref().map(|d| d.forms.clone()).unwrap_or_default();
    let rules = exp.runs.first().map(|r| super::distill::rules(&r.scene, &forms)).unwrap_or_default();
    let mut panels = vec![];
    let mut explained = vec![];
    for (species, form, numbers) in rules {
        let q = |n: &str| Quantity::Distilled(species.clone(), form, n.to_string());
        // A term's statistics are named after it ("turn.alignment.per_sd"): not gains themselves.
        let (gains, statistics): (Vec<&String>, Vec<&String>) =
            numbers.iter().partition(|n| !super::distill::STATISTICS.iter().any(|s| n.ends_with(&format!(".{s}"))));
        // A gain belongs to the turn or the thrust by its prefix, or (a pursuit rule's own-state terms) by name.
        for (part, own, shown) in [("turn.", "persistence", "turn"), ("thrust.", "speed", "thrust")] {
            // A memoryless rule's own-state terms are not fitted: not shown.
            let own_term = |n: &str| n == own || n.ends_with(&format!(".{own}"));
            // A binned rule's gains per bin are drawn by distance ([`binned_figure`]), not as rows here.
            let gain = |n: &&&String| {
                ((n.starts_with(part) && !n.ends_with("bias")) || n.as_str() == own)
                    && !(form == RuleForm::Memoryless && own_term(n))
                    && !n.contains('[')
            };
            let rows: Vec<Row> = gains.iter().filter(gain).map(|n| row(n.trim_start_matches(part), q(n))).collect();
            panels.push(EstimatePanel {
                title: title(&format!("{species}, {form:?}: {shown} gains")),
                x_label: format!("gain on the normalized {shown}"),
                rows,
            });
        }
        // Every term in one unit (per SD of its feature), and what it adds out of sample; runs fitted
        // before these were reported have none, and no panel.
        for (statistic, shown, x_label) in [
            ("per_sd", "gain per SD of each term", "gain per standard deviation of the term"),
            ("held_out", "held-out ΔR² of each term", "held-out variance explained, less the rule's without the term"),
        ] {
            let suffix = format!(".{statistic}");
            let rows: Vec<Row> = statistics
                .iter()
                .filter(|n| n.ends_with(&suffix))
                .map(|n| row(n.trim_end_matches(&suffix), q(n)))
                .filter(|r| r.mean.is_finite())
                .collect();
            if !rows.is_empty() {
                panels.push(EstimatePanel {
                    title: title(&format!("{species}, {form:?}: {shown}")),
                    x_label: x_label.into(),
                    rows,
                });
            }
        }
        explained.extend(
            super::distill::EXPLAINED
                .iter()
                .map(|n| row(&format!("{species} {form:?} {}", n.trim_start_matches("explained_")), q(n))),
        );
    }
    panels.push(EstimatePanel {
        title: title("variance explained, held-out episodes"),
        x_label: "fraction of the action's variance".into(),
        rows: explained,
    });
    plot::save_estimates(&dir.join(format!("{preset}-distilled")), &panels)?;
    binned_figure(exp, preset, table, dir, title)
}

/// The binned rules an experiment reads (`forms: [.., Binned]`), gain by distance: per species, the turn's
/// and the thrust's gain of each kind of term (kin directions, alignment, evasion) at each bin's middle,
/// mean over seeds with its 95 % band (`figures/<preset>-binned`). A bin no neighbour fell in keeps a
/// gain of zero.
fn binned_figure(
    exp: &Experiment,
    preset: &str,
    table: &super::summary::Summary,
    dir: &Path,
    title: &dyn Fn(&str) -> String,
) -> crate::error::Result<()> {
    use crate::scene::RuleForm;
    let (Some(d), Some(run)) = (&exp.spec.distill, exp.runs.first()) else { return Ok(()) };
    let variant = exp.spec.variants.first().map(|v| v.name.clone()).unwrap_or_default();
    let edges: Vec<f64> = super::distill::RADII.iter().map(|r| r * run.scene.world.arena_edge).collect();
    let middles: Vec<f64> = edges.windows(2).map(|w| (w[0] + w[1]) / 2.0).collect();
    let mut panels = vec![];
    for (species, _, _) in super::distill::rules(&run.scene, &d.forms).iter().filter(|(_, f, _)| *f == RuleForm::Binned)
    {
        for (part, kinds) in [("turn", &["kin", "alignment", "evasion"][..]), ("thrust", &["kin", "evasion"][..])] {
            let curves = kinds.iter().map(|kind| {
                let estimates: Vec<_> = (0..middles.len())
                    .map(|b| {
                        let q = Quantity::Distilled(species.clone(), RuleForm::Binned, format!("{part}.{kind}[{b}]"));
                        estimate(&table.values(exp, preset, &variant, &q))
                    })
                    .collect();
                plot::Curve::of_estimates(kind.to_string(), middles.clone(), &estimates)
            });
            panels.push(plot::Panel {
                title: title(&format!("{species}, binned rule: {part} gain by distance")),
                x_label: "distance to the neighbour (m, middle of its bin)".into(),
                y_label: format!("gain on the normalized {part}"),
                curves: curves.collect(),
                levels: vec![],
            });
        }
    }
    if panels.is_empty() {
        return Ok(());
    }
    plot::save(&dir.join(format!("{preset}-binned")), &panels)
}

/// The training curves, the variants compared (from the per-run values of `table`), catches, and per
/// evaluation its per-step curves and confusion curve.
/// The values a training curve of `curve` (DoS or DoA) is read against: the paper's start and end
/// levels as the experiment's claims state them (a start over the first 100 episodes, an end over the last
/// 100 of `episodes`; in the colour of the variant they are about), and chance at the base scene's density.
fn levels(exp: &Experiment, preset: &str, curve: super::file::Curve, episodes: usize) -> Vec<Level> {
    let last = if curve == super::file::Curve::Dos { Quantity::DosLast } else { Quantity::DoaLast };
    let first = Quantity::Start(curve);
    let end = episodes as f64;
    let mut out: Vec<Level> = Vec::new();
    for c in exp.spec.claims.iter().filter(|c| c.versus.is_none() && !c.direction_only) {
        let (Some(y), Some(colour)) = (c.paper, exp.spec.variants.iter().position(|v| v.name == c.variant)) else {
            continue;
        };
        let x = match &c.quantity {
            q if *q == first => (1.0, (WINDOW as f64).min(end)),
            q if *q == last => ((end - WINDOW as f64 + 1.0).max(1.0), end),
            _ => continue,
        };
        // One line per value and variant (a level several claims state is drawn once).
        if !out.iter().any(|l| l.y == y && l.colour == colour && l.x == Some(x)) {
            out.push(Level { label: "the paper".into(), y, x: Some(x), chance: false, colour });
        }
    }
    let base = exp.spec.variants.first().map(|v| v.name.clone()).unwrap_or_default();
    let scene = exp.runs.iter().find(|r| r.preset == preset && r.variant == base).map(|r| &r.scene);
    let probe = super::file::Claim::of("", &base, last);
    if let Some(y) = super::quantity::chance_level(exp, &probe, scene) {
        out.push(Level { label: "chance".into(), y, x: None, chance: true, colour: 0 });
    }
    out
}

/// Variants side by side: what each change does to the learning and to the interaction-driven part of
/// the alignment (seeing minus each control), mean over seeds with its 95 % CI; the ablations' answer to
/// "which differences decide".
fn variants_figure(
    exp: &Experiment,
    preset: &str,
    prey: &str,
    table: &Summary,
    title: &dyn Fn(&str) -> String,
) -> crate::error::Result<()> {
    let dir = exp.figures_dir();
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
    // How fast each variant converges, where a claim of the file asks (Halfway, Reaches): the episode per
    // variant with its interval, beside the changes.
    let mut convergence: Vec<Quantity> = Vec::new();
    for c in &exp.spec.claims {
        if c.quantity.is_convergence_episode() && !convergence.contains(&c.quantity) {
            convergence.push(c.quantity.clone());
        }
    }
    for q in convergence {
        // A panel's title fits its column: the quantity in short, the definition on the axis.
        let curve = |c: super::file::Curve| if c == super::file::Curve::Dos { "DoS" } else { "DoA" };
        let (what, x_label) = match q.shape() {
            Some((c, Shape::Halfway)) => (
                format!("{}: halfway episode", curve(c)),
                format!("episode its {}-episode mean completes half its change", super::results::HALFWAY_WINDOW),
            ),
            Some((c, Shape::Reaches(level))) => (
                format!("{}: episode it first reaches {level}", curve(c)),
                format!("episode its {}-episode mean first reaches {level}", super::results::HALFWAY_WINDOW),
            ),
            _ => (super::quantity::quantity_name(&q), "episode".into()),
        };
        compared.push((what, x_label, q));
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
    plot::save_estimates(&dir.join(format!("{preset}-variants")), &panels)
}

fn figures<'a>(
    exp: &Experiment,
    preset: &str,
    prey: &str,
    table: &Summary,
    of_variant: &dyn Fn(&str) -> Vec<&'a FigureData>,
    saved: &mut usize,
) -> crate::error::Result<()> {
    let dir = exp.figures_dir();
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
    let episodes = exp.spec.variants.iter().flat_map(|v| of_variant(&v.name)).map(|d| d.dos.len()).max().unwrap_or(0);
    let training = [
        Panel {
            title: title(&format!("DoS of {prey}")),
            x_label: "episode".into(),
            y_label: format!("DoS ({WINDOW}-episode mean)"),
            curves: curves(&|d| running_mean(&d.dos, WINDOW), 1.0),
            levels: levels(exp, preset, super::file::Curve::Dos, episodes),
        },
        Panel {
            title: title(&format!("DoA of {prey}")),
            x_label: "episode".into(),
            y_label: format!("DoA ({WINDOW}-episode mean)"),
            curves: curves(&|d| running_mean(&d.doa, WINDOW), 1.0),
            levels: levels(exp, preset, super::file::Curve::Doa, episodes),
        },
    ];
    if training.iter().all(|p| p.curves.is_empty()) {
        return Ok(());
    }
    plot::save(&dir.join(format!("{preset}-training")), &training)?;
    *saved += 1;
    if exp.spec.variants.len() > 1 {
        variants_figure(exp, preset, prey, table, &title)?;
        *saved += 1;
    }
    if exp.spec.distill.is_some() {
        distilled_figures(exp, preset, table, &dir, &title)?;
        *saved += 2;
    }
    let catches = [Panel {
        title: title("catches per episode"),
        x_label: "episode".into(),
        y_label: format!("catches ({WINDOW}-episode mean)"),
        curves: curves(&|d| running_mean(&d.catches, WINDOW), 1.0),
        levels: vec![],
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
                levels: vec![],
            },
            Panel {
                title: title(&format!("{}: DoA per step", e.name)),
                x_label: "time step".into(),
                y_label: "DoA".into(),
                curves: curves(&|d| d.evals.get(&e.name).map_or(vec![], |x| x.doa.clone()), 1.0),
                levels: vec![],
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
                levels: vec![],
            },
            Panel {
                title: title(&format!("{}: predator speed", e.name)),
                x_label: x_label.clone(),
                y_label: "mean speed / max".into(),
                curves: confusion(1),
                levels: vec![],
            },
            Panel {
                title: title(&format!("{}: catch rate", e.name)),
                x_label,
                y_label: "catches per predator-step".into(),
                curves: confusion(2),
                levels: vec![],
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
pub(crate) fn plot_run(dir: &Path, partial: bool) -> crate::error::Result<std::path::PathBuf> {
    let run = RunDir::new(dir);
    run.refuse_if_shipped()?;
    let scene = crate::scene::Scene::load(&run.scene())?;
    let prey = scene.species[SpeciesRegistry::from_scene(&scene).headline()].name.clone();
    let (metrics, note) = run.checked_metrics(partial)?;
    let note = note.map_or(String::new(), |n| format!(" ({n})"));
    // Chance: DoS of uniform random positions at the run's density, DoA of independent headings (2/π).
    let arena = crate::sim::space::Arena { edge: scene.world.arena_edge, boundary: scene.world.boundary };
    let count = scene.species.iter().find(|d| d.name == prey).map_or(0, |d| d.count);
    let chance = |y: Option<f64>| -> Vec<Level> {
        y.map(|y| Level { label: "chance".into(), y, x: None, chance: true, colour: 0 }).into_iter().collect()
    };
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
            levels: chance(crate::sim::metrics::random_dos(&arena, count)),
        },
        Panel {
            title: format!("DoA of {prey}{note}"),
            x_label: "episode".into(),
            y_label: format!("DoA ({WINDOW}-episode mean)"),
            curves: curve(&schema::of("doa", &prey))?,
            levels: chance(Some(std::f64::consts::FRAC_2_PI)),
        },
    ];
    let figures = crate::store::RunDir::new(dir).figures();
    crate::io::own_dir(&figures)?;
    plot::save(&figures.join("training"), &panels)?;
    Ok(figures.join("training.png"))
}
