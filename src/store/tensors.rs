//! The safetensors files of a checkpoint: networks named as PyTorch's `nn.Sequential`, metadata saying
//! what a file is (species, role, scene), the same bytes in every process, and reading that refuses a
//! file by name (metadata, tensor names, shapes, non-finite values) before the manifest checks the rest.

use super::manifest::{Digest, Manifest};
use crate::io::Existing;
use crate::learning::nets::Mlp;
use crate::scene::Scene;
use dfdx::shapes::HasShape;
use safetensors::tensor::{Dtype, SafeTensors, TensorView};
use std::path::Path;

/// A scene's identity in the metadata of the networks trained on it: the first 16 hex digits of the
/// BLAKE3 hash of its resolved RON.
pub(crate) fn scene_id(scene: &Scene) -> String {
    blake3::hash(scene.to_ron().as_bytes()).to_hex()[..16].to_string()
}

/// What a safetensors file of coevo says it is: `species`, `role` and the `scene` it was trained on.
pub(super) fn metadata(species: &str, role: &str, scene: Option<&Scene>) -> Metadata {
    let mut m = Metadata::from([("species".to_string(), species.to_string()), ("role".to_string(), role.to_string())]);
    if let Some(scene) = scene {
        m.insert("scene".into(), scene_id(scene));
    }
    m
}

/// Sorted, so a file's bytes are a function of its contents.
pub(super) type Metadata = std::collections::BTreeMap<String, String>;

/// Refuses a safetensors file whose metadata names another species or role (or, given, another scene)
/// than the file is read as. Files without coevo's metadata (older checkpoints, actors exported from
/// Python, shipped runs) pass.
pub(super) fn check_metadata(
    path: &Path,
    bytes: &[u8],
    species: &str,
    roles: &[&str],
    scene: Option<&str>,
) -> crate::error::Result<()> {
    let Ok((_, meta)) = SafeTensors::read_metadata(bytes) else { return Ok(()) };
    let Some(meta) = meta.metadata().as_ref() else { return Ok(()) };
    let field = |k: &str| meta.get(k).map(String::as_str);
    if let Some(theirs) = field("species").filter(|s| *s != species) {
        return Err(format!(
            "{}: holds a network of {theirs}, not of {species}; files were swapped or copied in",
            path.display()
        )
        .into());
    }
    if let Some(theirs) = field("role").filter(|r| !roles.contains(r)) {
        return Err(format!(
            "{}: holds a {theirs} file, not {}; files were swapped or copied in",
            path.display(),
            roles.join(" or ")
        )
        .into());
    }
    if let (Some(theirs), Some(ours)) = (field("scene"), scene) {
        if theirs != ours {
            return Err(format!(
                "{}: trained on another scene (scene {theirs}) than the run's (scene {ours}); snapshots of one run are not another's",
                path.display()
            )
            .into());
        }
    }
    Ok(())
}

/// An actor as its own safetensors file, named as PyTorch's `nn.Sequential` (module docs); its digest.
pub(super) fn write_actor(path: &Path, actor: &Mlp, meta: &Metadata) -> std::io::Result<Digest> {
    let bytes = serialize(&named("", actor.parameters(), actor), meta);
    crate::io::write_atomically(path, Existing::Replace, |w| std::io::Write::write_all(w, &bytes))?;
    Ok(Digest::of(&bytes))
}

/// Names of an MLP's tensors as in PyTorch's `nn.Sequential` with activations between the layers.
pub(super) fn named(prefix: &str, values: Vec<Vec<f32>>, net: &Mlp) -> Vec<(String, Vec<usize>, Vec<f32>)> {
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

/// The safetensors file of `tensors` with `meta` as its `__metadata__`, first in the header with its keys
/// sorted (safetensors' own writer orders metadata as a hash map iterates, which differs between
/// processes, and checkpoints must be the same bytes in every process).
pub(super) fn serialize(tensors: &[(String, Vec<usize>, Vec<f32>)], meta: &Metadata) -> Vec<u8> {
    let plain = serialize_plain(tensors);
    let n = u64::from_le_bytes(plain[..8].try_into().expect("8 bytes")) as usize;
    let header = std::str::from_utf8(&plain[8..8 + n]).expect("a JSON header").trim_end();
    let tensors_json = header.strip_prefix('{').expect("a JSON object");
    let header = padded(format!("{{\"__metadata__\":{},{tensors_json}", metadata_json(meta)));
    [&(header.len() as u64).to_le_bytes()[..], header.as_bytes(), &plain[8 + n..]].concat()
}

pub(super) fn metadata_json(meta: &Metadata) -> String {
    serde_json::to_string(meta).expect("strings serialize")
}

/// A header padded to 8 bytes with spaces, as safetensors' own writer does.
pub(super) fn padded(mut header: String) -> String {
    while !header.len().is_multiple_of(8) {
        header.push(' ');
    }
    header
}

pub(super) fn serialize_plain(tensors: &[(String, Vec<usize>, Vec<f32>)]) -> Vec<u8> {
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
pub(super) fn read_into(
    file: &Path,
    st: &SafeTensors,
    prefix: &str,
    like: &Mlp,
) -> crate::error::Result<Vec<Vec<f32>>> {
    named(prefix, like.parameters(), like)
        .into_iter()
        .map(|(name, shape, _)| {
            f32_tensor(file, st, &name, &shape, ("this scene needs", " (observation size or hidden width differ)"))
        })
        .collect()
}

/// The values of tensor `name` of a safetensors file, refused unless it is F32 of `shape` (`expected`: the
/// words before and after the shape in the error) and finite: no network or transition of a sound run
/// holds a NaN or an infinity.
pub(super) fn f32_tensor(
    file: &Path,
    st: &SafeTensors,
    name: &str,
    shape: &[usize],
    expected: (&str, &str),
) -> crate::error::Result<Vec<f32>> {
    let t = st.tensor(name).map_err(|_| format!("{}: no tensor {name:?}", file.display()))?;
    if t.dtype() != Dtype::F32 || t.shape() != shape {
        let (before, after) = expected;
        return Err(format!(
            "{}: tensor {name} is {:?} {:?}, {before} F32 {shape:?}{after}",
            file.display(),
            t.dtype(),
            t.shape()
        )
        .into());
    }
    let values: Vec<f32> = t.data().chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    match values.iter().position(|v| !v.is_finite()) {
        Some(i) => Err(format!(
            "{}: tensor {name} holds a non-finite value ({} at index {i}); refusing a broken checkpoint",
            file.display(),
            values[i]
        )
        .into()),
        None => Ok(values),
    }
}

/// What a safetensors file is read as: whose, which roles, trained on which scene (None: any).
pub(super) struct Expected<'a> {
    pub(super) species: &'a str,
    pub(super) roles: &'a [&'a str],
    pub(super) scene: Option<&'a str>,
}

/// A safetensors file's bytes, checked against what it is read as (its metadata). Its tensors are then
/// read (names, shapes, finite values) and last it is checked against the manifest ([`sealed`]), so a
/// file that is wrong in a way one can name is refused with that name, any other change by the manifest.
pub(super) fn read_as(path: &Path, expected: &Expected) -> crate::error::Result<Vec<u8>> {
    let bytes = read_file(path)?;
    check_metadata(path, &bytes, expected.species, expected.roles, expected.scene)?;
    Ok(bytes)
}

/// Checks a file's `bytes` against `entries` of the checkpoint's manifest, where it has one.
pub(super) fn sealed(
    path: &Path,
    bytes: &[u8],
    entries: Option<&std::collections::BTreeMap<String, Digest>>,
) -> crate::error::Result<()> {
    match entries {
        Some(entries) => {
            let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
            Manifest::check(entries, &name, path, bytes)
        }
        None => Ok(()),
    }
}

pub(super) fn read_file(path: &Path) -> crate::error::Result<Vec<u8>> {
    match std::fs::metadata(path) {
        Ok(m) if !m.is_file() => Err(format!("{}: not a regular file, not a checkpoint", path.display()).into()),
        Ok(_) => Ok(std::fs::read(path).map_err(|e| format!("{}: cannot read checkpoint: {e}", path.display()))?),
        Err(e) => Err(format!("{}: cannot read checkpoint: {e}", path.display()).into()),
    }
}

pub(super) fn parse<'a>(path: &Path, bytes: &'a [u8]) -> crate::error::Result<SafeTensors<'a>> {
    Ok(SafeTensors::deserialize(bytes)
        .map_err(|e| format!("{}: not a valid safetensors file ({e:?})", path.display()))?)
}

/// An actor file's bytes (as PyTorch names it) loaded into `like`.
pub(super) fn mlp_from(path: &Path, bytes: &[u8], like: &Mlp) -> crate::error::Result<Mlp> {
    let st = parse(path, bytes)?;
    let mut net = like.clone();
    net.set_parameters(&read_into(path, &st, "", like)?);
    Ok(net)
}
