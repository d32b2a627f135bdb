//! coevo: predators and prey that learn together (Li, Li & Zhao, New J. Phys. 2023) as a Bevy ECS app.
//!
//! The crate reads as the data flows: scene → simulation → learning → store → runs and experiments → viewer.
//!
//! | folder / file | what |
//! |---|---|
//! | `scene/` | scenes: schema, presets, patches and overrides, validation, the observation layout |
//! | `sim/` | the simulation core (components, space, physics, perception, reward, metrics, collective measures, episodes, species, policies) and [`sim::Simulation`]; one fixed step is the chain of [`sim::SimSet`]s (see [`sim`]) |
//! | `learning/` | Algorithm 1 (DDPG) as a plugin on dfdx; it knows no file |
//! | `store/` | what a run leaves on disk: a run folder (names, reserved outputs, lock, provenance, CSV schemas) and its checkpoint format (safetensors, replay segments, snapshots, manifest) |
//! | `run/` | the run modes: train, evaluate, record, animate, bench |
//! | `analysis/` | single-run analyses: read-outs of one run's trained actors (response fields, force maps, distilled rules, cross-play), with the statistics and drawing they share |
//! | `experiment/` | the lab: experiment files, the runner, aggregation, claims and verdicts, reports |
//! | `viewer/` | the window (`--features viewer`) |
//! | `cli.rs` | the command line (`main.rs` and examples call [`cli::main`]) |
//! | `error.rs`, `io/`, `parallel.rs`, `svg.rs` | the one error type, files written safely (and what a process must not leave behind, its memory, printing that never panics), threads that never change a result, SVG to pixels |
//!
//! # The public API
//!
//! Everything else is `pub(crate)`: the crate's own plumbing, free to change. What is public is what its
//! three kinds of users need (the integration tests in `tests/` are written as such a user):
//!
//! - **A species plugin** (`examples/hawk.rs`, `tests/species_plugin.rs`, the book's "Adding a species"):
//!   [`sim::species`] (`SpeciesPlugin`, `SpeciesPlugins`, `SpeciesTemplate`, `SpeciesRegistry`), the
//!   components of [`sim::components`], [`sim::perception`]'s batches, [`sim::reward`], [`sim::space::Arena`],
//!   [`sim::SimSet`] and [`sim::Simulation`], the scene types of [`scene`], and [`cli::main`] to run it all.
//! - **A binding or driver** (the Python package, `python/src/lib.rs`): [`run::env`] (`Env`, `VecEnv`),
//!   [`store::RunDir`] and [`store::schema::Table`] to read run folders, [`run::args::load_scene`],
//!   [`learning::control::ObservationControl`], [`analysis::stats`], [`analysis::response`],
//!   [`analysis::force_map`], [`experiment::external`], [`error`] (`Error`, `Kind`) and [`io`]'s safe
//!   writes.
//! - **A downstream crate** training and evaluating: [`run::train`] (`train`, `resume`, `TrainOptions`),
//!   [`run::evaluate`], [`run::animate`], [`learning`] (`Learners`, `Mode`), [`run::simulation`], [`sim::metrics`]
//!   and [`experiment::Experiment`] with its crossplay, distillation and summary readers, and
//!   [`claims::pin::Pin`], a pinned experiment's record of its binary.
//!
//! A few items stay public only because the integration tests check them from outside (checkpoint
//! manifests and snapshots in [`store`], [`cli::check_args`], [`io::bytes_shown`]); they are not meant
//! to be built on. The docs link private items as well: read them with `cargo doc --document-private-items`.

#![allow(rustdoc::private_intra_doc_links)]

/// The crate's version (`provenance.ron`'s `coevo_version`; the Python package's `__version__`).
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
/// The commit this build was made from (`git describe --always --dirty`, `build.rs`).
pub const GIT_COMMIT: &str = env!("COEVO_GIT_COMMIT");

pub mod analysis;
pub mod claims;
pub mod cli;
pub mod error;
pub mod experiment;
pub mod io;
pub mod learning;
pub mod parallel;
pub mod run;
pub mod scene;
pub mod sim;
pub mod store;
pub mod svg;
#[cfg(feature = "viewer")]
pub mod viewer;
/// Without the window only the viewer's flags exist, so they are refused with a hint.
#[cfg(not(feature = "viewer"))]
pub mod viewer {
    pub mod args;
}
