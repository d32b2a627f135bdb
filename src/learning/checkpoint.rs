//! Checkpoints, in `RUN/checkpoint/`:
//!
//! - `<species>-actor.safetensors`: the actor, f32, named as PyTorch's
//!   `nn.Sequential(Linear, ReLU, Linear, ReLU, Linear, ReLU, Linear, Tanh)`: `0.weight` (64, d_o),
//!   `0.bias` (64), `2.weight` (64, 64), `2.bias`, `4.weight` (64, 64), `4.bias`, `6.weight` (2, 64),
//!   `6.bias` (2). `model.load_state_dict(safetensors.torch.load_file(path))` loads it.
//! - `<species>-training.safetensors`: `critic.*`, `target_actor.*`, `target_critic.*` (same naming) and the
//!   Adam moments `actor_adam.m.*`, `actor_adam.v.*`, `critic_adam.m.*`, `critic_adam.v.*`.
//! - `state.ron`: the scene, episodes done, RNG states (environment, each species), exploration σ/ε, Adam step counts, metrics so far.
//!
//! The folder is written whole as `checkpoint.tmp/` and then swapped in, so a run killed at any moment
//! leaves either the previous checkpoint or the new one, never a mix. Replay buffers are not saved (up to
//! 5·10⁵ transitions, ~220 MB per species): a resumed run refills them.

use super::ddpg::Ddpg;
use super::nets::Mlp;
use super::SpeciesLearner;
use crate::io::Existing;
use crate::scene::Scene;
use dfdx::shapes::HasShape;
use rand_chacha::ChaCha8Rng;
use safetensors::tensor::{Dtype, SafeTensors, TensorView};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Everything but the networks that a run needs to resume.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TrainingState {
    pub scene: Scene,
    pub episodes_done: usize,
    pub sim_rng: ChaCha8Rng,
    pub species: Vec<Option<SpeciesState>>,
    /// metrics.csv as it stood at this checkpoint.
    pub metrics_csv: String,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SpeciesState {
    pub name: String,
    pub noise_std: f64,
    pub epsilon: f64,
    pub actor_adam_step: u64,
    pub critic_adam_step: u64,
    /// The species' exploration and sampling stream (absent in checkpoints of coevo before per-species
    /// streams: a resumed run then continues on a fresh stream of the seed).
    #[serde(default)]
    pub rng: Option<ChaCha8Rng>,
}

pub fn checkpoint_dir(run: &Path) -> PathBuf {
    run.join("checkpoint")
}

/// Names of an MLP's tensors as in PyTorch's `nn.Sequential` with activations between the layers.
fn named(prefix: &str, values: Vec<Vec<f32>>, net: &Mlp) -> Vec<(String, Vec<usize>, Vec<f32>)> {
    net.layers
        .iter()
        .enumerate()
        .flat_map(|(i, l)| {
            let (o, n) = *l.weight.shape();
            [(format!("{prefix}{}.weight", 2 * i), vec![o, n]), (format!("{prefix}{}.bias", 2 * i), vec![o])]
        })
        .zip(values)
        .map(|((name, shape), v)| (name, shape, v))
        .collect()
}

fn serialize(tensors: &[(String, Vec<usize>, Vec<f32>)]) -> Vec<u8> {
    let bytes: Vec<Vec<u8>> =
        tensors.iter().map(|(_, _, v)| v.iter().flat_map(|x| x.to_le_bytes()).collect()).collect();
    let views: Vec<(String, TensorView)> = tensors
        .iter()
        .zip(&bytes)
        .map(|((name, shape, _), b)| {
            (name.clone(), TensorView::new(Dtype::F32, shape.clone(), b).expect("shape matches data"))
        })
        .collect();
    safetensors::serialize(views, &None).expect("f32 tensors serialize")
}

/// Reads the tensors `net` needs under `prefix` from a safetensors file, checking names and shapes.
fn read_into(file: &Path, st: &SafeTensors, prefix: &str, like: &Mlp) -> Result<Vec<Vec<f32>>, String> {
    named(prefix, like.parameters(), like)
        .into_iter()
        .map(|(name, shape, _)| {
            let t = st.tensor(&name).map_err(|_| format!("{}: no tensor {name:?}", file.display()))?;
            if t.dtype() != Dtype::F32 || t.shape() != shape.as_slice() {
                return Err(format!(
                    "{}: tensor {name} is {:?} {:?}, this scene needs F32 {shape:?} (observation size or hidden width differ)",
                    file.display(),
                    t.dtype(),
                    t.shape()
                ));
            }
            let values: Vec<f32> = t.data().chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
            match values.iter().position(|v| !v.is_finite()) {
                Some(i) => Err(format!("{}: tensor {name} holds a non-finite value ({} at index {i}); refusing a broken network", file.display(), values[i])),
                None => Ok(values),
            }
        })
        .collect()
}

fn read_file(path: &Path) -> Result<Vec<u8>, String> {
    match std::fs::metadata(path) {
        Ok(m) if !m.is_file() => Err(format!("{}: not a regular file, not a checkpoint", path.display())),
        Ok(_) => std::fs::read(path).map_err(|e| format!("{}: cannot read checkpoint: {e}", path.display())),
        Err(e) => Err(format!("{}: cannot read checkpoint: {e}", path.display())),
    }
}

fn parse<'a>(path: &Path, bytes: &'a [u8]) -> Result<SafeTensors<'a>, String> {
    SafeTensors::deserialize(bytes).map_err(|e| format!("{}: not a valid safetensors file ({e:?})", path.display()))
}

/// Loads a species' actor from a run folder into `like` (which fixes the expected shapes).
pub fn load_actor(run: &Path, species: &str, like: &Mlp) -> Result<Mlp, String> {
    let path = checkpoint_dir(run).join(format!("{species}-actor.safetensors"));
    let bytes = read_file(&path)?;
    let st = parse(&path, &bytes)?;
    let mut net = like.clone();
    net.set_parameters(&read_into(&path, &st, "", like)?);
    Ok(net)
}

/// Saves learners and state into `run/checkpoint/`, atomically as a folder.
pub fn save(
    run: &Path,
    learners: &[Option<SpeciesLearner>],
    names: &[String],
    state: &TrainingState,
) -> std::io::Result<()> {
    let dir = checkpoint_dir(run);
    let tmp = run.join("checkpoint.tmp");
    let old = run.join("checkpoint.old");
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(&tmp)?;
    for (learner, name) in learners.iter().zip(names) {
        let Some(l) = learner else { continue };
        let d = &l.ddpg;
        let actor = named("", d.actor.parameters(), &d.actor);
        crate::io::write_atomically(&tmp.join(format!("{name}-actor.safetensors")), Existing::Replace, |w| {
            std::io::Write::write_all(w, &serialize(&actor))
        })?;
        let mut training = named("critic.", d.critic.parameters(), &d.critic);
        training.extend(named("target_actor.", d.target_actor.parameters(), &d.target_actor));
        training.extend(named("target_critic.", d.target_critic.parameters(), &d.target_critic));
        training.extend(named("actor_adam.m.", d.actor_opt.m.clone(), &d.actor));
        training.extend(named("actor_adam.v.", d.actor_opt.v.clone(), &d.actor));
        training.extend(named("critic_adam.m.", d.critic_opt.m.clone(), &d.critic));
        training.extend(named("critic_adam.v.", d.critic_opt.v.clone(), &d.critic));
        crate::io::write_atomically(&tmp.join(format!("{name}-training.safetensors")), Existing::Replace, |w| {
            std::io::Write::write_all(w, &serialize(&training))
        })?;
    }
    let ron = ron::ser::to_string_pretty(state, ron::ser::PrettyConfig::new().struct_names(false))
        .map_err(|e| std::io::Error::other(e.to_string()))?;
    crate::io::write_atomically(&tmp.join("state.ron"), Existing::Replace, |w| {
        std::io::Write::write_all(w, ron.as_bytes())
    })?;
    // Swap: the old checkpoint stays until the new one is in place; `load` falls back to `.old`.
    let _ = std::fs::remove_dir_all(&old);
    if dir.exists() {
        std::fs::rename(&dir, &old)?;
    }
    std::fs::rename(&tmp, &dir)?;
    let _ = std::fs::remove_dir_all(&old);
    Ok(())
}

/// Restores learners from `run/checkpoint/` (or `checkpoint.old` after a kill mid-swap) and returns the state.
pub fn load(run: &Path, learners: &mut [Option<SpeciesLearner>], names: &[String]) -> Result<TrainingState, String> {
    let mut dir = checkpoint_dir(run);
    if !dir.join("state.ron").exists() && run.join("checkpoint.old/state.ron").exists() {
        dir = run.join("checkpoint.old");
    }
    let state_path = dir.join("state.ron");
    if !state_path.exists() {
        return Err(format!("{}: no checkpoint to resume", state_path.display()));
    }
    let text = crate::io::read_text(&state_path, crate::io::MAX_TEXT_BYTES)
        .map_err(|e| format!("{}: {e}", state_path.display()))?;
    let state: TrainingState =
        ron::from_str(&text).map_err(|e| format!("{}: corrupt checkpoint state ({e})", state_path.display()))?;
    for (learner, name) in learners.iter_mut().zip(names) {
        let Some(l) = learner else { continue };
        let s = state
            .species
            .iter()
            .flatten()
            .find(|s| &s.name == name)
            .ok_or_else(|| format!("{}: no species {name:?} in the checkpoint", state_path.display()))?;
        let actor_path = dir.join(format!("{name}-actor.safetensors"));
        let bytes = read_file(&actor_path)?;
        let st = parse(&actor_path, &bytes)?;
        let actor = read_into(&actor_path, &st, "", &l.ddpg.actor)?;
        let path = dir.join(format!("{name}-training.safetensors"));
        let bytes = read_file(&path)?;
        let st = parse(&path, &bytes)?;
        let d: &mut Ddpg = &mut l.ddpg;
        let critic = read_into(&path, &st, "critic.", &d.critic)?;
        let target_actor = read_into(&path, &st, "target_actor.", &d.actor)?;
        let target_critic = read_into(&path, &st, "target_critic.", &d.critic)?;
        d.actor_opt.m = read_into(&path, &st, "actor_adam.m.", &d.actor)?;
        d.actor_opt.v = read_into(&path, &st, "actor_adam.v.", &d.actor)?;
        d.critic_opt.m = read_into(&path, &st, "critic_adam.m.", &d.critic)?;
        d.critic_opt.v = read_into(&path, &st, "critic_adam.v.", &d.critic)?;
        d.actor.set_parameters(&actor);
        d.critic.set_parameters(&critic);
        d.target_actor.set_parameters(&target_actor);
        d.target_critic.set_parameters(&target_critic);
        d.actor_opt.step = s.actor_adam_step;
        d.critic_opt.step = s.critic_adam_step;
        l.noise_std = s.noise_std;
        l.epsilon = s.epsilon;
        if let Some(rng) = &s.rng {
            l.rng = rng.clone();
        }
    }
    Ok(state)
}
