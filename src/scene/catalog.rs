//! The species that species plugins bring, by name: scenes are read before any app exists (like the
//! presets), so a scene that names `hawk` is resolved from here. Program-wide, filled once at start-up by
//! `sim::species::SpeciesPlugins::register`.

use super::schema::{ContactReward, SpeciesDef};
use std::sync::RwLock;

/// A species as a plugin brings it: its definition with defaults, the species that catch it, and the
/// reward of each contact it takes part in (its own catches are `def.catches`).
#[derive(Clone, Debug, PartialEq)]
pub struct SpeciesTemplate {
    pub def: SpeciesDef,
    /// Species that catch this one (added to their `catches` when both are in a scene).
    pub caught_by: Vec<String>,
    /// Contact rewards of its pairs, either side; a scene's own `contact_rewards` entry for a pair wins.
    pub contact_rewards: Vec<ContactReward>,
}

static SPECIES: RwLock<Vec<SpeciesTemplate>> = RwLock::new(Vec::new());

/// Adds a species template: Ok(true) when new, Ok(false) for the same template again, an error for
/// another template of the same name.
pub(crate) fn insert(t: SpeciesTemplate) -> crate::error::Result<bool> {
    let mut all = SPECIES.write().unwrap_or_else(|e| e.into_inner());
    match all.iter().find(|o| o.def.name == t.def.name) {
        Some(o) if *o == t => Ok(false),
        Some(_) => Err(format!("species plugin {:?}: two species plugins define it", t.def.name).into()),
        None => {
            all.push(t);
            Ok(true)
        }
    }
}

/// The template of a species name, if a plugin of this program defines it.
pub(crate) fn get(name: &str) -> Option<SpeciesTemplate> {
    SPECIES.read().unwrap_or_else(|e| e.into_inner()).iter().find(|t| t.def.name == name).cloned()
}
