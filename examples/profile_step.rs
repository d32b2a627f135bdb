//! Steps one benchmark population for a while: `cargo run --release --example profile_step -- 3 1000`,
//! for profilers.
fn main() {
    let args: Vec<usize> = std::env::args().skip(1).map(|a| a.parse().expect("counts")).collect();
    let (p, e) = (args.first().copied().unwrap_or(3), args.get(1).copied().unwrap_or(1000));
    let mut sim = coevo::sim::Simulation::new(coevo::run::bench::bench_scene(p, e, e > 50));
    for _ in 0..(2_000_000 / (p + e)).max(100) {
        sim.step();
    }
}
