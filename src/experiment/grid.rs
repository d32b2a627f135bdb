//! An experiment's grid (`grid:` in its file): one or two axes of levels expanded into one variant per
//! cell, and the claims that read it (`GridTest`): a trend along an axis, the boundary where a quantity
//! crosses a value, and how that boundary moves with the other axis. The field maps collective states over
//! two parameters so (Couzin et al. 2002, Fig. 2; Tunstrøm et al. 2013), and a trend over every level
//! decides with fewer seeds than pairs of levels against a standard arm.

use super::file::{Axis, ExperimentFile, GridTest, Level, VariantFile};
use crate::scene::{parse_ron, ScenePatch};

/// At most this many axes: a map is drawn over two.
pub(crate) const MAX_AXES: usize = 2;

/// The patch that sets the scene number at `path` ("species.prey.max_speed") to `value`, as a scene file
/// would write it, so that a path naming no field is refused as a scene file's unknown field is.
fn patch_at(path: &str, value: f64) -> Result<ScenePatch, String> {
    fn fields(segments: &[&str], value: f64) -> Result<String, String> {
        match segments {
            [] => Err("is empty".into()),
            ["species"] => Err("names no species (species.NAME.FIELD)".into()),
            [field] => Ok(format!("{field}: {value}")),
            ["species", name, rest @ ..] => Ok(format!("species: [(name: {name:?}, {})]", fields(rest, value)?)),
            [field, rest @ ..] => Ok(format!("{field}: ({})", fields(rest, value)?)),
        }
    }
    let segments: Vec<&str> = path.split('.').collect();
    if segments.iter().any(|s| s.is_empty() || !s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')) {
        return Err(format!("path {path:?} is not a dotted path of scene fields (e.g. \"species.prey.max_speed\")"));
    }
    let text = format!("({})", fields(&segments, value).map_err(|m| format!("path {path:?} {m}"))?);
    parse_ron::<ScenePatch>(&text, path).map_err(|e| format!("path {path:?}: {}", e.message))
}

/// Resolves each axis to its levels (a `path` and `values` become levels labelled by the values) and
/// appends one variant per cell to the file's variants. Err is (field, message).
pub(crate) fn expand(spec: &mut ExperimentFile) -> Result<(), (String, String)> {
    if spec.grid.len() > MAX_AXES {
        return Err(("grid".into(), format!("at most {MAX_AXES} axes (got {})", spec.grid.len())));
    }
    for axis in &mut spec.grid {
        let field = |f: &str| format!("grid[{}].{f}", axis.name);
        if axis.name.trim().is_empty() {
            return Err(("grid".into(), "every axis needs a name".into()));
        }
        match (&axis.path, axis.values.is_empty(), axis.levels.is_empty()) {
            (Some(path), false, true) => {
                let path = path.clone();
                for &value in &axis.values {
                    if !value.is_finite() {
                        return Err((field("values"), format!("must be finite numbers (got {value})")));
                    }
                    let patch = patch_at(&path, value).map_err(|m| (field("path"), m))?;
                    axis.levels.push(Level { label: format!("{value}"), value, patch });
                }
            }
            (None, true, false) => {}
            _ => {
                return Err((
                    field("levels"),
                    "give either path and values, or levels (label, value, patch), and at least one level".into(),
                ))
            }
        }
        for pair in axis.levels.windows(2) {
            if !(pair[0].value < pair[1].value) {
                return Err((
                    field("levels"),
                    format!("values must increase along the axis ({} then {})", pair[0].value, pair[1].value),
                ));
            }
        }
        if let Some(level) = axis.levels.iter().find(|l| !l.value.is_finite() || l.label.trim().is_empty()) {
            return Err((field("levels"), format!("level {:?}: needs a label and a finite value", level.label)));
        }
    }
    if let [a, b] = &spec.grid[..] {
        if a.name == b.name {
            return Err(("grid".into(), format!("two axes named {:?}", a.name)));
        }
    }
    for cell in cells(&spec.grid) {
        let levels: Vec<&Level> = cell.iter().zip(&spec.grid).map(|(&i, axis)| &axis.levels[i]).collect();
        spec.variants.push(VariantFile {
            name: levels.iter().map(|l| l.label.as_str()).collect::<Vec<_>>().join(", "),
            patch: ScenePatch::default(),
            shared_from: None,
            same_training_as: None,
            then: levels.iter().map(|l| l.patch.clone()).collect(),
            cell,
        });
    }
    Ok(())
}

/// Every cell of the axes, the first axis slowest (its level indices).
fn cells(axes: &[Axis]) -> Vec<Vec<usize>> {
    axes.iter().fold(vec![Vec::new()], |cells, axis| {
        cells
            .into_iter()
            .flat_map(|cell| {
                (0..axis.levels.len()).map(move |i| {
                    let mut cell = cell.clone();
                    cell.push(i);
                    cell
                })
            })
            .collect()
    })
}

/// What a grid claim reads: the index of the axis it runs along, the cells along it (in the axis's
/// order), and for a shift the other axis. Err names what is wrong.
pub(crate) struct Along<'a> {
    pub(crate) axis: usize,
    /// The variant of each level along the axis, for a trend or a boundary (the other axis held at `at`),
    /// or for a shift, one such row per level of the other axis.
    pub(crate) rows: Vec<Vec<&'a VariantFile>>,
}

/// Checks a grid claim against the file's grid and finds the cells it reads.
pub(crate) fn along<'a>(spec: &'a ExperimentFile, test: &GridTest) -> Result<Along<'a>, String> {
    let (name, at, shift) = match test {
        GridTest::Trend { axis, at } => (axis, at.as_deref(), false),
        GridTest::Boundary { axis, at, crosses } => {
            finite(*crosses)?;
            (axis, at.as_deref(), false)
        }
        GridTest::BoundaryShift { axis, crosses } => {
            finite(*crosses)?;
            (axis, None, true)
        }
    };
    let Some(axis) = spec.grid.iter().position(|a| &a.name == name) else {
        let known: Vec<&str> = spec.grid.iter().map(|a| a.name.as_str()).collect();
        return Err(format!("no grid axis named {name:?} (the file's: {known:?})"));
    };
    if spec.grid[axis].levels.len() < 2 {
        return Err(format!("axis {name:?} has one level: a trend or a boundary needs two or more"));
    }
    let other = (spec.grid.len() == 2).then_some(1 - axis);
    let row = |level: Option<usize>| -> Vec<&'a VariantFile> {
        (0..spec.grid[axis].levels.len())
            .map(|i| {
                spec.variants
                    .iter()
                    .find(|v| v.cell.get(axis) == Some(&i) && other.is_none_or(|o| v.cell.get(o) == level.as_ref()))
                    .expect("every cell of the grid is a variant")
            })
            .collect()
    };
    let rows = match (other, at, shift) {
        (None, None, false) => vec![row(None)],
        (None, _, true) => return Err("BoundaryShift needs a grid of two axes".into()),
        (None, Some(_), false) => return Err("at: names a level of the other axis, and this grid has one".into()),
        (Some(o), None, false) => {
            return Err(format!("at: must name the level of {:?} the claim holds fixed", spec.grid[o].name))
        }
        (Some(o), Some(label), false) => match spec.grid[o].levels.iter().position(|l| l.label == label) {
            Some(level) => vec![row(Some(level))],
            None => return Err(format!("at: {:?} is no level of {:?}", label, spec.grid[o].name)),
        },
        (Some(o), _, true) => (0..spec.grid[o].levels.len()).map(|l| row(Some(l))).collect(),
    };
    Ok(Along { axis, rows })
}

fn finite(x: f64) -> Result<(), String> {
    match x.is_finite() {
        true => Ok(()),
        false => Err(format!("crosses must be a finite number (got {x})")),
    }
}
