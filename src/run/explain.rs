//! What a finished `--train` or `--resume` says about its run, on stdout: first → last DoS, DoA and
//! catches beside their values without swarming, where each running mean peaked and how far it fell
//! back, how far seeds of the scene differ, and the next commands for that run, spelled as they run where
//! the user is.

use crate::scene::Scene;
use crate::sim::species::SpeciesRegistry;
use crate::store::folder::RunDir;
use crate::store::schema;
use std::path::Path;

/// The command that opens the viewer on run `r`, as it runs where the user is: this executable when it
/// was built with the window; in a clone (a `Cargo.toml` here), the build that adds it; else what it
/// takes, in words (only the source builds the window, and its folder is the user's to name).
fn watch(r: &str, coevo: &str) -> String {
    if cfg!(feature = "viewer") {
        format!("{coevo} --watch {r}")
    } else if Path::new("Cargo.toml").is_file() {
        format!("cargo run --release --features viewer -- --watch {r}")
    } else {
        format!("{coevo} --watch {r}, with a coevo built with the window (--features viewer, from its source)")
    }
}

/// One plain sentence on the course of a quantity's 100-episode running mean over training: where it
/// peaked (the highest, or with `highest` false the lowest, full window) and how far it moved back by the
/// last episode, or that the extreme is at the end.
fn course(what: &str, values: &[f64], highest: bool, digits: usize) -> String {
    use crate::sim::metrics::WINDOW;
    let rm = crate::sim::metrics::running_mean(values, WINDOW);
    let full: Vec<(usize, f64)> =
        rm.iter().copied().enumerate().skip(WINDOW - 1).filter(|(_, x)| x.is_finite()).collect();
    let pick = |a: &&(usize, f64), b: &&(usize, f64)| if highest { a.1.total_cmp(&b.1) } else { b.1.total_cmp(&a.1) };
    let (Some(&(at, extreme)), Some(&(_, last))) = (full.iter().max_by(pick), full.last()) else {
        return String::new();
    };
    let (word, moved) = if highest { ("highest", "fell") } else { ("lowest", "rose") };
    let (from, to) = (at + 2 - WINDOW, at + 1);
    if to + WINDOW / 2 >= values.len() {
        format!("  {what}: its 100-episode mean is {word} near the end ({extreme:.digits$}, episodes {from}–{to})\n")
    } else {
        format!(
            "  {what}: its 100-episode mean was {word} in episodes {from}–{to} ({extreme:.digits$}), then {moved} by {:.digits$} to {last:.digits$}\n",
            (extreme - last).abs()
        )
    }
}

/// What a finished `--train` says about its run: first → last DoS, DoA and catches with the baselines of
/// no swarming at that density, overlapping windows named as such, and the next commands for this run.
pub(crate) fn explain(run: &Path, spread: Option<&str>) -> crate::error::Result<String> {
    use crate::sim::metrics::WINDOW;
    let dir = RunDir::new(run);
    let scene = Scene::load(&dir.scene())?;
    let registry = SpeciesRegistry::from_scene(&scene);
    let prey = registry.headline();
    let name = &registry.defs[prey].name;
    let table = schema::Table::read(&dir.metrics())?;
    let (dos, doa, catches) = (
        table.column(&schema::of("dos", name))?,
        table.column(&schema::of("doa", name))?,
        table.column(schema::CATCHES)?,
    );
    let n = dos.len();
    let window = WINDOW.min(n);
    let mean = |v: &[f64]| {
        let finite: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
        (!finite.is_empty()).then(|| finite.iter().sum::<f64>() / finite.len() as f64)
    };
    let span = |v: &[f64]| (mean(&v[..window]), mean(&v[n - window..]));
    let shown = |x: Option<f64>, digits: usize| x.map_or("–".to_string(), |x| format!("{x:.digits$}"));
    let arena = crate::sim::space::Arena { edge: scene.world.arena_edge, boundary: scene.world.boundary };
    let count = registry.defs[prey].count;
    let mut out = String::new();
    let line = |out: &mut String, what: &str, (a, b): (Option<f64>, Option<f64>), digits: usize, baseline: String| {
        out.push_str(&format!("  {what:<22} {} → {}{baseline}\n", shown(a, digits), shown(b, digits)));
    };
    out.push_str(&format!("  {name}, mean of the first → last {window} of {n} episodes (exploration noise on):\n"));
    let random = crate::sim::metrics::random_dos(&arena, count)
        .map_or(String::new(), |r| format!("   (random positions, {count} {name}: {r:.3})"));
    line(&mut out, "DoS", span(&dos), 3, random);
    line(&mut out, "DoA", span(&doa), 3, "   (random headings: 2/π = 0.637)".into());
    line(&mut out, "catches per episode", span(&catches), 1, String::new());
    if n < 2 * WINDOW {
        out.push_str(&format!(
            "  the two windows overlap ({} of {n} episodes are in both): not a change over training; train at least {} episodes for one\n",
            2 * window - n.min(2 * window),
            2 * WINDOW
        ));
    }
    if n >= 2 * WINDOW {
        out.push_str(&course("DoA", &doa, true, 3));
        out.push_str(&course("DoS", &dos, false, 3));
        out.push_str(&course("catches per episode", &catches, true, 1));
    }
    out.push_str("  one run is one sample: seeds of the same scene differ widely; compare seeds with an experiment file (the book's experiments guide, docs/src/guide/experiments.md in coevo's source)\n");
    out.push_str(spread.unwrap_or_default());
    let r = run.display();
    // Each next command with what it does, the comments in one column, coevo spelled as it runs here.
    let coevo = crate::store::provenance::spelled();
    let next = [
        (format!("{coevo} --eval {r} --prey 50 --episodes 10"), format!("the trained actors, no noise, on 50 {name}")),
        (
            format!(
                "{coevo} --eval {r} --prey 50 --episodes 10 --control blind:{name}:{name} --eval-out eval-blind.csv"
            ),
            format!("{name} blind to each other (still seeing the rest)"),
        ),
        (format!("{coevo} --plot {r}"), format!("learning curves, {r}/figures/")),
        (format!("{coevo} --animate {r}/clip.gif --run {r} --prey 50"), "a GIF of the trained swarm".to_string()),
        (watch(&r.to_string(), &coevo), "watch it live".to_string()),
    ];
    let width = next.iter().map(|(command, _)| command.chars().count()).max().unwrap_or(0);
    out.push_str("next:\n");
    for (command, what) in next {
        out.push_str(&format!("  {command:<width$}   # {what}\n"));
    }
    Ok(out)
}
