//! What a costly call says before it starts, and its progress bar (robustness III: no silent hour).

/// Above this many estimated seconds per step a mode says what it is about to cost and shows progress.
const COSTLY_STEP_SECONDS: f64 = 0.5;

fn costly(scene: &crate::scene::Scene) -> bool {
    scene.estimated_step_seconds() >= COSTLY_STEP_SECONDS
}

/// Before `steps` steps of `scene` (and before its population is spawned, which costs a step):
/// where a step is estimated to cost more than half a second
/// ([`crate::scene::Scene::estimated_step_seconds`]), says so on stderr with the estimate for the
/// whole call.
pub fn announce_cost(scene: &crate::scene::Scene, steps: usize) -> crate::error::Result<()> {
    if !costly(scene) {
        return Ok(());
    }
    let (agents, per_step) = (scene.agents(), scene.estimated_step_seconds());
    let total = per_step * steps as f64;
    let shown = |s: f64| match s {
        s if s < 120.0 => format!("{s:.0} s"),
        s if s < 7200.0 => format!("{:.0} min", s / 60.0),
        s => format!("{:.1} h", s / 3600.0),
    };
    crate::errln!(
        "coevo: {agents} agents with ~{:.0} bodies within contact reach of each ({} m arena): about {} a step, {} for {steps} steps (an estimate); Ctrl-C stops it",
        scene.bodies_within_reach(),
        scene.world.arena_edge,
        shown(per_step),
        shown(total)
    )
}

/// A progress bar over `steps` steps where a step of `scene` is costly ([`announce_cost`]), a hidden
/// one otherwise.
pub fn step_bar(scene: &crate::scene::Scene, steps: usize) -> indicatif::ProgressBar {
    if !costly(scene) {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(steps as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:30} {pos}/{len} steps  {elapsed} elapsed, ETA {eta}")
            .expect("valid template"),
    );
    bar
}
