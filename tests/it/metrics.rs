//! The authors' DoS and DoA (differences 9–11 of docs/src/results/authors-code.md): measured on the
//! states an episode decides on, 0…T−1, the spawn state included and the last state not, as
//! `NJP_algorithm/main.py` stores them; logged beside the paper's, only when the scene asks.

use crate::common::scene;
use coevo::scene::{Boundary, Policy};
use coevo::sim::metrics::{authors_dos_doa, EpisodeLog};
use coevo::sim::perception::Population;
use coevo::sim::species::SpeciesRegistry;
use coevo::sim::Simulation;
use coevo::store::schema;

/// The authors' DoS and DoA of the prey at the state the world holds now.
fn prey_now(sim: &Simulation) -> [f64; 2] {
    let pop = sim.world().resource::<Population>();
    let prey = pop.ranges[1].clone();
    authors_dos_doa(2.0, &pop.position[prey.clone()], &pop.heading[prey]).unwrap()
}

#[test]
fn the_authors_metrics_average_the_states_from_the_spawn_to_the_last_but_one() {
    let mut s = scene(3, 10, Policy::FleeNearest, Boundary::Periodic);
    s.species[0].policy = Policy::ChaseNearest;
    s.episode_steps = 2;
    s.authors_metrics = true;
    let mut sim = Simulation::new(s.clone());
    let spawn = prey_now(&sim);
    sim.step();
    let first = prey_now(&sim);
    assert_ne!(spawn, first, "the agents moved");
    sim.step();
    let last = prey_now(&sim);
    let log = sim.world().resource::<EpisodeLog>();
    let e = &log.episodes[0];
    let [dos, doa] = e.authors[1].expect("ten prey");
    for (got, want) in [(dos, (spawn[0] + first[0]) / 2.0), (doa, (spawn[1] + first[1]) / 2.0)] {
        assert!((got - want).abs() < 1e-12, "{got} against states 0 and 1: {want} (state 2: {last:?})");
    }
    assert!(e.authors[0].is_some(), "three predators");
    // metrics.csv: the columns after the returns, one cell each; none without the switch.
    let registry = sim.world().resource::<SpeciesRegistry>();
    let header = schema::metrics_header_for(registry, &[], true);
    let cells = schema::episode_cells(e, registry);
    assert_eq!(header.split(',').count(), cells.len() + 1, "every cell under a column, then wall_seconds");
    let names: Vec<&str> = header.split(',').collect();
    let at = names.iter().position(|c| *c == "authors_dos_prey").expect("the column");
    assert_eq!(names[at - 1], "authors_doa_predator");
    assert_eq!(cells[at], dos.to_string());
    s.authors_metrics = false;
    let mut plain = Simulation::new(s);
    plain.step();
    plain.step();
    let log = plain.world().resource::<EpisodeLog>();
    assert!(log.episodes[0].authors.is_empty());
    assert!(!schema::metrics_header_for(registry, &[], false).contains("authors"));
    assert_eq!(schema::episode_cells(&log.episodes[0], registry).len(), cells.len() - 4);
}
