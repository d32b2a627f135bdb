//! Live plots (egui_plot): DoS and DoA per episode with their 100-episode running means, DoS, DoA,
//! polarization, milling, largest cluster and nearest-neighbour heading correlation step by step within the
//! current episode (the last finished one "as fast as possible", where a frame ends on an episode's
//! updates), and catches per episode, for the headline species (the prey). Every plot has labelled ticks on
//! both axes at any size ([`ticks`]), DoS/DoA plots their chance levels at the density shown.

use crate::sim::clock::Episode;
use crate::sim::metrics::{EpisodeLog, SwarmMetrics};
use crate::sim::species::SpeciesRegistry;
use bevy::prelude::*;
use bevy_egui::egui;
use egui_plot::{AxisHints, GridInput, GridMark, HLine, Line, LineStyle, Plot, PlotPoints, Points};

/// The paper's smoothing window for learning curves (Fig. 3: running mean over 100 episodes).
const RUNNING_MEAN: usize = 100;

/// What the plots show, collected after every step.
#[derive(Resource, Default, Debug)]
pub(crate) struct History {
    /// Per finished episode: [episode, DoS], [episode, DoA], [episode, catches].
    pub(crate) dos: Vec<[f64; 2]>,
    pub(crate) doa: Vec<[f64; 2]>,
    pub(crate) catches: Vec<[f64; 2]>,
    /// Within the current episode, step by step.
    pub(crate) steps: StepCurves,
    /// The last finished episode's (its index), shown "as fast as possible".
    pub(crate) last_steps: Option<(usize, StepCurves)>,
    /// Chance levels of the headline species at the density of this world: (its count, DoS of uniform
    /// random positions at that count); DoA's is 2/π at any count.
    pub(crate) chance: Option<(usize, Option<f64>)>,
    /// Watching a run: how many of the headline species it trained with (its training curves' density).
    pub(crate) trained_count: Option<usize>,
    /// Watching a run: its training curves from its `metrics.csv` ([episode, value] for DoS, DoA,
    /// catches), shown before the episodes watched here.
    pub(crate) training: Option<[Vec<[f64; 2]>; 3]>,
    /// Watching a run that was cross-played: every snapshot's rating per species ([episode, rating],
    /// `crossplay-ratings.csv`), the arms race over training.
    pub(crate) ratings: Option<Vec<(String, Vec<[f64; 2]>)>>,
}

/// One episode's order parameters, step by step: [step, value].
#[derive(Default, Debug, Clone)]
pub(crate) struct StepCurves {
    pub(crate) dos: Vec<[f64; 2]>,
    pub(crate) doa: Vec<[f64; 2]>,
    pub(crate) polarization: Vec<[f64; 2]>,
    pub(crate) milling: Vec<[f64; 2]>,
    pub(crate) largest_cluster: Vec<[f64; 2]>,
    pub(crate) nn_correlation: Vec<[f64; 2]>,
}

impl History {
    pub(crate) fn clear(&mut self) {
        *self = History::default();
    }

    /// A new episode starts (or the population changed): its curves start empty. A finished episode's
    /// (`finished`: its index) are kept as the last one.
    pub(crate) fn start_episode(&mut self, finished: Option<usize>) {
        let steps = std::mem::take(&mut self.steps);
        if let Some(episode) = finished.filter(|_| !steps.dos.is_empty()) {
            self.last_steps = Some((episode, steps));
        }
    }
}

pub(crate) struct PlotsPlugin;

impl Plugin for PlotsPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<History>();
    }
}

/// After a step: the step's DoS/DoA, and any episode that just ended.
pub(crate) fn record_step(world: &mut World) {
    let prey = world.resource::<SpeciesRegistry>().headline();
    let ended = std::mem::take(&mut world.resource_mut::<EpisodeLog>().episodes);
    let step = world.resource::<Episode>().step as f64;
    let now = world.resource::<SwarmMetrics>().now.get(prey).copied().flatten();
    let count = world.resource::<SpeciesRegistry>().defs[prey].count;
    if world.resource::<History>().chance.is_none_or(|(n, _)| n != count) {
        let dos = crate::sim::metrics::random_dos(world.resource::<crate::sim::space::Arena>(), count);
        world.resource_mut::<History>().chance = Some((count, dos));
    }
    let mut h = world.resource_mut::<History>();
    for e in &ended {
        let x = e.episode as f64;
        if let Some(s) = e.swarming.get(prey).copied().flatten() {
            h.dos.push([x, s.dos]);
            h.doa.push([x, s.doa]);
        }
        h.catches.push([x, e.catches as f64]);
    }
    if let Some(last) = ended.last() {
        h.start_episode(Some(last.episode));
    }
    if let Some(s) = now {
        let c = &mut h.steps;
        c.dos.push([step, s.dos]);
        c.doa.push([step, s.doa]);
        c.polarization.push([step, s.polarization]);
        c.milling.push([step, s.milling]);
        c.largest_cluster.push([step, s.largest_cluster]);
        c.nn_correlation.push([step, s.nn_correlation]);
    }
}

/// Running mean over the last `window` points (fewer at the start).
pub(crate) fn running_mean(points: &[[f64; 2]], window: usize) -> Vec<[f64; 2]> {
    let values: Vec<f64> = points.iter().map(|p| p[1]).collect();
    points.iter().zip(crate::sim::metrics::running_mean(&values, window)).map(|(p, m)| [p[0], m]).collect()
}

const DOS: egui::Color32 = egui::Color32::from_rgb(70, 130, 220);
const DOA: egui::Color32 = egui::Color32::from_rgb(235, 140, 40);

fn line(name: &str, points: &[[f64; 2]], colour: egui::Color32, width: f32) -> Line<'static> {
    Line::new(name, PlotPoints::from(points.to_vec())).color(colour).width(width)
}

/// The curves' names in their colours, on one wrapping row above a plot: a legend that never covers a
/// curve (egui_plot draws its legend inside the plot area).
fn key(ui: &mut egui::Ui, entries: &[(&str, egui::Color32)]) {
    ui.horizontal_wrapped(|ui| {
        for (name, colour) in entries {
            ui.label(egui::RichText::new(format!("— {name}")).color(*colour).small());
        }
    });
}

const POLARIZATION: egui::Color32 = egui::Color32::from_rgb(60, 160, 90);
const MILLING: egui::Color32 = egui::Color32::from_rgb(150, 90, 200);
const CLUSTER: egui::Color32 = egui::Color32::from_rgb(120, 120, 120);
const C_NN: egui::Color32 = egui::Color32::from_rgb(200, 60, 140);
const CATCHES: egui::Color32 = egui::Color32::from_rgb(200, 40, 40);

/// Reads a watched run's training curves of `species` (DoS, DoA, catches per episode) from its
/// `metrics.csv`; None when it has none to show.
pub(crate) fn training_curves(run: &std::path::Path, species: &str) -> Option<[Vec<[f64; 2]>; 3]> {
    use crate::store::schema::{self, Table};
    let table = Table::read(&crate::store::RunDir::new(run).metrics()).ok()?;
    let column = |name: &str| -> Option<Vec<[f64; 2]>> {
        Some(table.column(name).ok()?.into_iter().enumerate().map(|(e, v)| [e as f64, v]).collect())
    };
    let curves = [column(&schema::of("dos", species))?, column(&schema::of("doa", species))?, column(schema::CATCHES)?];
    (!curves[0].is_empty()).then_some(curves)
}

/// How many of `species` a watched run trained with (its `scene.ron`); None without one.
pub(crate) fn trained_count(run: &std::path::Path, species: &str) -> Option<usize> {
    let scene = crate::scene::Scene::load(&crate::store::RunDir::new(run).scene()).ok()?;
    scene.species.iter().find(|d| d.name == species).map(|d| d.count)
}

/// The episodes watched here, placed after the run's training episodes on the same axis.
fn after(points: &[[f64; 2]], offset: f64) -> Vec<[f64; 2]> {
    points.iter().map(|p| [p[0] + offset, p[1]]).collect()
}

/// Pixels between labelled ticks, beyond the spacing from which the axes label a tick fully opaque
/// ([`X_LABEL_SPACING`]; egui_plot's default y spacing is 20–30 px).
const X_LABEL_PX: f64 = 48.0;
const Y_LABEL_PX: f64 = 32.0;
/// From how far apart x ticks are labelled (faint) to fully opaque: egui_plot's default (60–80 px) is
/// wide enough for long dates; episode numbers need ~30 px.
const X_LABEL_SPACING: (f32, f32) = (36.0, 44.0);
/// egui_plot's default `grid_spacing` minimum, which `GridInput::base_step_size` is measured in.
const GRID_MIN_PX: f64 = 8.0;

/// Ticks at round values (1, 2, 2.5 or 5 × 10^k; on a `whole` axis, episodes or steps, whole numbers from
/// 1, 2, 5 × 10^k) spaced at least `label_px` pixels apart, so that every tick is labelled at any plot
/// size (egui_plot's default ticks step in powers of ten, and a 300 px plot of 900 episodes then labels
/// only 0); thinner unlabelled grid lines at a fifth of the step.
pub(crate) fn ticks(label_px: f64, whole: bool) -> impl Fn(GridInput) -> Vec<GridMark> {
    move |input: GridInput| {
        let per_px = input.base_step_size / GRID_MIN_PX;
        let (lo, hi) = input.bounds;
        if !(per_px > 0.0 && per_px.is_finite() && lo.is_finite() && hi.is_finite() && hi > lo) {
            return vec![];
        }
        let step = match whole {
            true => round_step(per_px * label_px, &[1.0, 2.0, 5.0]).max(1.0),
            false => round_step(per_px * label_px, &[1.0, 2.0, 2.5, 5.0]),
        };
        // A whole axis draws no grid lines between whole numbers.
        let per_major = if whole && step < 5.0 { 1 } else { 5 };
        let minor = step / per_major as f64;
        let first = (lo / minor).ceil() as i64;
        let last = (hi / minor).floor() as i64;
        (first..=last)
            .map(|k| {
                let major = k.rem_euclid(per_major) == 0;
                GridMark { value: k as f64 * minor, step_size: if major { step } else { minor } }
            })
            .collect()
    }
}

/// The smallest of `mantissas` × 10^k at least `at_least`.
fn round_step(at_least: f64, mantissas: &[f64]) -> f64 {
    let power = 10f64.powf(at_least.log10().floor());
    mantissas.iter().chain([&10.0]).map(|m| m * power).find(|&s| s >= at_least * (1.0 - 1e-9)).unwrap_or(10.0 * power)
}

/// A tick's label: up to three decimals, trailing zeros dropped ("0.25", "0.5", "1", "1500"); egui_plot's
/// default rounds to the step's power of ten, so 0.5 would read "0".
fn tick_label(mark: GridMark, _range: &std::ops::RangeInclusive<f64>) -> String {
    let text = format!("{:.3}", mark.value);
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" {
        "0".to_string()
    } else {
        text.to_string()
    }
}

/// A plot with round, labelled ticks on both axes; whole numbers on x when it counts (`whole_x`: episodes,
/// steps).
fn plot(id: &str, height: f32, x: &str, whole_x: bool, y: &str) -> Plot<'static> {
    let x_axis = AxisHints::new_x()
        .label(x.to_string())
        .label_spacing(egui::Rangef::new(X_LABEL_SPACING.0, X_LABEL_SPACING.1))
        .formatter(tick_label);
    Plot::new(id)
        .height(height)
        .custom_x_axes(vec![x_axis])
        .custom_y_axes(vec![AxisHints::new_y().label(y.to_string()).formatter(tick_label)])
        .grid_spacing(egui::Rangef::new(GRID_MIN_PX as f32, 300.0))
        .x_grid_spacer(ticks(X_LABEL_PX, whole_x))
        .y_grid_spacer(ticks(Y_LABEL_PX, false))
}

/// Chance levels are drawn dashed in this near-white, which nothing else inside a plot uses.
pub(crate) const CHANCE: egui::Color32 = egui::Color32::from_rgb(225, 225, 225);

/// The chance lines of a DoS/DoA plot: DoA 2/π (random headings), DoS of uniform random positions at the
/// density shown.
fn chance_lines(p: &mut egui_plot::PlotUi, h: &History) {
    let dashed = LineStyle::Dashed { length: 6.0 };
    p.hline(HLine::new("chance DoA", std::f64::consts::FRAC_2_PI).color(CHANCE).style(dashed).width(1.0));
    if let Some((_, Some(dos))) = h.chance {
        p.hline(HLine::new("chance DoS", dos).color(CHANCE).style(dashed).width(1.0));
    }
}

/// The key of the chance lines, with their values.
fn chance_key(ui: &mut egui::Ui, h: &History) {
    let dos = match h.chance {
        Some((n, Some(dos))) => format!(", DoS {dos:.2} (uniform random positions, {n} at this density)"),
        _ => String::new(),
    };
    ui.label(egui::RichText::new(format!("- - chance: DoA 2/π = 0.64 (random headings){dos}")).color(CHANCE).small());
}

/// The plots, stacked, each with labelled axes and its key above it, sized to fit the window's height
/// below where they start (never under 170 px each, about 130 of them the frame: then the panel scrolls). `fast`: "as fast as
/// possible", where the step plot shows the last finished episode.
pub(crate) fn show(ui: &mut egui::Ui, h: &History, species: &str, fast: bool) {
    let plots = if h.ratings.is_some() { 4.0 } else { 3.0 };
    // Each plot's title, key and spacing take about 56 px above and below its frame.
    let below = ui.clip_rect().bottom() - ui.cursor().top();
    let height = ((below - plots * 56.0) / plots).clamp(170.0, 220.0);
    let trained = h.training.as_ref().map_or(0.0, |t| t[0].len() as f64);
    match &h.training {
        Some(t) => {
            let here = h.chance.map(|(n, _)| n);
            let density = match (h.trained_count, here) {
                (Some(a), Some(b)) if a != b => format!(
                    "; trained with {a}, watched with {b}: DoS and DoA depend on the density, so dots and curve differ also for that"
                ),
                _ => String::new(),
            };
            ui.label(format!(
                "{species}: the run's training ({} episodes of metrics.csv, exploration noise on; {RUNNING_MEAN}-episode running mean), then the episodes watched here (dots, no noise){density}",
                t[0].len()
            ));
            key(ui, &[("DoS", DOS), ("DoA", DOA), ("watched DoS", DOS), ("watched DoA", DOA)]);
        }
        None => {
            ui.label(format!("{species}: per episode (thin) and {RUNNING_MEAN}-episode running mean"));
            key(ui, &[("DoS", DOS), ("DoA", DOA)]);
        }
    }
    chance_key(ui, h);
    plot("per_episode", height, "episode", true, "DoS, DoA").include_y(0.0).include_y(1.0).show(ui, |p| {
        chance_lines(p, h);
        match &h.training {
            Some([dos, doa, _]) => {
                p.line(line("DoS", &running_mean(dos, RUNNING_MEAN), DOS, 2.0));
                p.line(line("DoA", &running_mean(doa, RUNNING_MEAN), DOA, 2.0));
                p.points(Points::new("watched DoS", after(&h.dos, trained)).color(DOS).radius(3.0));
                p.points(Points::new("watched DoA", after(&h.doa, trained)).color(DOA).radius(3.0));
            }
            None => {
                p.line(line("DoS", &h.dos, DOS.gamma_multiply(0.45), 1.0));
                p.line(line("DoA", &h.doa, DOA.gamma_multiply(0.45), 1.0));
                p.line(line("DoS mean", &running_mean(&h.dos, RUNNING_MEAN), DOS, 2.0));
                p.line(line("DoA mean", &running_mean(&h.doa, RUNNING_MEAN), DOA, 2.0));
            }
        }
    });
    let (title, steps) = match (&h.last_steps, fast) {
        (Some((episode, last)), true) => {
            (format!("episode {}, step by step (the last finished: as fast as possible)", episode + 1), last)
        }
        _ => ("this episode, step by step".to_string(), &h.steps),
    };
    ui.label(title);
    key(
        ui,
        &[
            ("DoS", DOS),
            ("DoA", DOA),
            ("polarization", POLARIZATION),
            ("milling", MILLING),
            ("largest cluster / N", CLUSTER),
            ("C_nn (local order)", C_NN),
        ],
    );
    plot("per_step", height, "step", true, "order parameter").include_y(0.0).include_y(1.0).show(ui, |p| {
        chance_lines(p, h);
        p.line(line("DoS", &steps.dos, DOS, 1.5));
        p.line(line("DoA", &steps.doa, DOA, 1.5));
        p.line(line("polarization", &steps.polarization, POLARIZATION, 1.0));
        p.line(line("milling", &steps.milling, MILLING, 1.0));
        p.line(line("largest cluster / N", &steps.largest_cluster, CLUSTER, 1.0));
        p.line(line("C_nn (local order)", &steps.nn_correlation, C_NN, 1.0));
    });
    ui.label("catches per episode");
    plot("catches", height, "episode", true, "catches").include_y(0.0).show(ui, |p| match &h.training {
        Some([_, _, catches]) => {
            p.line(line("catches (training)", &running_mean(catches, RUNNING_MEAN), CATCHES, 1.5));
            p.points(Points::new("catches (watched)", after(&h.catches, trained)).color(CATCHES).radius(3.0));
        }
        None => p.line(line("catches", &h.catches, CATCHES, 1.5)),
    });
    if let Some(ratings) = &h.ratings {
        ui.label("rating of each snapshot from the run's cross-play (log catch rate against every opponent snapshot; higher is better for both)");
        let colours = [DOS, CATCHES, POLARIZATION, MILLING];
        let entries: Vec<(&str, egui::Color32)> =
            ratings.iter().zip(colours.iter().cycle()).map(|((s, _), c)| (s.as_str(), *c)).collect();
        key(ui, &entries);
        plot("ratings", height, "snapshot (episode)", true, "rating").show(ui, |p| {
            for ((species, points), colour) in ratings.iter().zip(colours.iter().cycle()) {
                p.line(line(species, points, *colour, 1.5));
                p.points(Points::new(species.clone(), points.clone()).color(*colour).radius(2.5));
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::running_mean;

    #[test]
    fn ticks_are_round_and_far_enough_apart_to_be_labelled_at_any_size() {
        use egui_plot::GridInput;
        // Plots 120 to 1200 px long over the ranges the viewer shows: at least two labelled ticks, each
        // labelled one at least `label_px` apart, at round values.
        for (lo, hi) in [(0.0, 1.0), (-0.05, 1.05), (0.0, 60.0), (0.0, 900.0), (0.0, 2000.0), (0.0, 37.0), (3.0, 4.5)] {
            for px in [120.0, 200.0, 300.0, 600.0, 1200.0] {
                for label_px in [super::X_LABEL_PX, super::Y_LABEL_PX] {
                    if px < 2.0 * label_px {
                        continue;
                    }
                    let per_px = (hi - lo) / px;
                    for whole in [false, true] {
                        let input = GridInput { bounds: (lo, hi), base_step_size: per_px * super::GRID_MIN_PX };
                        let marks = super::ticks(label_px, whole)(input);
                        let labelled: Vec<_> = marks.iter().filter(|m| m.step_size / per_px >= label_px).collect();
                        // A whole axis shorter than two labels' spacing shows its whole units.
                        let units = (hi.floor() - lo.ceil()) as usize + 1;
                        assert!(labelled.len() >= 2.min(units), "{lo}..{hi} over {px} px: {labelled:?}");
                        for m in &labelled {
                            let mantissa = m.step_size / 10f64.powf(m.step_size.log10().floor());
                            assert!([1.0, 2.0, 2.5, 5.0].iter().any(|r| (mantissa - r).abs() < 1e-9), "{m:?}");
                            assert!((m.value / m.step_size - (m.value / m.step_size).round()).abs() < 1e-9, "{m:?}");
                            assert!(!whole || m.value.fract() == 0.0, "{m:?} on a whole axis");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn a_finished_episode_is_kept_for_the_step_plot_and_a_respawn_is_not_one() {
        let mut h = super::History::default();
        h.steps.doa = vec![[1.0, 0.7], [2.0, 0.8]];
        h.steps.dos = vec![[1.0, 0.2], [2.0, 0.2]];
        h.start_episode(Some(4));
        assert!(h.steps.doa.is_empty());
        assert_eq!(h.last_steps.as_ref().map(|(e, c)| (*e, c.doa.len())), Some((4, 2)));
        // A respawn (no episode finished) and an empty episode leave the last finished one shown.
        h.steps.doa = vec![[1.0, 0.1]];
        h.steps.dos = vec![[1.0, 0.3]];
        h.start_episode(None);
        h.start_episode(Some(5));
        assert_eq!(h.last_steps.as_ref().map(|(e, c)| (*e, c.doa.len())), Some((4, 2)));
    }

    #[test]
    fn tick_labels_show_the_decimals_a_round_step_needs() {
        let label = |value: f64| super::tick_label(egui_plot::GridMark { value, step_size: 0.25 }, &(0.0..=1.0));
        let shown: Vec<String> = [0.0, 0.25, 0.5, 1.0, -0.0, 0.30000000000000004, 1500.0, -2.5].map(label).to_vec();
        assert_eq!(shown, ["0", "0.25", "0.5", "1", "0", "0.3", "1500", "-2.5"]);
    }

    #[test]
    fn running_mean_averages_the_last_window() {
        let pts: Vec<[f64; 2]> = (0..5).map(|i| [i as f64, i as f64]).collect();
        let m = running_mean(&pts, 2);
        assert_eq!(m.iter().map(|p| p[1]).collect::<Vec<_>>(), vec![0.0, 0.5, 1.5, 2.5, 3.5]);
    }

    #[test]
    fn a_watched_run_shows_its_training_curves_from_its_metrics() {
        let dir = tempfile::tempdir().unwrap();
        let mut scene = crate::scene::Scene::preset("paper").unwrap();
        scene.episode_steps = 20;
        let run = dir.path().join("run");
        crate::run::train::train(scene, &crate::run::train::TrainOptions::new(run.clone(), Some(3))).unwrap();
        let [dos, doa, catches] = super::training_curves(&run, "prey").expect("curves from metrics.csv");
        let table = crate::store::schema::Table::read(&crate::store::RunDir::new(&run).metrics()).unwrap();
        let values = |c: &[[f64; 2]]| c.iter().map(|p| p[1]).collect::<Vec<_>>();
        assert_eq!(dos.iter().map(|p| p[0]).collect::<Vec<_>>(), vec![0.0, 1.0, 2.0]);
        assert_eq!(values(&dos), table.column("dos_prey").unwrap());
        assert_eq!(values(&doa), table.column("doa_prey").unwrap());
        assert_eq!(values(&catches), table.column("catches").unwrap());
        // A run folder without metrics (the shipped actors) has none: the plot shows the watched episodes.
        std::fs::remove_file(crate::store::RunDir::new(&run).metrics()).unwrap();
        assert!(super::training_curves(&run, "prey").is_none());
    }
}
