//! coevo: predators and prey that learn together (Li, Li & Zhao, New J. Phys. 2023) as a Bevy ECS app.
//!
//! The crate reads as the data flows: scene → simulation → learning → runs and experiments → viewer.
//!
//! | folder / file | what |
//! |---|---|
//! | `scene/` | scenes: schema, presets, patches and overrides, validation, the observation layout |
//! | `sim/` | the simulation core (components, space, physics, perception, reward, metrics, collective measures, episodes, species, policies) and [`sim::Simulation`]; one fixed step is the chain of [`sim::SimSet`]s (see [`sim`]) |
//! | `learning/` | Algorithm 1 (DDPG) as a plugin on dfdx, checkpoints |
//! | `run/` | a run folder (names, reserved outputs, lock, provenance, CSV schemas) and the run modes: train, evaluate, record, animate, bench |
//! | `experiment/` | experiment files, the runner, aggregation, claims and verdicts, reports |
//! | `viewer/` | the window (`--features viewer`) |
//! | `cli.rs` | the command line (`main.rs` and examples call [`cli::main`]) |
//! | `error.rs`, `io.rs`, `parallel.rs`, `svg.rs` | the one error type, files written safely, threads that never change a result, SVG to pixels |

/// The crate's version (`provenance.ron`'s `coevo_version`; the Python package's `__version__`).
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
/// The commit this build was made from (`git describe --always --dirty`, `build.rs`).
pub const GIT_COMMIT: &str = env!("COEVO_GIT_COMMIT");

pub mod cli;
pub mod error;
pub mod experiment;
pub mod io;
pub mod learning;
pub mod parallel;
pub mod run;
pub mod scene;
pub mod sim;
pub mod svg;
#[cfg(feature = "viewer")]
pub mod viewer;
/// Without the window only the viewer's flags exist, so they are refused with a hint.
#[cfg(not(feature = "viewer"))]
pub mod viewer {
    pub mod args;
}
