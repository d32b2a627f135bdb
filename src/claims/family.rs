//! A family's claims judged together: Holm's adjustment over every test of one family, whichever files
//! and presets its claims are in, and each claim's verdict from its adjusted test.

use super::results::ClaimResult;
use super::stats::{holm, holm_levels};
use super::verdict::{is_effect, verdict, Outcome, ALPHA};

/// Adjusts every tested claim of `results` within its family and judges every claim. A family is the
/// claims of one `family` name, whichever experiment files and presets they are in (a claim without a name
/// is its own experiment's family); Holm's procedure runs over it, and each test's interval is shown at
/// its Holm step's level. A test that reads the same samples in the same way as an earlier test of its
/// family (the same runs, the same quantity: e.g. a variant shared from another experiment) is that test,
/// counted once: the first of them in `results`' order (the files' order) is tested, the others name it.
pub(crate) fn adjust(results: &mut [ClaimResult]) {
    let key = |r: &ClaimResult| match &r.claim.family {
        Some(name) => (name.clone(), String::new()),
        None => (String::new(), r.experiment.clone()),
    };
    let families: std::collections::BTreeSet<(String, String)> = results.iter().map(key).collect();
    for family in families {
        let members: Vec<usize> =
            (0..results.len()).filter(|&i| results[i].p.is_some() && key(&results[i]) == family).collect();
        let mut tested: Vec<usize> = Vec::new();
        let mut repeats: Vec<(usize, usize)> = Vec::new();
        for &i in &members {
            match tested.iter().find(|&&j| results[j].same_test == results[i].same_test) {
                Some(&j) => repeats.push((i, j)),
                None => tested.push(i),
            }
        }
        let p: Vec<f64> = tested.iter().map(|&i| results[i].p.unwrap_or(1.0)).collect();
        for ((&i, adjusted), level) in tested.iter().zip(holm(&p)).zip(holm_levels(&p, ALPHA)) {
            results[i].p_holm = Some(adjusted);
            results[i].level = Some(level);
        }
        for &i in &members {
            results[i].family_tests = tested.len();
        }
        for (i, j) in repeats {
            let (p_holm, level) = (results[j].p_holm, results[j].level);
            let first = format!("{} / {} / {}", results[j].experiment, results[j].preset, results[j].claim.text);
            let r = &mut results[i];
            (r.p_holm, r.level, r.same_as) = (p_holm, level, Some(first));
        }
    }
    // A verdict given before the tests (identical runs, overlapping windows, in progress) stands.
    for r in results.iter_mut().filter(|r| r.verdict.is_none()) {
        let mut judged = match (&r.claim.grid, &r.resamples) {
            (Some(_), Some(resamples)) => {
                super::grid::bootstrap_verdict(&r.claim, r.estimate, resamples, r.p_holm, r.level)
            }
            _ => verdict(&r.claim, r.estimate, r.p_holm, r.level, r.baseline),
        };
        if let Some(first) = &r.same_as {
            judged.note(&format!("; the same test as {first}, counted once in its family"));
        }
        if let Some(caveat) = &r.caveat {
            judged.note(caveat);
        }
        r.verdict = Some(judged);
    }
    say_where_a_level_and_its_contrast_disagree(results);
}

/// How a level's verdict says that it disagrees with its contrast (read by `paper_table`).
pub(crate) const DISAGREES: &str = "disagrees with the primary contrast";

/// One sentence of the paper often gives a level and the contrast it implies ("at R = D/3, DoA drops to
/// 0.75", against 0.82 at R = D): the contrast (the variant against its base, the same quantity) is the
/// primary test and the level a secondary row, which must not contradict it silently. Where one is
/// reproduced and the other is not, both rows say so.
fn say_where_a_level_and_its_contrast_disagree(results: &mut [ClaimResult]) {
    // Reproduced or in the paper's direction (an equivalence is never a level's contrast: those have no margin).
    let reproduced = |r: &ClaimResult| {
        r.verdict
            .as_ref()
            .is_some_and(|v| matches!(v.outcome, Outcome::Reproduced | Outcome::DirectionReproduced { .. }))
    };
    let word = |r: &ClaimResult| r.verdict.as_ref().map_or(String::new(), |v| v.word().to_string());
    let mut notes: Vec<(usize, String)> = Vec::new();
    for (i, level) in results.iter().enumerate() {
        if level.claim.versus.is_some() || level.claim.paper.is_none() || is_effect(&level.claim) {
            continue;
        }
        let contrast = results.iter().position(|c| {
            c.experiment == level.experiment
                && c.preset == level.preset
                && c.claim.variant == level.claim.variant
                && c.claim.versus.is_some()
                && c.claim.paper.is_some()
                && c.claim.quantity == level.claim.quantity
        });
        if let Some(j) = contrast {
            let c = &results[j];
            if reproduced(level) != reproduced(c) {
                notes.push((
                    i,
                    format!(
                        "; {DISAGREES} \"{}\" ({}): the contrast decides the paper's sentence",
                        c.claim.text,
                        word(c)
                    ),
                ));
                notes.push((
                    j,
                    format!(
                        "; its secondary level row \"{}\" is {} (the contrast decides)",
                        level.claim.text,
                        word(level)
                    ),
                ));
            }
        }
    }
    for (i, note) in notes {
        if let Some(v) = &mut results[i].verdict {
            v.note(&note);
        }
    }
}
