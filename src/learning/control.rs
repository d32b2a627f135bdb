//! Evaluation-time controls for alignment claims: what the actors are given of their neighbours.
//!
//! Whole-row forms act on **every neighbour block of every learning species** (`blind`, `shuffled`);
//! block forms act on one block of one observer species (`blind:prey:prey`: prey do not see each other,
//! still see the predators, the predators see everything). Only the block forms separate what prey take
//! from each other (flocking) from what they take in common from the predators (herding). The training-time
//! counterpart is a species' `blind_to` (`sim::perception`), whose observations never hold the block.

use crate::sim::species::SpeciesRegistry;
use bevy::prelude::Resource;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::ops::Range;

/// What a control does to the slots it touches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Alteration {
    /// Zero, as if nothing were within the perception radius.
    Blind,
    /// The slots of another individual of the observer's species (a fresh random permutation every step).
    Shuffled,
}

/// One form of `--control`: an alteration of every neighbour block of every learning species, or of the
/// block in which species `observer` sees species `observed`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct ControlForm {
    pub(crate) alteration: Alteration,
    /// (observer, observed); None: every neighbour block of every learning species.
    pub(crate) block: Option<(String, String)>,
}

/// The controls of an evaluation (none: the observations as perceived, `seeing`). Written as
/// `seeing`, `blind`, `shuffled`, `blind:OBSERVER:OBSERVED`, `shuffled:OBSERVER:OBSERVED`; several block
/// forms combine (`--control` repeated, or a list in an experiment file).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "ControlFile", into = "Vec<String>")]
pub struct ObservationControl {
    pub(crate) forms: Vec<ControlForm>,
}

/// The forms `--control` and experiment files accept.
pub(crate) const CONTROL_FORMS: &str =
    "seeing, blind, shuffled, blind:OBSERVER:OBSERVED or shuffled:OBSERVER:OBSERVED (species names)";

impl std::str::FromStr for ControlForm {
    type Err = String;
    fn from_str(text: &str) -> Result<ControlForm, String> {
        let parts: Vec<&str> = text.split(':').collect();
        let alteration = match parts[0] {
            "blind" => Alteration::Blind,
            "shuffled" => Alteration::Shuffled,
            _ => return Err(format!("{text:?} is not a control: use {CONTROL_FORMS}")),
        };
        match parts[..] {
            [_] => Ok(ControlForm { alteration, block: None }),
            [_, observer, observed] if !observer.is_empty() && !observed.is_empty() => {
                Ok(ControlForm { alteration, block: Some((observer.into(), observed.into())) })
            }
            _ => Err(format!("{text:?} is not a control: use {CONTROL_FORMS}")),
        }
    }
}

impl std::fmt::Display for ControlForm {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        let name = match self.alteration {
            Alteration::Blind => "blind",
            Alteration::Shuffled => "shuffled",
        };
        match &self.block {
            None => write!(f, "{name}"),
            Some((observer, observed)) => write!(f, "{name}:{observer}:{observed}"),
        }
    }
}

impl ObservationControl {
    /// The controls written as `texts` (`seeing` alone, or forms); Err says which text is wrong.
    pub fn parse<S: AsRef<str>>(texts: &[S]) -> Result<ObservationControl, String> {
        let texts: Vec<&str> = texts.iter().map(AsRef::as_ref).collect();
        if texts == ["seeing"] || texts.is_empty() {
            return Ok(ObservationControl::default());
        }
        if texts.len() > 1 && texts.iter().any(|t| *t == "seeing" || !t.contains(':')) {
            return Err(format!("{}: only block forms (blind:OBSERVER:OBSERVED) combine", texts.join(", ")));
        }
        let forms: Vec<ControlForm> = texts.iter().map(|t| t.parse()).collect::<Result<_, _>>()?;
        // One alteration per block: a second would silently decide which applies.
        for (i, f) in forms.iter().enumerate() {
            if let Some(twice) = forms[..i].iter().find(|o| o.block == f.block) {
                return Err(format!("{twice} and {f}: name the same block twice; give each block once"));
            }
        }
        Ok(ObservationControl { forms })
    }

    pub(crate) fn is_seeing(&self) -> bool {
        self.forms.is_empty()
    }

    /// The forms as written (`seeing` for none): what `--control` takes, one per flag.
    pub(crate) fn texts(&self) -> Vec<String> {
        match self.forms.is_empty() {
            true => vec!["seeing".into()],
            false => self.forms.iter().map(ControlForm::to_string).collect(),
        }
    }

    /// Exactly which slots the controls touch, for summaries and `--help`.
    pub(crate) fn describe(&self) -> String {
        let one = |f: &ControlForm| {
            let what = match f.alteration {
                Alteration::Blind => "zeroed",
                Alteration::Shuffled => "shuffled between individuals",
            };
            match &f.block {
                None => format!("every neighbour block of every learning species {what}"),
                Some((observer, observed)) => format!("{observer}'s view of {observed} {what}"),
            }
        };
        self.forms.iter().map(one).collect::<Vec<_>>().join("; ")
    }

    /// The controls resolved against a scene's species; Err names the form and what is wrong (an unknown
    /// species, or an observer that does not learn, whose actions no actor decides).
    pub(crate) fn resolve(&self, registry: &SpeciesRegistry) -> Result<ResolvedControl, String> {
        use crate::scene::Policy;
        let learns = |s: usize| registry.defs[s].policy == Policy::Learned;
        let index = |name: &str, form: &ControlForm| {
            registry
                .defs
                .iter()
                .position(|d| d.name == name)
                .ok_or_else(|| format!("{form}: no species named {name:?} in this scene"))
        };
        let mut per_species = vec![vec![]; registry.len()];
        for form in &self.forms {
            match &form.block {
                None => {
                    for (s, touched) in per_species.iter_mut().enumerate().filter(|(s, _)| learns(*s)) {
                        touched.push((form.alteration, registry.layouts[s].neighbours()));
                    }
                }
                Some((observer, observed)) => {
                    let (s, t) = (index(observer, form)?, index(observed, form)?);
                    if !learns(s) {
                        return Err(format!(
                            "{form}: {observer} does not learn (policy {:?}), so no actor reads its observations",
                            registry.defs[s].policy
                        ));
                    }
                    per_species[s].push((form.alteration, registry.block(s, t)));
                }
            }
        }
        Ok(ResolvedControl { per_species })
    }
}

/// [`ObservationControl`] as an experiment file writes it: `Seeing`/`Blind`/`Shuffled` (the original
/// names), one form as a string, or a list of forms.
#[derive(Deserialize)]
#[serde(untagged)]
enum ControlFile {
    Named(Named),
    One(String),
    Many(Vec<String>),
}

#[derive(Deserialize)]
enum Named {
    Seeing,
    Blind,
    Shuffled,
}

impl TryFrom<ControlFile> for ObservationControl {
    type Error = String;
    fn try_from(file: ControlFile) -> Result<ObservationControl, String> {
        match file {
            ControlFile::Named(Named::Seeing) => ObservationControl::parse(&["seeing"]),
            ControlFile::Named(Named::Blind) => ObservationControl::parse(&["blind"]),
            ControlFile::Named(Named::Shuffled) => ObservationControl::parse(&["shuffled"]),
            ControlFile::One(text) => ObservationControl::parse(&[text]),
            ControlFile::Many(texts) => ObservationControl::parse(&texts),
        }
    }
}

impl From<ObservationControl> for Vec<String> {
    fn from(c: ObservationControl) -> Vec<String> {
        c.texts()
    }
}

/// The controls of an evaluation resolved to slots: per species, the alterations and the ranges of its
/// observation row they touch, in order.
#[derive(Resource, Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct ResolvedControl {
    pub(crate) per_species: Vec<Vec<(Alteration, Range<usize>)>>,
}

impl ResolvedControl {
    /// Whether the observations of species `s` are altered.
    pub(crate) fn touches(&self, s: usize) -> bool {
        self.per_species.get(s).is_some_and(|t| !t.is_empty())
    }

    /// The observations species `s`'s actor is given: `observations` (`[n × d]`) with the touched slots
    /// altered. Each shuffled range draws its own permutation from `rng` and copies from the unaltered rows.
    pub(crate) fn apply(&self, s: usize, observations: &[f32], n: usize, rng: &mut ChaCha8Rng) -> Vec<f32> {
        let mut out = observations.to_vec();
        let d = observations.len() / n.max(1);
        for (alteration, range) in self.per_species.get(s).into_iter().flatten() {
            match alteration {
                Alteration::Blind => out.chunks_exact_mut(d).for_each(|row| row[range.clone()].fill(0.0)),
                Alteration::Shuffled => {
                    let mut order: Vec<usize> = (0..n).collect();
                    order.shuffle(rng);
                    for (row, &from) in out.chunks_exact_mut(d).zip(&order) {
                        row[range.clone()].copy_from_slice(&observations[from * d..(from + 1) * d][range.clone()]);
                    }
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{ObservationFrame, ObservationLayout, Policy, Scene};
    use crate::sim::species::{NEIGHBOUR_DIM, OWN_STATE_DIM};
    use rand::SeedableRng;

    /// The paper's two species, both learning, observed in `frame`.
    fn registry(frame: ObservationFrame) -> SpeciesRegistry {
        let mut scene = Scene::preset("paper").unwrap();
        scene.observation_frame = frame;
        SpeciesRegistry::from_scene(&scene)
    }

    /// The authors' code's observation: 2 predators and 5 prey, energy and heading after the blocks.
    fn authors_registry() -> SpeciesRegistry {
        let mut scene = Scene::preset("gym-pps").unwrap();
        scene.observation_layout = ObservationLayout::Authors;
        for s in &mut scene.species {
            s.topological_limit = 5;
            s.topological_limit_of = vec![("predator".into(), 2)];
        }
        SpeciesRegistry::from_scene(&scene)
    }

    /// `n` rows of species `s`, every number distinct.
    fn rows(r: &SpeciesRegistry, s: usize, n: usize) -> Vec<f32> {
        (0..n * r.observation_dim(s)).map(|i| 1.0 + i as f32).collect()
    }

    #[test]
    fn each_block_control_alters_exactly_its_block_of_its_observer() {
        for r in [registry(ObservationFrame::World), registry(ObservationFrame::Body), authors_registry()] {
            for (s, observer) in r.defs.iter().enumerate() {
                for (t, observed) in r.defs.iter().enumerate() {
                    let block = r.block_offset(s, t)..r.block_offset(s, t) + r.slots(s, t) * NEIGHBOUR_DIM;
                    let (n, d) = (7, r.observation_dim(s));
                    let obs = rows(&r, s, n);
                    for alteration in ["blind", "shuffled"] {
                        let text = format!("{alteration}:{}:{}", observer.name, observed.name);
                        let control = ObservationControl::parse(&[&text]).unwrap().resolve(&r).unwrap();
                        assert!(control.touches(s) && !control.touches(1 - s), "{text}: only the observer");
                        let out = control.apply(s, &obs, n, &mut ChaCha8Rng::seed_from_u64(3));
                        for (i, (row, orig)) in out.chunks(d).zip(obs.chunks(d)).enumerate() {
                            for k in (0..d).filter(|k| !block.contains(k)) {
                                assert_eq!(row[k], orig[k], "{text}: slot {k} of row {i} outside the block changed");
                            }
                            if alteration == "blind" {
                                assert!(row[block.clone()].iter().all(|&x| x == 0.0), "{text}: row {i}");
                            } else {
                                // The whole block of one row of the species, unaltered.
                                assert!(
                                    obs.chunks(d).any(|o| o[block.clone()] == row[block.clone()]),
                                    "{text}: row {i} holds no other row's block"
                                );
                            }
                        }
                        if alteration == "shuffled" {
                            let mut got: Vec<&[f32]> = out.chunks(d).map(|row| &row[block.clone()]).collect();
                            let mut want: Vec<&[f32]> = obs.chunks(d).map(|row| &row[block.clone()]).collect();
                            assert_ne!(got, want, "{text}: permuted");
                            got.sort_by(|a, b| a[0].total_cmp(&b[0]));
                            want.sort_by(|a, b| a[0].total_cmp(&b[0]));
                            assert_eq!(got, want, "{text}: every row's block once");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn whole_row_controls_alter_every_neighbour_slot_of_every_learning_species() {
        // The paper's order: own state, then every block. The authors': [x, y, v_x, v_y], the blocks
        // (2 predators, 5 prey: 4 + 28 numbers), then energy and heading, which no control touches.
        for (r, blocks) in [(registry(ObservationFrame::Body), OWN_STATE_DIM..54), (authors_registry(), 4..32)] {
            let blind = ObservationControl::parse(&["blind"]).unwrap().resolve(&r).unwrap();
            let shuffled = ObservationControl::parse(&["shuffled"]).unwrap().resolve(&r).unwrap();
            for s in 0..r.len() {
                let (n, d) = (5, r.observation_dim(s));
                let obs = rows(&r, s, n);
                let outside = |k: &usize| !blocks.contains(k);
                let out = blind.apply(s, &obs, n, &mut ChaCha8Rng::seed_from_u64(1));
                for (row, orig) in out.chunks(d).zip(obs.chunks(d)) {
                    assert!((0..d).filter(outside).all(|k| row[k] == orig[k]));
                    assert!(row[blocks.clone()].iter().all(|&x| x == 0.0));
                }
                let out = shuffled.apply(s, &obs, n, &mut ChaCha8Rng::seed_from_u64(1));
                for (row, orig) in out.chunks(d).zip(obs.chunks(d)) {
                    assert!((0..d).filter(outside).all(|k| row[k] == orig[k]));
                    assert!(obs.chunks(d).any(|o| o[blocks.clone()] == row[blocks.clone()]));
                }
            }
        }
        let seeing = ObservationControl::parse(&["seeing"]).unwrap();
        assert!(seeing.is_seeing() && !seeing.resolve(&authors_registry()).unwrap().touches(0));
    }

    #[test]
    fn bad_controls_say_what_is_wrong() {
        let mut scene = Scene::preset("paper").unwrap();
        scene.species[0].policy = Policy::ChaseNearest;
        let r = SpeciesRegistry::from_scene(&scene);
        for (texts, says) in [
            (vec!["blinded"], "is not a control"),
            (vec!["blind:prey"], "is not a control"),
            (vec!["blind:prey:prey:prey"], "is not a control"),
            (vec!["blind", "shuffled:prey:prey"], "only block forms"),
        ] {
            let e = ObservationControl::parse(&texts).unwrap_err();
            assert!(e.contains(says), "{texts:?}: {e}");
        }
        for (text, says) in [
            ("blind:prey:hawk", "no species named \"hawk\""),
            ("shuffled:owl:prey", "no species named \"owl\""),
            ("blind:predator:prey", "predator does not learn"),
        ] {
            let e = ObservationControl::parse(&[text]).unwrap().resolve(&r).unwrap_err();
            assert!(e.starts_with(text) && e.contains(says), "{text}: {e}");
        }
        // The original experiment-file names still read, and forms as strings or lists.
        let read = |ron_text: &str| ron::from_str::<ObservationControl>(ron_text).unwrap().texts();
        assert_eq!(read("Blind"), ["blind"]);
        assert_eq!(read("\"shuffled:prey:predator\""), ["shuffled:prey:predator"]);
        assert_eq!(
            read("[\"blind:prey:prey\", \"shuffled:prey:predator\"]"),
            ["blind:prey:prey", "shuffled:prey:predator"]
        );
        assert!(ron::from_str::<ObservationControl>("\"blind:prey\"").is_err());
    }
}
