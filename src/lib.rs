//! coevo: predators and prey that learn together (Li, Li & Zhao, New J. Phys. 2023) as a Bevy ECS app.
//!
//! The crate reads as the data flows: scene → simulation → learning → runs and experiments → viewer.
//!
//! | folder / file | what |
//! |---|---|
//! | `scene.rs` | scenes: presets, patches, validation |
//! | `sim/` | the simulation core (components, space, physics, perception, reward, metrics, collective measures, episodes, species, policies) and [`Simulation`]; one fixed step is the chain of [`SimSet`]s (see [`sim`]) |
//! | `learning/` | Algorithm 1 (DDPG) as a plugin on dfdx, checkpoints |
//! | `run/` | a run folder: its names, reserved outputs, lock, provenance |
//! | `train.rs`, `record.rs`, `animate.rs`, `bench.rs`, `experiment/` | the run modes and the experiment layer |
//! | `viewer/` | the window (`--features viewer`) |
//! | `cli.rs` | the command line (`main.rs` and examples call [`cli::main`]) |
//! | `io.rs`, `parallel.rs`, `svg.rs` | files written safely, threads that never change a result, SVG to pixels |

pub mod cli;
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
