//! `results/<experiment>/claims.csv`: each claim's fingerprint as it stood when the experiment's runs were
//! aggregated, so that a claim edited or added after its results existed is flagged in the reports
//! (hypotheses fixed before the runs). The one owner of that file.

use super::file::{Claim, Experiment};
use std::path::Path;

/// The file, beside `summary.csv`.
pub(crate) const FILE: &str = "claims.csv";

/// What a claim says, to the bit, as a short hash (BLAKE3, `blake3` crate): its text, variants, quantity,
/// the paper's value, margin, baseline and whether only a direction is claimed. Not its family, which sorts
/// claims for the adjustment rather than stating what a claim expects, and not `ours` (whether the direction
/// is the paper's or the project's), which names who expects it and leaves the test as it is.
pub(crate) fn fingerprint(claim: &Claim) -> String {
    hash(&format!("{}\u{1f}{}", claim.text, tested(claim)))
}

/// What a claim tests, without its words, as a short hash: [`fingerprint`] less the text. Its words may be
/// reworded after its results exist (the record above flags that); what it tests may not
/// (`registration.rs`).
pub(crate) fn test_fingerprint(claim: &Claim) -> String {
    hash(&tested(claim))
}

fn hash(canonical: &str) -> String {
    blake3::hash(canonical.as_bytes()).to_hex()[..16].to_string()
}

/// The fields of a claim that state its test, canonically, as every recorded fingerprint was made.
fn tested(claim: &Claim) -> String {
    let bits = |x: Option<f64>| x.map_or(String::from("-"), |x| format!("{:016x}", x.to_bits()));
    let canonical = format!(
        "{}\u{1f}{}\u{1f}{:?}\u{1f}{}\u{1f}{}\u{1f}{}\u{1f}{}",
        claim.variant,
        claim.versus.as_deref().unwrap_or("-"),
        claim.quantity,
        bits(claim.paper),
        bits(claim.margin),
        bits(claim.baseline),
        claim.direction_only
    );
    // A scale other than the default is part of the hypothesis; the default adds nothing, so every
    // fingerprint recorded before scales existed stands.
    let canonical = match claim.scale {
        super::file::Scale::Linear => canonical,
        scale => format!("{canonical}\u{1f}{scale:?}"),
    };
    // Likewise a level's own tolerance, which claims before tolerances lack (those take the rule's,
    // `verdict::tolerance`, set after their results: REPRODUCTION.md's preamble says so).
    let canonical = match claim.tolerance {
        None => canonical,
        Some(t) => format!("{canonical}\u{1f}tolerance {}", bits(Some(t))),
    };
    // Likewise a grid's test (its axis, level and crossing value), which claims before grids lack; a
    // boundary's direction only when not the default (a fall), so a test stated before directions could be
    // named keeps the fingerprint it was recorded with.
    match &claim.grid {
        None => canonical,
        Some(test) => format!("{canonical}\u{1f}{}", grid_statement(test)),
    }
}

/// A grid test as a claim's fingerprint states it ([`fingerprint`]): as written before a boundary's
/// direction could be named, with the direction added only when it is not the default fall.
fn grid_statement(test: &super::file::GridTest) -> String {
    use super::file::{Crossing::Falls, GridTest};
    match test {
        GridTest::Trend { .. } => format!("{test:?}"),
        GridTest::Boundary { axis, crosses, at, direction } => {
            let named = if *direction == Falls { String::new() } else { format!(", direction: {direction:?}") };
            format!("Boundary {{ axis: {axis:?}, crosses: {crosses:?}, at: {at:?}{named} }}")
        }
        GridTest::BoundaryShift { axis, crosses, direction } => {
            let named = if *direction == Falls { String::new() } else { format!(", direction: {direction:?}") };
            format!("BoundaryShift {{ axis: {axis:?}, crosses: {crosses:?}{named} }}")
        }
    }
}

/// How a claim stands against the fingerprints recorded with its experiment's results.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Stated {
    /// As recorded before (or, for a record begun late, when) its results existed.
    AsRecorded,
    /// Its text is recorded with another fingerprint: edited after its results existed.
    Edited,
    /// Its text is not recorded: added after its results existed.
    Added,
    /// Its text is not recorded, but a recorded claim no longer in the file had the same test under
    /// another text: reworded after its results existed, what it tests unchanged.
    Reworded,
    /// As recorded, but in another family than the one recorded: moved after its results existed.
    Moved,
    /// Nothing recorded (no results yet).
    Unknown,
}

impl Stated {
    /// The words a report adds to the claim's hypothesis; empty when nothing is to be said.
    pub(crate) fn flag(self) -> &'static str {
        match self {
            Stated::Edited => " — **edited after its results existed** (post hoc)",
            Stated::Added => " — **added after its results existed** (post hoc)",
            Stated::Reworded => " — reworded after its results existed (what it tests unchanged)",
            Stated::Moved => " — **moved to this family after its results existed** (post hoc)",
            Stated::AsRecorded | Stated::Unknown => "",
        }
    }
}

/// A claim as recorded: its fingerprint and its family ("" for its file's own; None in a record written
/// before families were recorded).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Recorded {
    pub(crate) fingerprint: String,
    pub(crate) family: Option<String>,
}

fn family_of(claim: &Claim) -> String {
    claim.family.clone().unwrap_or_default()
}

/// The recorded claims, by text, in the record's order; None without the file.
pub(crate) fn read(root: &Path) -> crate::error::Result<Option<Vec<(String, Recorded)>>> {
    let path = root.join(FILE);
    let mut text = String::new();
    let read = |f: std::fs::File| {
        std::io::Read::read_to_string(&mut std::io::Read::take(f, crate::io::MAX_TEXT_BYTES), &mut text)
    };
    match crate::io::open_input(&path).and_then(read) {
        Ok(_) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(format!("{}: {e}", path.display()).into()),
    }
    let bad = |e: csv::Error| format!("{}: {e}", path.display());
    let mut recorded = Vec::new();
    for row in csv::ReaderBuilder::new().flexible(true).from_reader(text.as_bytes()).records() {
        let row = row.map_err(bad)?;
        match (row.get(0), row.get(1)) {
            (Some(claim), Some(fingerprint)) => recorded.push((
                claim.to_string(),
                Recorded { fingerprint: fingerprint.to_string(), family: row.get(2).map(str::to_string) },
            )),
            _ => return Err(format!("{}: a row without claim and fingerprint", path.display()).into()),
        };
    }
    Ok(Some(recorded))
}

fn write(exp: &Experiment, recorded: &[(String, Recorded)]) -> crate::error::Result<()> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    let row = |w: &mut csv::Writer<Vec<u8>>, fields: [&str; 3]| w.write_record(fields).map_err(|e| e.to_string());
    row(&mut writer, ["claim", "fingerprint", "family"])?;
    for (claim, r) in recorded {
        row(&mut writer, [claim, &r.fingerprint, r.family.as_deref().unwrap_or_default()])?;
    }
    let bytes = writer.into_inner().map_err(|e| e.to_string())?;
    crate::io::write_file(&exp.root.join(FILE), crate::io::Existing::Replace, &bytes)
}

/// Records the claims of `exp` that are not recorded yet and may still be stated before their results:
/// every claim when nothing is recorded (a record begun late records the claims as they stand), else each
/// new text whose variants (`unfinished`: a variant some run of which has not finished) still have runs to
/// come. A recorded claim is never rewritten, so an edit after its results stays flagged. Called when an
/// experiment's runs start, and by the aggregation when it finds results without a record.
pub(crate) fn record(exp: &Experiment, unfinished: &dyn Fn(&str) -> bool) -> crate::error::Result<()> {
    let old = read(&exp.root)?;
    let mut recorded = old.clone().unwrap_or_default();
    for claim in &exp.spec.claims {
        let known = recorded.iter().any(|(text, _)| *text == claim.text);
        // A claim over the grid reads every cell.
        let cells = || exp.spec.variants.iter().filter(|v| !v.cell.is_empty()).any(|v| unfinished(&v.name));
        let to_come = match claim.grid {
            Some(_) => cells(),
            None => unfinished(&claim.variant) || claim.versus.as_deref().is_some_and(unfinished),
        };
        if !known && (old.is_none() || to_come) {
            recorded.push((
                claim.text.clone(),
                Recorded { fingerprint: fingerprint(claim), family: Some(family_of(claim)) },
            ));
        }
    }
    if old.as_ref() != Some(&recorded) {
        std::fs::create_dir_all(&exp.root).map_err(|e| format!("{}: {e}", exp.root.display()))?;
        write(exp, &recorded)?;
    }
    Ok(())
}

/// How `claim` stands against `recorded` ([`read`]).
pub(crate) fn stated(claim: &Claim, claims: &[Claim], recorded: Option<&[(String, Recorded)]>) -> Stated {
    let Some(recorded) = recorded else { return Stated::Unknown };
    // A recorded text that no claim of the file has now, whose fingerprint this claim's test gives
    // under that text: this claim, reworded.
    let reworded = || {
        recorded.iter().any(|(text, r)| {
            !claims.iter().any(|c| c.text == *text)
                && r.fingerprint == fingerprint(&Claim { text: text.clone(), ..claim.clone() })
        })
    };
    match recorded.iter().find(|(text, _)| *text == claim.text) {
        None if reworded() => Stated::Reworded,
        None => Stated::Added,
        Some((_, r)) if r.fingerprint != fingerprint(claim) => Stated::Edited,
        Some((_, r)) if r.family.as_ref().is_some_and(|f| *f != family_of(claim)) => Stated::Moved,
        Some(_) => Stated::AsRecorded,
    }
}
