//! From the runs' CSV files alone (never retraining): the paper's claims checked on the per-run values,
//! with the summaries (`summary.rs`) and figures (`figures.rs`) written beside them.

use super::claims::{chance_level, is_effect, verdict, ClaimResult, RunData, ALPHA, WINDOW};
use super::data::check_complete;
use super::figure_data;
use super::figures;
use super::file::Experiment;
use super::stats::{difference, estimate, holm, holm_levels};
use super::summary::{self, Summary};
use std::collections::BTreeMap;

/// Checks an experiment's claims on the `data` of its finished runs ([`load`]) and, when there are any,
/// writes its summaries and figures. Claims with no run yet say so.
pub fn aggregate(exp: &Experiment, data: &BTreeMap<usize, RunData>) -> crate::error::Result<Aggregated> {
    check_complete(exp, data)?;
    let written = !data.is_empty();
    let quantities = summary::columns(exp);
    let summary = summary::text(exp, data, &quantities);

    // The claims are computed from the per-run values alone (summary.csv), so that a clone without run
    // folders recomputes them from the committed summary exactly.
    let table = if written {
        Summary::parse(&summary, &exp.root.join("summary.csv"))?
    } else {
        Summary::read(&exp.root.join("summary.csv"))?.unwrap_or_default()
    };
    let drawn = figures::data(exp, data, &table, written)?;
    if drawn.is_some() {
        crate::io::own_dir(&exp.root.join("figures"))?;
    }
    let means = summary::means_text(exp, data, &quantities);
    let mut results = Vec::new();
    let mut saved = 0;
    for preset in &exp.spec.presets {
        for claim in &exp.spec.claims {
            let samples = |variant: &str| table.values(exp, preset, variant, &claim.quantity);
            let (ours, theirs) = (samples(&claim.variant), claim.versus.as_deref().map(samples));
            // Two variants whose runs are identical (a deterministic re-run, e.g. a switch that never acts)
            // are one sample, not two: no comparison, no p-value.
            let identical = theirs.as_ref().is_some_and(|t| t.len() >= 2 && *t == ours);
            // A change over training needs a first and a last window that do not overlap.
            let overlap = super::claims::compares_windows(&claim.quantity)
                && std::iter::once(&claim.variant)
                    .chain(&claim.versus)
                    .any(|v| table.episodes(preset, v).is_some_and(|n| n < 2 * WINDOW));
            let identical = identical || overlap;
            let e = match &theirs {
                Some(t) => difference(&ours, t),
                None => estimate(&ours),
            };
            let scene = exp.runs.iter().find(|r| r.preset == *preset && r.variant == claim.variant).map(|r| &r.scene);
            results.push(ClaimResult {
                experiment: exp.name.clone(),
                preset: preset.clone(),
                claim: claim.clone(),
                estimate: e,
                // The claim's own test: TOST for a claim of no effect, else the two-sided test of none.
                p: e.filter(|_| is_effect(claim) && !identical).and_then(|e| match claim.margin {
                    Some(m) => e.tost_p(m),
                    None => e.p_value(),
                }),
                p_holm: None,
                level: None,
                baseline: chance_level(exp, claim, scene),
                verdict: match (overlap, identical) {
                    (true, _) => OVERLAP.into(),
                    (false, true) => IDENTICAL.into(),
                    _ => String::new(),
                },
            });
        }
        if let Some(drawn) = &drawn {
            figures::draw(exp, preset, &table, drawn, &mut saved)?;
        }
    }
    // Families: the claims of one `family` name, all presets, adjusted together (Holm); claims without a
    // name are the experiment's family. Each test's interval is shown at its Holm step's level.
    let families: std::collections::BTreeSet<Option<String>> = results.iter().map(|r| r.claim.family.clone()).collect();
    for family in families {
        let tested: Vec<usize> =
            (0..results.len()).filter(|&i| results[i].p.is_some() && results[i].claim.family == family).collect();
        let p: Vec<f64> = tested.iter().map(|&i| results[i].p.unwrap_or(1.0)).collect();
        for ((&i, adjusted), level) in tested.iter().zip(holm(&p)).zip(holm_levels(&p, ALPHA)) {
            results[i].p_holm = Some(adjusted);
            results[i].level = Some(level);
        }
    }
    for r in results.iter_mut().filter(|r| r.verdict != IDENTICAL && r.verdict != OVERLAP) {
        r.verdict = verdict(&r.claim, r.estimate, r.p_holm, r.level, r.baseline);
    }
    if written {
        // The figure data before the summary it must match: a write that fails between them leaves the
        // old summary, which the next aggregation finds incomplete, never a new summary beside old curves.
        figure_data::write(exp, drawn.as_ref().expect("drawn from the run folders"))?;
        crate::io::write_file(&exp.root.join("summary.csv"), crate::io::Existing::Replace, summary.as_bytes())?;
        crate::io::write_file(&exp.root.join("summary-mean.csv"), crate::io::Existing::Replace, means.as_bytes())?;
    }
    Ok(Aggregated { results, summary: table, figures: drawn.is_some().then_some(saved), from_folders: written })
}

/// What [`aggregate`] found, and what it wrote.
pub struct Aggregated {
    pub results: Vec<ClaimResult>,
    /// The per-run values the claims were computed from (written now, or the committed summary.csv).
    pub summary: Summary,
    /// How many figures it drew (each as .svg and .png): from the run folders, or in a clone from the
    /// committed figure data. None when it drew none (a clone of a commit without figure data).
    pub figures: Option<usize>,
    /// Whether the run folders were here, so summary.csv, summary-mean.csv and figure-data.ron.gz were
    /// written from them (else the committed ones were read and left as they are).
    pub from_folders: bool,
}

/// The verdict on a change over training of runs shorter than two windows.
const OVERLAP: &str = "not measured: runs shorter than 200 episodes, so the first and last 100 episodes overlap";

/// The verdict on a comparison of two variants whose runs are identical.
const IDENTICAL: &str = "not a comparison: the two variants' runs are identical (one training, run twice)";
