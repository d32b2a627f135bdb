//! From a scene file to the scene the simulation runs: RON read in a user's words ([`parse_ron`]), the
//! file applied as a patch of its preset (species by name, new ones complete), and the overrides of a
//! call ([`Overrides`]) applied and validated. Every error is one line: `file:line: field: message`.

use super::diagnostics::{field_before, locate, readable};
use super::schema::*;
use super::{catalog, presets};
use crate::error::{Error, Kind, Result, ResultExt};
use std::path::Path;

/// Reads RON text of a coevo file (a scene, an experiment) into `T`, with `Some` implied for optional
/// fields, and errors in a user's words: `file:line: field: message`.
pub fn parse_ron<T: serde::de::DeserializeOwned>(text: &str, file: &str) -> Result<T> {
    ron::Options::default().with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME).from_str(text).map_err(
        |e| Error {
            file: Some(file.to_string()),
            line: Some(e.span.start.line),
            field: Some(match &e.code {
                ron::Error::NoSuchStructField { found, .. } => found.clone(),
                _ => field_before(text, e.span.start.line, e.span.start.col),
            }),
            message: readable(text, &e),
            kind: crate::error::Kind::Other,
        },
    )
}

impl Scene {
    /// A preset by name (`paper` or `gym-pps`).
    pub fn preset(name: &str) -> Option<Scene> {
        match name {
            "paper" => Some(presets::paper()),
            "gym-pps" => Some(presets::gym_pps()),
            _ => None,
        }
    }

    /// Loads, resolves and validates a scene file.
    pub fn load(path: &Path) -> Result<Scene> {
        let text = crate::io::read_text(path, MAX_SCENE_BYTES)
            .map_err(|e| Error::from(e.message.replace("cannot read:", "cannot read scene:")).in_file(path))
            .kind(Kind::Scene)?;
        Scene::parse(&text, &path.display().to_string())
    }

    /// Parses, resolves and validates scene text; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<Scene> {
        Scene::parse_with_preset(text, file, None)
    }

    /// [`Scene::parse`], on `preset` instead of the one the text names (experiments switch a sweep's base
    /// between the `paper` and `gym-pps` presets).
    pub fn parse_with_preset(text: &str, file: &str, preset: Option<&str>) -> Result<Scene> {
        Scene::resolve_text(text, file, preset).kind(Kind::Scene)
    }

    fn resolve_text(text: &str, file: &str, preset: Option<&str>) -> Result<Scene> {
        let patch: ScenePatch = parse_ron(text, file)?;
        // An error about a field, at the line of the file that sets it.
        let located = |e: Error| {
            let line = e.field.as_deref().and_then(|f| locate(text, f));
            Error { file: Some(file.to_string()), line, ..e }
        };
        let preset_name =
            preset.map(str::to_string).or_else(|| patch.preset.clone()).unwrap_or_else(|| "paper".to_string());
        let mut scene = Scene::preset(&preset_name).ok_or_else(|| {
            located(Error::field(
                "preset".into(),
                format!("unknown preset {preset_name:?} (known: {})", PRESETS.join(", ")),
            ))
        })?;
        scene.apply(patch).map_err(located)?;
        scene.validate().map_err(located)?;
        Ok(scene)
    }

    /// Applies a scene patch (an experiment's variant) and validates the result.
    pub(crate) fn patched(&self, patch: ScenePatch) -> Result<Scene> {
        let mut scene = self.clone();
        scene.apply(patch)?;
        scene.validate()?;
        Ok(scene)
    }

    /// Applies a patch; a new species must give every field.
    fn apply(&mut self, patch: ScenePatch) -> Result<()> {
        if let Some(v) = patch.seed {
            self.seed = v;
        }
        if let Some(v) = patch.episode_steps {
            self.episode_steps = v;
        }
        if let Some(v) = patch.episodes {
            self.episodes = v;
        }
        if let Some(v) = patch.observation_frame {
            self.observation_frame = v;
        }
        if let Some(v) = patch.observation_layout {
            self.observation_layout = v;
        }
        if let Some(v) = patch.cluster_link {
            self.cluster_link = v;
        }
        if let Some(v) = patch.confusion_radius {
            self.confusion_radius = Some(v);
        }
        if let Some(v) = patch.contact_rewards {
            self.contact_rewards = v;
        }
        if let Some(v) = patch.authors_metrics {
            self.authors_metrics = v;
        }
        if let Some(p) = patch.world {
            p.apply(&mut self.world);
        }
        if let Some(p) = patch.rewards {
            p.apply(&mut self.rewards);
        }
        if let Some(p) = patch.learning {
            p.apply(&mut self.learning);
        }
        let mut seen = std::collections::BTreeSet::new();
        for (i, sp) in patch.species.unwrap_or_default().into_iter().enumerate() {
            let Some(name) = sp.name.clone() else {
                return Err(Error::field(format!("species[{i}].name"), "every species entry needs a name".into()));
            };
            if !seen.insert(name.clone()) {
                return Err(Error::field(
                    format!("species[{name}]"),
                    "appears twice in this scene; give each species one entry".into(),
                ));
            }
            if let Some(existing) = self.species.iter_mut().find(|s| s.name == name) {
                sp.apply(existing);
            } else if let Some(t) = catalog::get(&name) {
                // A species a plugin of this program defines: its defaults, then the scene's fields.
                let mut def = t.def.clone();
                sp.apply(&mut def);
                self.species.push(def);
                for catcher in &t.caught_by {
                    if let Some(c) = self.species.iter_mut().find(|s| &s.name == catcher) {
                        if !c.catches.contains(&name) {
                            c.catches.push(name.clone());
                        }
                    }
                }
                for r in &t.contact_rewards {
                    let present = |n: &str| self.species.iter().any(|s| s.name == n);
                    let set = self.contact_rewards.iter().any(|c| c.catcher == r.catcher && c.caught == r.caught);
                    if !set && present(&r.catcher) && present(&r.caught) {
                        self.contact_rewards.push(r.clone());
                    }
                }
            } else {
                let mut def = SpeciesDef::template(&name);
                let missing = sp.missing_fields();
                if !missing.is_empty() {
                    return Err(Error::field(
                        format!("species[{name}]"),
                        format!(
                            "no preset or species plugin of this program defines {name:?}; a new species must set: {}",
                            missing.join(", ")
                        ),
                    ));
                }
                sp.apply(&mut def);
                self.species.push(def);
            }
        }
        Ok(())
    }
}

/// What a call changes of a scene it loads: species counts (`--prey`, `--predators`, `--count`, an
/// evaluation's `counts`), species policies (`--policy`, an evaluation's `policies`), the seed, the steps
/// per episode, the confusion radius. The one place where overrides are applied; the scene is validated
/// again after them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Overrides {
    pub counts: Vec<(String, usize)>,
    pub policies: Vec<(String, Policy)>,
    pub seed: Option<u64>,
    pub episode_steps: Option<usize>,
    pub confusion_radius: Option<f64>,
    /// The arena's edge (m): a larger group at the density of a smaller one (`world.arena_edge`).
    pub arena_edge: Option<f64>,
}

impl Overrides {
    /// The scene file at `path` with the overrides applied and validated.
    pub fn load(&self, path: &Path) -> Result<Scene> {
        let mut scene = Scene::load(path)?;
        self.apply(&mut scene, path).kind(Kind::Scene)?;
        Ok(scene)
    }

    /// Applies the overrides to `scene` (read from `source`, which errors name) and validates the result.
    pub(crate) fn apply(&self, scene: &mut Scene, source: &Path) -> Result<()> {
        for (name, n) in &self.counts {
            scene.set_count(name, *n).map_err(|e| format!("{}: {e}", source.display()))?;
        }
        for (name, policy) in &self.policies {
            scene.set_policy(name, policy.clone()).map_err(|e| format!("{}: {e}", source.display()))?;
        }
        if let Some(seed) = self.seed {
            scene.seed = seed;
        }
        if let Some(steps) = self.episode_steps {
            scene.episode_steps = steps;
        }
        if let Some(r) = self.confusion_radius {
            scene.confusion_radius = Some(r);
        }
        if let Some(edge) = self.arena_edge {
            scene.world.arena_edge = edge;
        }
        scene.validate().map_err(|e| e.in_file(source))
    }
}

impl SpeciesDef {
    /// Placeholder values for a species a scene adds; `missing_fields` makes sure all are overwritten.
    fn template(name: &str) -> SpeciesDef {
        SpeciesDef {
            name: name.to_string(),
            count: 0,
            mass: 0.0,
            radius: 0.0,
            max_speed: 0.0,
            max_thrust: 0.0,
            max_turn_rate: 0.0,
            perception: Perception::Full,
            topological_limit: 0,
            colour: [0.0; 3],
            catches: vec![],
            policy: Policy::Still,
            blind_to: vec![],
            field_of_view: super::schema::FULL_VIEW,
            field_of_view_of: vec![],
            perception_of: vec![],
            topological_limit_of: vec![],
        }
    }
}

impl SpeciesPatch {
    fn missing_fields(&self) -> Vec<&'static str> {
        let mut m = vec![];
        macro_rules! need { ($($f:ident),*) => { $( if self.$f.is_none() { m.push(stringify!($f)); } )* } }
        need!(
            count,
            mass,
            radius,
            max_speed,
            max_thrust,
            max_turn_rate,
            perception,
            topological_limit,
            colour,
            catches,
            policy
        );
        m
    }
}
