//! `results/<experiment>/claims.csv`: each claim's fingerprint as it stood when the experiment's runs were
//! aggregated, so that a claim edited or added after its results existed is flagged in the reports
//! (issue 36: hypotheses fixed before the runs). The one owner of that file.

use super::file::{Claim, Experiment};
use std::collections::BTreeMap;
use std::path::Path;

/// The file, beside `summary.csv`.
pub const FILE: &str = "claims.csv";

/// What a claim says, to the bit, as a short hash (BLAKE3, `blake3` crate): its text, variants, quantity,
/// the paper's value, margin, baseline and whether only a direction is claimed. Not its family, which sorts
/// claims for the adjustment rather than stating what a claim expects.
pub fn fingerprint(claim: &Claim) -> String {
    let bits = |x: Option<f64>| x.map_or(String::from("-"), |x| format!("{:016x}", x.to_bits()));
    let canonical = format!(
        "{}\u{1f}{}\u{1f}{}\u{1f}{:?}\u{1f}{}\u{1f}{}\u{1f}{}\u{1f}{}",
        claim.text,
        claim.variant,
        claim.versus.as_deref().unwrap_or("-"),
        claim.quantity,
        bits(claim.paper),
        bits(claim.margin),
        bits(claim.baseline),
        claim.direction_only
    );
    blake3::hash(canonical.as_bytes()).to_hex()[..16].to_string()
}

/// How a claim stands against the fingerprints recorded with its experiment's results.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stated {
    /// As recorded when its runs were aggregated.
    AsRecorded,
    /// Its text is recorded with another fingerprint: edited after its results existed.
    Edited,
    /// Its text is not recorded: added after its results existed.
    Added,
    /// Nothing recorded (no results yet).
    Unknown,
}

impl Stated {
    /// The words a report adds to the claim's hypothesis; empty when nothing is to be said.
    pub fn flag(self) -> &'static str {
        match self {
            Stated::Edited => " — **edited after its results existed** (post hoc)",
            Stated::Added => " — **added after its results existed** (post hoc)",
            Stated::AsRecorded | Stated::Unknown => "",
        }
    }
}

/// The recorded fingerprints, by claim text; None without the file.
pub fn read(root: &Path) -> crate::error::Result<Option<BTreeMap<String, String>>> {
    let path = root.join(FILE);
    let text = match std::fs::read_to_string(&path) {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(format!("{}: {e}", path.display()).into()),
    };
    let bad = |e: csv::Error| format!("{}: {e}", path.display());
    let mut recorded = BTreeMap::new();
    for row in csv::Reader::from_reader(text.as_bytes()).records() {
        let row = row.map_err(bad)?;
        match (row.get(0), row.get(1)) {
            (Some(claim), Some(fingerprint)) => recorded.insert(claim.to_string(), fingerprint.to_string()),
            _ => return Err(format!("{}: a row without claim and fingerprint", path.display()).into()),
        };
    }
    Ok(Some(recorded))
}

/// Records every claim of `exp` as it stands now.
pub fn write(exp: &Experiment) -> crate::error::Result<()> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    let row = |w: &mut csv::Writer<Vec<u8>>, fields: [&str; 2]| w.write_record(fields).map_err(|e| e.to_string());
    row(&mut writer, ["claim", "fingerprint"])?;
    for claim in &exp.spec.claims {
        row(&mut writer, [&claim.text, &fingerprint(claim)])?;
    }
    let bytes = writer.into_inner().map_err(|e| e.to_string())?;
    crate::io::write_file(&exp.root.join(FILE), crate::io::Existing::Replace, &bytes)
}

/// How `claim` stands against `recorded` ([`read`]).
pub fn stated(claim: &Claim, recorded: Option<&BTreeMap<String, String>>) -> Stated {
    match recorded.map(|r| r.get(&claim.text)) {
        None => Stated::Unknown,
        Some(None) => Stated::Added,
        Some(Some(f)) if *f != fingerprint(claim) => Stated::Edited,
        Some(Some(_)) => Stated::AsRecorded,
    }
}
