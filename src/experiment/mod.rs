//! Experiments: the paper's sweeps as files (`experiments/*.ron`), run as independent training runs, then
//! evaluated, aggregated over seeds (mean and Student-t 95 % confidence interval) and plotted.
//!
//! ```ron
//! (
//!     description: "Effect of the speed limit ratio predator:prey (the paper's Fig. 10)",
//!     base: "scenes/paper.ron",             // the scene every variant starts from
//!     presets: ["paper", "gym-pps"],        // the base is run on each preset (default ["paper"])
//!     seeds: [1, 2, 3],
//!     episodes: 2000,                       // optional: overrides the base scene's
//!     variants: [
//!         (name: "1:1"),                                                    // the base as it is
//!         (name: "5:3", patch: (species: [(name: "prey", max_speed: 0.3)])), // a scene patch
//!     ],
//!     evaluations: [(name: "50 prey", counts: [("prey", 50)], episodes: 3, steps: 500)],
//!     claims: [ /* the paper's numbers this experiment tests, see `Claim` */ ],
//! )
//! ```
//!
//! Every preset × variant × seed is one run folder, `results/<experiment>/<preset>/<variant>/seed<k>/`,
//! trained by `coevo --train` in a child process on its share of the cores (results never depend on how
//! many run at once or on how many threads each has), resumed from its checkpoint when it was killed, skipped when finished ([`runner`]). Then the
//! evaluations write `eval-<name>.csv` beside it, and [`aggregate`] reads only CSV files to write
//! `summary.csv`, `summary-mean.csv` and the figures ([`plot`]).

// The single-run analyses the lab runs, aggregates and draws with, and the claims it judges, from the
// rooms below it.
pub(crate) use crate::analysis::{crossplay, crossplay_matrix, crossplay_readouts, distill, plot, stats};
pub(crate) use crate::claims::{
    curves, family, figure_data, file, grid, quantity, registry, report, results, summary, trainings, verdict,
};
pub mod aggregate;
pub(crate) mod carry;
pub(crate) mod command;
pub(crate) mod data;
pub(crate) mod estimate;
pub mod external;
pub(crate) mod figures;
mod load;
pub mod paper_table;
pub(crate) mod pin;
pub(crate) mod registration;
pub(crate) mod runner;
pub(crate) mod spread;

pub use crate::claims::{file::*, ClaimResult, RunData};
