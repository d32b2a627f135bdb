//! Live plots (egui_plot): DoS and DoA per episode with their 100-episode running means, DoS, DoA,
//! polarization, milling, largest cluster and nearest-neighbour heading correlation step by step within the current episode, and catches per episode, for the
//! headline species (the prey).

use crate::sim::clock::Episode;
use crate::sim::metrics::{EpisodeLog, SwarmMetrics};
use crate::sim::species::SpeciesRegistry;
use bevy::prelude::*;
use bevy_egui::egui;
use egui_plot::{Line, Plot, PlotPoints, Points};

/// The paper's smoothing window for learning curves (Fig. 3: running mean over 100 episodes).
const RUNNING_MEAN: usize = 100;

/// What the plots show, collected after every step.
#[derive(Resource, Default, Debug)]
pub struct History {
    /// Per finished episode: [episode, DoS], [episode, DoA], [episode, catches].
    pub dos: Vec<[f64; 2]>,
    pub doa: Vec<[f64; 2]>,
    pub catches: Vec<[f64; 2]>,
    /// Within the current episode: [step, value].
    pub step_dos: Vec<[f64; 2]>,
    pub step_doa: Vec<[f64; 2]>,
    pub step_polarization: Vec<[f64; 2]>,
    pub step_milling: Vec<[f64; 2]>,
    pub step_largest_cluster: Vec<[f64; 2]>,
    pub step_nn_correlation: Vec<[f64; 2]>,
    /// Watching a run: its training curves from its `metrics.csv` ([episode, value] for DoS, DoA,
    /// catches), shown before the episodes watched here.
    pub training: Option<[Vec<[f64; 2]>; 3]>,
    /// Watching a run that was cross-played: every snapshot's rating per species ([episode, rating],
    /// `crossplay-ratings.csv`), the arms race over training.
    pub ratings: Option<Vec<(String, Vec<[f64; 2]>)>>,
}

impl History {
    pub fn clear(&mut self) {
        *self = History::default();
    }

    pub fn start_episode(&mut self) {
        self.step_dos.clear();
        self.step_doa.clear();
        self.step_polarization.clear();
        self.step_milling.clear();
        self.step_largest_cluster.clear();
        self.step_nn_correlation.clear();
    }
}

pub struct PlotsPlugin;

impl Plugin for PlotsPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<History>();
    }
}

/// After a step: the step's DoS/DoA, and any episode that just ended.
pub fn record_step(world: &mut World) {
    let prey = world.resource::<SpeciesRegistry>().headline();
    let ended = std::mem::take(&mut world.resource_mut::<EpisodeLog>().episodes);
    let step = world.resource::<Episode>().step as f64;
    let now = world.resource::<SwarmMetrics>().now.get(prey).copied().flatten();
    let mut h = world.resource_mut::<History>();
    for e in &ended {
        let x = e.episode as f64;
        if let Some(s) = e.swarming.get(prey).copied().flatten() {
            h.dos.push([x, s.dos]);
            h.doa.push([x, s.doa]);
        }
        h.catches.push([x, e.catches as f64]);
    }
    if !ended.is_empty() {
        h.start_episode();
    }
    if let Some(s) = now {
        h.step_dos.push([step, s.dos]);
        h.step_doa.push([step, s.doa]);
        h.step_polarization.push([step, s.polarization]);
        h.step_milling.push([step, s.milling]);
        h.step_largest_cluster.push([step, s.largest_cluster]);
        h.step_nn_correlation.push([step, s.nn_correlation]);
    }
}

/// Running mean over the last `window` points (fewer at the start).
pub fn running_mean(points: &[[f64; 2]], window: usize) -> Vec<[f64; 2]> {
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
pub fn training_curves(run: &std::path::Path, species: &str) -> Option<[Vec<[f64; 2]>; 3]> {
    use crate::run::schema::{self, Table};
    let table = Table::read(&crate::run::RunDir::new(run).metrics()).ok()?;
    let column = |name: &str| -> Option<Vec<[f64; 2]>> {
        Some(table.column(name).ok()?.into_iter().enumerate().map(|(e, v)| [e as f64, v]).collect())
    };
    let curves = [column(&schema::of("dos", species))?, column(&schema::of("doa", species))?, column(schema::CATCHES)?];
    (!curves[0].is_empty()).then_some(curves)
}

/// The episodes watched here, placed after the run's training episodes on the same axis.
fn after(points: &[[f64; 2]], offset: f64) -> Vec<[f64; 2]> {
    points.iter().map(|p| [p[0] + offset, p[1]]).collect()
}

/// The three plots, stacked, each with labelled axes and its key above it.
pub fn show(ui: &mut egui::Ui, h: &History, species: &str) {
    // From the window's height, not the space left: the panel scrolls, so the plots never shrink to a strip.
    let height = ((ui.ctx().viewport_rect().height() - 120.0) / 3.0).clamp(140.0, 220.0);
    let trained = h.training.as_ref().map_or(0.0, |t| t[0].len() as f64);
    match &h.training {
        Some(t) => {
            ui.label(format!(
                "{species}: the run's training ({} episodes of metrics.csv, exploration noise on; {RUNNING_MEAN}-episode running mean), then the episodes watched here (dots, no noise)",
                t[0].len()
            ));
            key(ui, &[("DoS", DOS), ("DoA", DOA), ("watched DoS", DOS), ("watched DoA", DOA)]);
        }
        None => {
            ui.label(format!("{species}: per episode (thin) and {RUNNING_MEAN}-episode running mean"));
            key(ui, &[("DoS", DOS), ("DoA", DOA)]);
        }
    }
    Plot::new("per_episode")
        .height(height)
        .x_axis_label("episode")
        .y_axis_label("DoS, DoA")
        .include_y(0.0)
        .include_y(1.0)
        .show(ui, |p| match &h.training {
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
        });
    ui.label("this episode, step by step");
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
    Plot::new("per_step")
        .height(height)
        .x_axis_label("step")
        .y_axis_label("order parameter")
        .include_y(0.0)
        .include_y(1.0)
        .show(ui, |p| {
            p.line(line("DoS", &h.step_dos, DOS, 1.5));
            p.line(line("DoA", &h.step_doa, DOA, 1.5));
            p.line(line("polarization", &h.step_polarization, POLARIZATION, 1.0));
            p.line(line("milling", &h.step_milling, MILLING, 1.0));
            p.line(line("largest cluster / N", &h.step_largest_cluster, CLUSTER, 1.0));
            p.line(line("C_nn (local order)", &h.step_nn_correlation, C_NN, 1.0));
        });
    ui.label("catches per episode");
    Plot::new("catches").height(height).x_axis_label("episode").y_axis_label("catches").include_y(0.0).show(ui, |p| {
        match &h.training {
            Some([_, _, catches]) => {
                p.line(line("catches (training)", &running_mean(catches, RUNNING_MEAN), CATCHES, 1.5));
                p.points(Points::new("catches (watched)", after(&h.catches, trained)).color(CATCHES).radius(3.0));
            }
            None => p.line(line("catches", &h.catches, CATCHES, 1.5)),
        }
    });
    if let Some(ratings) = &h.ratings {
        ui.label("rating of each snapshot from the run's cross-play (log catch rate against every opponent snapshot; higher is better for both)");
        let colours = [DOS, CATCHES, POLARIZATION, MILLING];
        let entries: Vec<(&str, egui::Color32)> =
            ratings.iter().zip(colours.iter().cycle()).map(|((s, _), c)| (s.as_str(), *c)).collect();
        key(ui, &entries);
        Plot::new("ratings").height(height).x_axis_label("snapshot (episode)").y_axis_label("rating").show(ui, |p| {
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
        let table = crate::run::schema::Table::read(&crate::run::RunDir::new(&run).metrics()).unwrap();
        let values = |c: &[[f64; 2]]| c.iter().map(|p| p[1]).collect::<Vec<_>>();
        assert_eq!(dos.iter().map(|p| p[0]).collect::<Vec<_>>(), vec![0.0, 1.0, 2.0]);
        assert_eq!(values(&dos), table.column("dos_prey").unwrap());
        assert_eq!(values(&doa), table.column("doa_prey").unwrap());
        assert_eq!(values(&catches), table.column("catches").unwrap());
        // A run folder without metrics (the shipped actors) has none: the plot shows the watched episodes.
        std::fs::remove_file(crate::run::RunDir::new(&run).metrics()).unwrap();
        assert!(super::training_curves(&run, "prey").is_none());
    }
}
