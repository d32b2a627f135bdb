//! Single-run analyses: what one run's trained actors do, read off them (the response fields and force
//! maps of `--response` and `--force-map`, the rules `--distill` fits, the cross-play of `--crossplay`),
//! with the statistics and the drawing they share. Below the lab (`experiment/`), which runs them on every
//! run of an experiment and aggregates them; above `run/` and `store/`, whose run folders they read. The viewer uses
//! them and never the lab; the Python package too, but for the lab's comparison with other
//! implementations (`experiment::external`).

pub mod crossplay;
pub mod crossplay_matrix;
pub mod crossplay_readouts;
pub mod distill;
pub mod force_map;
pub(crate) mod plot;
pub mod response;
pub(crate) mod rule_fit;
pub mod stats;
pub(crate) mod swarm;
