//! Scenes: the whole configuration of a run, as RON files under `scenes/`.
//!
//! A scene names a **preset** (`paper` or `gym-pps`, see `../shared/reference/parameters.md` and the
//! book, docs/src/guide/scenes.md) and overrides any field of it. Every struct here exists twice: the resolved value the simulation
//! reads ([`Scene`], [`WorldParams`], [`RewardParams`], [`SpeciesDef`], [`LearningParams`]) and a patch with every field
//! optional, which is what a scene file holds. Species are patched by `name`; a name the preset does not
//! know adds a new species and must then give every field.
//!
//! Every error is one line naming the file, the line when it is known, and the field.

pub(crate) mod catalog;
mod classic;
mod diagnostics;
pub(crate) mod layout;
mod presets;
mod resolve;
mod rules;
mod schema;
mod validate;

pub use resolve::{parse_ron, Overrides};
pub use rules::{BinnedGains, PursuitGains, RuleForm, ZonalTerm, ZonalThrust, ZonalTurn};
pub use schema::*;
