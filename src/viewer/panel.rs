//! The egui panels. Left: mode, scene and run pickers, play / pause / step and speed, population, the
//! key parameters (applied on reset), overlays, status and errors. Right: the selected agent's
//! observation vector, action and reward, and the live plots.
//!
//! The panels only write requests ([`Control`], [`Playback`], [`Overlays`]); the next frame's
//! `ViewerSet::Control` carries them out, so a bad scene or checkpoint is refused there and the
//! running world is left as it was.

use super::capture::ScreenshotQueue;
use super::draw::{species_colour, Overlays, PanelSpace, Selection};
use super::plots::{self, History};
use super::setup::{run_folders, scene_files, Control, Playback, RunMode, Setup};
use crate::learning::Learners;
use crate::scene::{Boundary, Perception, Scene, PRESETS};
use crate::sim::clock::Episode;
use crate::sim::components::{Action, AgentId, Contacts, Heading, Position, Reward, Slot, SpeciesId, Velocity};
use crate::sim::perception::{neighbour_slot, Batches};
use crate::sim::species::SpeciesRegistry;
use bevy::ecs::system::SystemParam;
use bevy::prelude::*;
use bevy_egui::{egui, EguiContexts, EguiPrimaryContextPass};
use std::path::{Path, PathBuf};

pub(crate) struct PanelPlugin;

impl Plugin for PanelPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<Draft>().add_systems(EguiPrimaryContextPass, (controls, inspector).chain());
    }
}

/// The parameters being edited, applied to the world on reset.
#[derive(Resource, Default)]
struct Draft(Option<Scene>);

/// Panels live in a root `Ui` over the whole window, as in bevy_egui's side-panel example.
fn root_ui(ctx: &egui::Context, id: &'static str) -> egui::Ui {
    egui::Ui::new(
        ctx.clone(),
        id.into(),
        egui::UiBuilder::new().layer_id(egui::LayerId::background()).max_rect(ctx.viewport_rect()),
    )
}

/// What the status lines show.
#[derive(SystemParam)]
struct Status<'w> {
    episode: Res<'w, Episode>,
    registry: Res<'w, SpeciesRegistry>,
    learners: Res<'w, Learners>,
    time: Res<'w, Time<Real>>,
    live: Option<Res<'w, crate::run::live::LiveRun>>,
}

fn controls(
    mut contexts: EguiContexts,
    mut control: ResMut<Control>,
    mut playback: ResMut<Playback>,
    mut overlays: ResMut<Overlays>,
    mut space: ResMut<PanelSpace>,
    mut draft: ResMut<Draft>,
    mut shots: ResMut<ScreenshotQueue>,
    world: Status,
) -> Result {
    let ctx = contexts.ctx_mut()?;
    let mut root = root_ui(ctx, "controls_root");
    let c = &mut *control;
    let draft = draft.0.get_or_insert_with(|| c.current.scene.clone());
    let width = egui::Panel::left("controls")
        .resizable(true)
        .default_size(290.0)
        .show(&mut root, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| {
                ui.heading("coevo");
                if let Some(error) = &c.error {
                    ui.colored_label(egui::Color32::from_rgb(230, 80, 70), error);
                }
                status(ui, c, &playback, &world);
                if let Some(live) = &world.live {
                    ui.separator();
                    save_run(ui, c, live, &world.episode);
                }
                ui.separator();
                mode_and_files(ui, c, draft);
                ui.separator();
                playback_controls(ui, &mut playback);
                ui.separator();
                population(ui, c, &world.registry);
                ui.separator();
                parameters(ui, c, draft);
                ui.separator();
                ui.label("Overlays");
                ui.checkbox(&mut overlays.trails, "trails");
                ui.add_enabled(
                    overlays.trails,
                    egui::Slider::new(&mut overlays.trail_length, 2..=400).text("trail steps"),
                );
                ui.checkbox(&mut overlays.catches, "highlight catches");
                ui.checkbox(&mut overlays.perception, "perception of the selected agent");
                ui.horizontal(|ui| {
                    ui.checkbox(&mut overlays.rule, "its rule: turn with one more")
                        .on_hover_text("red: it would turn left, blue: right, with one more agent of this species there (its response field amid what it sees now)");
                    let names: Vec<String> = world.registry.defs.iter().map(|d| d.name.clone()).collect();
                    let shown = names.get(overlays.rule_of).cloned().unwrap_or_default();
                    egui::ComboBox::from_id_salt("rule of").selected_text(shown).show_ui(ui, |ui| {
                        for (t, name) in names.iter().enumerate() {
                            ui.selectable_value(&mut overlays.rule_of, t, name);
                        }
                    });
                });
                if ui.button("Screenshot (F12)").clicked() {
                    shots.0.push(super::capture::timestamped_path());
                }
            });
        })
        .response
        .rect
        .width();
    space.left = width;
    Ok(())
}

fn status(ui: &mut egui::Ui, c: &Control, playback: &Playback, w: &Status) {
    ui.label(format!(
        "{}  ·  {}{}",
        c.current.source.display(),
        c.current.mode.label(),
        crate::run::evaluate::snapshots_shown(&c.current.snapshots)
    ));
    ui.label(format!(
        "episode {}  ·  step {} / {}  ·  {} agents",
        w.episode.index,
        w.episode.step,
        w.episode.length,
        w.registry.defs.iter().map(|d| d.count).sum::<usize>()
    ));
    let fps = 1.0 / w.time.delta_secs_f64().max(1e-6);
    ui.label(format!(
        "{:.0} steps/s  ·  {fps:.0} fps  ·  {} steps run",
        playback.steps_per_second, playback.total_steps
    ));
    for (s, l) in w.learners.species.iter().enumerate() {
        if let Some(l) = l {
            let what = if l.frozen {
                "frozen (its trained actor acts, without noise; nothing learns)".to_string()
            } else {
                format!("learning: σ {:.3}, ε {:.3}, {} transitions", l.noise_std, l.epsilon, l.buffer.len)
            };
            ui.label(format!("{}: {what}", w.registry.defs[s].name));
        }
    }
}

/// Live training as a run folder: saved when the current episode ends, never over an existing folder.
fn save_run(ui: &mut egui::Ui, c: &mut Control, live: &crate::run::live::LiveRun, episode: &Episode) {
    // `--save-run`: the folder the run is kept in, and how far it goes now (it grows every episode).
    let kept = c.keep_in.clone().filter(|_| c.keeping);
    if let Some(dir) = &kept {
        ui.label(format!(
            "kept in {}: {} episodes written, the last checkpoint after episode {} (--resume continues from it)",
            dir.display(),
            live.episodes(),
            live.checkpointed()
        ));
    }
    ui.label(if kept.is_some() { "Save a copy" } else { "Save this run" });
    if let Some(why) = &live.altered {
        ui.label(format!("not savable: {why} (restart to train a savable run)"));
        return;
    }
    ui.horizontal(|ui| {
        ui.label("into");
        ui.text_edit_singleline(&mut c.save_folder);
    });
    let into_kept = kept.as_ref().is_some_and(|dir| Path::new(c.save_folder.trim()) == dir.as_path());
    match &c.save_pending {
        Some(dir) => {
            ui.label(format!("saving into {} when episode {} ends…", dir.display(), episode.index));
            if ui.button("cancel").clicked() {
                c.save_pending = None;
            }
        }
        None => {
            let button = ui.add_enabled(!into_kept, egui::Button::new("Save at the end of this episode"));
            if into_kept {
                button.on_disabled_hover_text("the run is kept there already; name another folder for a copy");
            } else if button.clicked() {
                c.save_pending = Some(PathBuf::from(c.save_folder.trim()));
                c.notice = None;
            }
        }
    }
    // What the last save (a copy) wrote; the kept folder's line above says how far that one goes now.
    if let Some(notice) = &c.notice {
        ui.colored_label(egui::Color32::from_rgb(60, 150, 80), notice);
    }
}

/// Restarts in `mode`; the snapshots chosen stay while the same run is watched.
fn restart_as(c: &mut Control, scene: Scene, source: PathBuf, mode: RunMode) {
    let snapshots = if mode == c.current.mode { c.current.snapshots.clone() } else { vec![] };
    c.restart = Some(Setup { scene, source, mode, snapshots });
}

/// While watching a run: which actor each learning species deploys, its trained one or one of its
/// snapshots (the arms race seen, not only plotted in cross-play).
fn snapshot_picker(ui: &mut egui::Ui, c: &mut Control) {
    let RunMode::Watch(run) = c.current.mode.clone() else { return };
    for def in c.current.scene.species.iter().filter(|d| d.policy == crate::scene::Policy::Learned) {
        let kept = crate::store::snapshots::snapshot_episodes(&run, &def.name);
        if kept.is_empty() {
            continue;
        }
        let chosen = c.current.snapshots.iter().find(|(s, _)| s == &def.name).map(|(_, e)| *e);
        let shown =
            |e: Option<usize>| e.map_or("trained (last checkpoint)".to_string(), |e| format!("after {e} episodes"));
        let mut pick = None;
        egui::ComboBox::from_label(format!("{} actor", def.name)).selected_text(shown(chosen)).show_ui(ui, |ui| {
            for e in std::iter::once(None).chain(kept.iter().copied().map(Some)) {
                if ui.selectable_label(e == chosen, shown(e)).clicked() && e != chosen {
                    pick = Some(e);
                }
            }
        });
        if let Some(e) = pick {
            let mut snapshots: Vec<(String, usize)> =
                c.current.snapshots.iter().filter(|(s, _)| s != &def.name).cloned().collect();
            snapshots.extend(e.map(|e| (def.name.clone(), e)));
            c.restart = Some(Setup { snapshots, ..c.current.clone() });
            return;
        }
    }
}

fn mode_and_files(ui: &mut egui::Ui, c: &mut Control, draft: &mut Scene) {
    ui.label("Mode");
    ui.horizontal(|ui| {
        let watching = matches!(c.current.mode, RunMode::Watch(_));
        for (mode, label) in [(RunMode::LiveTraining, "live training"), (RunMode::RuleBased, "rule-based")] {
            if ui.selectable_label(c.current.mode == mode, label).clicked() && c.current.mode != mode {
                restart_as(c, c.current.scene.clone(), c.current.source.clone(), mode);
            }
        }
        let _ = ui.selectable_label(watching, "watch a run");
    });
    let runs = run_folders();
    egui::ComboBox::from_label("run")
        .selected_text(match &c.current.mode {
            RunMode::Watch(run) => file_name(run),
            _ => {
                if runs.is_empty() {
                    "no runs/ yet".into()
                } else {
                    "choose…".into()
                }
            }
        })
        .show_ui(ui, |ui| {
            for run in &runs {
                if ui.selectable_label(false, file_name(run)).clicked() {
                    let path = crate::store::RunDir::new(run).scene();
                    match Scene::load(&path) {
                        Ok(scene) => {
                            *draft = scene.clone();
                            restart_as(c, scene, path, RunMode::Watch(run.clone()));
                        }
                        Err(e) => c.error = Some(e.to_string()),
                    }
                }
            }
        });
    snapshot_picker(ui, c);
    ui.horizontal(|ui| {
        egui::ComboBox::from_label("scene").selected_text(file_name(&c.current.source)).show_ui(ui, |ui| {
            for path in scene_files() {
                if ui.selectable_label(path == c.current.source, file_name(&path)).clicked() {
                    load_scene(c, draft, &path);
                }
            }
        });
        if ui.button("reload").on_hover_text("read the scene file again and restart").clicked() {
            let path = c.current.source.clone();
            load_scene(c, draft, &path);
        }
    });
}

/// A scene file, restarted in the current mode (watching a run loads its actors into the new scene,
/// which refuses them if they do not fit). A file that fails to load leaves the world running.
fn load_scene(c: &mut Control, draft: &mut Scene, path: &Path) {
    match Scene::load(path) {
        Ok(scene) => {
            *draft = scene.clone();
            restart_as(c, scene, path.to_path_buf(), c.current.mode.clone());
        }
        Err(e) => c.error = Some(e.to_string()),
    }
}

fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned())
}

fn playback_controls(ui: &mut egui::Ui, p: &mut Playback) {
    ui.horizontal(|ui| {
        let label = if p.playing { "⏸ pause" } else { "▶ play" };
        if ui.button(label).clicked() {
            p.playing = !p.playing;
        }
        if ui.add_enabled(!p.playing, egui::Button::new("step")).clicked() {
            p.step_once = true;
        }
    });
    ui.checkbox(&mut p.as_fast_as_possible, "as fast as possible");
    ui.add_enabled(
        !p.as_fast_as_possible,
        egui::Slider::new(&mut p.steps_per_frame, 1..=500).logarithmic(true).text("steps / frame"),
    );
}

fn population(ui: &mut egui::Ui, c: &mut Control, registry: &SpeciesRegistry) {
    ui.label("Population (respawns, keeps the networks)");
    let mut counts: Vec<usize> = registry.defs.iter().map(|d| d.count).collect();
    let mut apply = false;
    for (def, n) in registry.defs.iter().zip(counts.iter_mut()) {
        let r = ui.add(
            egui::Slider::new(n, 0..=2000)
                .logarithmic(true)
                .text(&def.name)
                .text_color(to_egui(species_colour(def.colour))),
        );
        apply |= r.drag_stopped() || (r.changed() && !r.dragged());
    }
    if apply {
        c.respawn = Some(counts);
    }
}

fn to_egui(c: Color) -> egui::Color32 {
    let s = c.to_srgba();
    egui::Color32::from_rgb((s.red * 255.0) as u8, (s.green * 255.0) as u8, (s.blue * 255.0) as u8)
}

fn parameters(ui: &mut egui::Ui, c: &mut Control, draft: &mut Scene) {
    ui.label("Parameters (applied on reset)");
    egui::ComboBox::from_label("preset").selected_text(draft.preset.clone()).show_ui(ui, |ui| {
        for name in PRESETS {
            if ui.selectable_label(draft.preset == name, name).clicked() {
                // A preset's values, with this scene's seed and populations.
                let mut fresh = Scene::preset(name).expect("listed presets exist");
                fresh.seed = draft.seed;
                for s in &mut fresh.species {
                    if let Some(old) = draft.species.iter().find(|o| o.name == s.name) {
                        s.count = old.count;
                        s.policy = old.policy.clone();
                    }
                }
                *draft = fresh;
            }
        }
    });
    ui.horizontal(|ui| {
        ui.label("boundary");
        ui.selectable_value(&mut draft.world.boundary, Boundary::Periodic, "periodic");
        ui.selectable_value(&mut draft.world.boundary, Boundary::Walls, "walls");
    });
    let registry = SpeciesRegistry::from_scene(draft);
    let prey = registry.headline();
    if let Some(predator) = registry.predators_of(prey).next() {
        let v_predator = draft.species[predator].max_speed;
        let mut ratio = draft.species[prey].max_speed / v_predator;
        if ui
            .add(
                egui::Slider::new(&mut ratio, 0.1..=3.0)
                    .text(format!("speed ratio {}/{}", draft.species[prey].name, draft.species[predator].name)),
            )
            .changed()
        {
            draft.species[prey].max_speed = ratio * v_predator;
        }
    }
    let d = draft.max_distance();
    for s in &mut draft.species {
        let mut fraction = match s.perception {
            Perception::Full => 1.0,
            Perception::FractionOfD(f) => f,
            Perception::Radius(r) => r / d,
        };
        if ui.add(egui::Slider::new(&mut fraction, 0.02..=1.0).text(format!("{} perception R / D", s.name))).changed() {
            s.perception = if fraction >= 1.0 { Perception::Full } else { Perception::FractionOfD(fraction) };
        }
    }
    ui.add(egui::Slider::new(&mut draft.rewards.wall_penalty, 0.0..=1.0).text("wall penalty"));
    ui.horizontal(|ui| {
        ui.label("seed");
        ui.add(egui::DragValue::new(&mut draft.seed));
    });
    ui.horizontal(|ui| {
        if ui.button("reset with these").clicked() {
            restart_as(c, draft.clone(), c.current.source.clone(), c.current.mode.clone());
        }
        if ui.button("revert").clicked() {
            *draft = c.current.scene.clone();
        }
    });
}

/// The inspector keeps one width, so the arena does not move as its contents change.
const INSPECTOR_WIDTH: f32 = 370.0;

type Inspected<'w, 's> = Query<
    'w,
    's,
    (
        &'static AgentId,
        &'static SpeciesId,
        &'static Position,
        &'static Velocity,
        &'static Heading,
        &'static Action,
        &'static Reward,
        &'static Contacts,
        &'static Slot,
    ),
>;

fn inspector(
    mut contexts: EguiContexts,
    mut space: ResMut<PanelSpace>,
    selection: Res<Selection>,
    agents: Inspected,
    registry: Res<SpeciesRegistry>,
    batches: Res<Batches>,
    history: Res<History>,
    scene: Res<crate::sim::ActiveScene>,
    playback: Res<Playback>,
) -> Result {
    let ctx = contexts.ctx_mut()?;
    let mut root = root_ui(ctx, "inspector_root");
    let width = egui::Panel::right("inspector")
        .resizable(false)
        .exact_size(INSPECTOR_WIDTH)
        .show(&mut root, |ui| {
            // One scroll for the whole panel: with an agent selected, its observation table and the plots
            // keep their sizes and the panel scrolls, rather than squeezing the plots.
            egui::ScrollArea::vertical().id_salt("inspector_scroll").show(ui, |ui| {
                ui.heading("Selected agent");
                let found = selection.0.and_then(|id| agents.iter().find(|a| *a.0 == id));
                match found {
                    None => {
                        ui.label("Click an agent to see its observation, action and reward.");
                    }
                    Some(a) => agent_details(ui, a, &registry, &batches, scene.0.observation_frame),
                }
                ui.separator();
                ui.heading("Swarming");
                let prey = registry.headline();
                let name = registry.defs.get(prey).map_or("", |d| d.name.as_str());
                plots::show(ui, &history, name, playback.as_fast_as_possible);
            });
        })
        .response
        .rect
        .width();
    space.right = width;
    Ok(())
}

type AgentRow<'a> = (
    &'a AgentId,
    &'a SpeciesId,
    &'a Position,
    &'a Velocity,
    &'a Heading,
    &'a Action,
    &'a Reward,
    &'a Contacts,
    &'a Slot,
);

fn agent_details(
    ui: &mut egui::Ui,
    a: AgentRow,
    registry: &SpeciesRegistry,
    batches: &Batches,
    frame: crate::scene::ObservationFrame,
) {
    let (id, s, x, v, h, action, reward, contacts, slot) = a;
    let def = &registry.defs[s.0];
    ui.label(format!(
        "{} #{}  ·  x ({:.3}, {:.3})  ·  |v| {:.3} m/s  ·  θ {:.2} rad",
        def.name,
        id.0,
        x.0.x,
        x.0.y,
        v.0.length(),
        h.0
    ));
    ui.label(format!("action: thrust a_F {:.3} N, turn rate a_R {:+.3} rad/s", action.thrust, action.turn_rate));
    ui.label(format!(
        "reward of the last step {:+.4}  ·  contacts: catching {}, caught {}, walls {}",
        reward.0, contacts.now.catching, contacts.now.caught, contacts.now.walls
    ));
    let r = registry.perception_radius[s.0];
    // Each observed species' slots, and its field of view where it is less than all around.
    let slots: Vec<String> = (0..registry.len())
        .map(|t| {
            let view = registry.field_of_view(s.0, t).map_or(String::new(), |degrees| format!(" (in {degrees:.0}°)"));
            format!("{} {}{view}", registry.slots(s.0, t), registry.defs[t].name)
        })
        .collect();
    ui.label(format!("perception radius R = {r:.3} m, observes at most {}", slots.join(", ")));
    let Some(batch) = batches.species.get(s.0).filter(|b| (slot.row as usize) < b.n) else { return };
    let obs = batch.observation(slot.row as usize);
    let own = |i: usize| format!("({:+.3}, {:+.3})", obs[i], obs[i + 1]);
    let layout = &registry.layouts[s.0];
    let body = frame == crate::scene::ObservationFrame::Body;
    if body {
        ui.label(format!(
            "observation (body frame: ahead, left), {} numbers; own: v {}, turn {:+.3}, nearest wall {}",
            obs.len(),
            own(0),
            obs[2],
            own(3)
        ));
    } else if let Some(e) = layout.energy() {
        let h = layout.heading().start;
        ui.label(format!(
            "observation (the authors' order), {} numbers; own state: x {}, v {}, energy input {:+.3}, h {}",
            obs.len(),
            own(0),
            own(2),
            obs[e],
            own(h)
        ));
    } else {
        ui.label(format!("observation, {} numbers; own state: x {}, v {}, h {}", obs.len(), own(0), own(2), own(4)));
    }
    let headers = if body {
        ["neighbour", "Δ ahead", "Δ left", "Δh ahead", "Δh left"]
    } else {
        ["neighbour", "Δx", "Δy", "Δh_x", "Δh_y"]
    };
    egui::Grid::new("obs").striped(true).num_columns(5).show(ui, |ui| {
        for header in headers {
            ui.strong(header);
        }
        ui.end_row();
        for t in 0..registry.len() {
            for n in 0..registry.slots(s.0, t) {
                ui.label(format!("{} {}", registry.defs[t].name, n + 1));
                match neighbour_slot(obs, registry, s.0, t, n) {
                    Some(slot) => slot.iter().for_each(|v| {
                        ui.monospace(format!("{v:+.3}"));
                    }),
                    None => {
                        ui.label("empty");
                    }
                }
                ui.end_row();
            }
        }
    });
}
