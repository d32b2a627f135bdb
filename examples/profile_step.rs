//! Steps one benchmark population for a while, for profilers, and prints the mean wall time of each stage
//! of the step (`SimSet`, and `PerceiveSet` inside Perceive):
//! `cargo run --release --example profile_step -- 3 1000` (random actions), or
//! `cargo run --release --example profile_step -- 3 10000 learned` (one batched forward pass per species
//! per step, untrained weights: what `coevo --bench`'s policy-driven figure measures).
use bevy::prelude::*;
use coevo::sim::perception::{self, PerceiveSet};
use coevo::sim::SimSet;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Wall time per stage, summed over steps.
type Totals = Vec<(&'static str, Duration)>;
/// The totals, and the instant the last stage ended.
static STAGES: Mutex<(Totals, Option<Instant>)> = Mutex::new((Vec::new(), None));

fn mark(label: &'static str) -> impl FnMut() {
    move || {
        let mut s = STAGES.lock().unwrap();
        let now = Instant::now();
        if let Some(before) = s.1 {
            match s.0.iter_mut().find(|(l, _)| *l == label) {
                Some((_, d)) => *d += now - before,
                None => s.0.push((label, now - before)),
            }
        }
        s.1 = Some(now);
    }
}

/// The stages as a step runs them (the mark before Decide only starts the step's clock).
const STEP_ORDER: [&str; 10] = [
    "decide",
    "act",
    "physics",
    "perceive: index",
    "perceive: contacts",
    "perceive: observe",
    "reward",
    "measure",
    "learn",
    "episode",
];

/// Marks the end of each stage; the first mark of a step starts its clock.
fn instrument(app: &mut App) {
    use SimSet::*;
    app.add_systems(FixedUpdate, mark("(start of step)").before(Decide));
    for (label, set, next) in [
        ("decide", Decide, Act),
        ("act", Act, Physics),
        ("physics", Physics, Perceive),
        ("reward", Reward, Measure),
        ("measure", Measure, Learn),
        ("learn", Learn, Episode),
    ] {
        app.add_systems(FixedUpdate, mark(label).after(set).before(next));
    }
    app.add_systems(FixedUpdate, mark("episode").after(Episode));
    use PerceiveSet::*;
    app.add_systems(
        perception::Perceive,
        (
            mark("perceive: index").after(Index).before(Contacts),
            mark("perceive: contacts").after(Contacts).before(Observe),
            mark("perceive: observe").after(Observe),
        ),
    );
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let count = |i: usize, default: usize| args.get(i).map_or(default, |a| a.parse().expect("counts"));
    let (p, e) = (count(0, 3), count(1, 1000));
    let mut scene = coevo::run::bench::bench_scene(p, e, e > 50);
    let steps = (2_000_000 / (p + e)).max(100);
    let mut sim = if args.get(2).is_some_and(|a| a == "learned") {
        for s in &mut scene.species {
            s.policy = coevo::scene::Policy::Learned;
        }
        let learners = coevo::learning::Learners::new(&scene, coevo::learning::Mode::Evaluate);
        coevo::learning::simulation_of(scene, learners, instrument).expect("no checkpoint needed")
    } else {
        coevo::sim::Simulation::with_plugins(scene, instrument)
    };
    let start = Instant::now();
    for _ in 0..steps {
        sim.step();
    }
    let total = start.elapsed();
    println!("{steps} steps of {p}+{e}: {:.3} ms per step", total.as_secs_f64() * 1e3 / steps as f64);
    let stages = &STAGES.lock().unwrap().0;
    for label in STEP_ORDER {
        let d = stages.iter().find(|(l, _)| *l == label).map_or(Duration::ZERO, |(_, d)| *d);
        println!("  {label:<20} {:>8.3} ms", d.as_secs_f64() * 1e3 / steps as f64);
    }
}
