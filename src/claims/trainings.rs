//! One training, counted once. A training is its resolved scene, seed included, and
//! the binary that made it: the same pair in two places is one deterministic training. Two experiments
//! hold one training either as one run folder (`shared_from`) or as a declared re-training
//! (`same_training_as`); a training found twice without either is refused when results are aggregated,
//! before anything is written, so no training is counted as two pieces of evidence or two in the suite's
//! totals ([`count`]).

use super::file::Experiment;
use super::results::RunData;
use super::summary::Summary;
use std::collections::BTreeMap;

/// A finished training an experiment made itself (not a run it shares from another experiment).
#[derive(Clone, Debug)]
pub(crate) struct Training {
    pub(crate) experiment: String,
    /// The run's index among its experiment's runs.
    pub(crate) run: usize,
    pub(crate) preset: String,
    pub(crate) variant: String,
    pub(crate) seed: u64,
    /// Its identity: the scene's id ([`crate::store::tensors::scene_id`]) and the binary, with the
    /// kernel family its variant runs on when it names one (`kernels:`: the same scene, seed and binary on
    /// another family is another training).
    pub(crate) key: (String, String),
    /// The variant's `same_training_as`, when it declares one.
    pub(crate) declared: Option<String>,
    /// Its own wall clock (`metrics.csv`'s `wall_seconds`), 0 where not finite.
    pub(crate) seconds: f64,
    /// The numbers of its training (its summary row's columns but the evaluations, cross-play and wall
    /// clock), to the bit, by column (from a summary only).
    pub(crate) outcome: Option<BTreeMap<String, u64>>,
}

impl Training {
    fn new(exp: &Experiment, i: usize, binary: &str, seconds: f64) -> Training {
        let run = &exp.runs[i];
        Training {
            experiment: exp.name.clone(),
            run: i,
            preset: run.preset.clone(),
            variant: run.variant.clone(),
            seed: run.seed,
            key: (
                crate::store::tensors::scene_id(&run.scene),
                Training::binary_on(binary, run.kernels.map(|k| k.name())),
            ),
            declared: run.same_training_as.clone(),
            seconds: if seconds.is_finite() { seconds.max(0.0) } else { 0.0 },
            outcome: None,
        }
    }

    /// The binary part of a training's identity: the binary, and the variant's own kernel family if any.
    fn binary_on(binary: &str, kernels: Option<&str>) -> String {
        match kernels {
            Some(family) => format!("{binary} on {family} kernels"),
            None => binary.to_string(),
        }
    }

    fn name(&self) -> String {
        format!("{}/{}/{}/seed{}", self.experiment, self.preset, self.variant, self.seed)
    }

    /// Whether this training declares itself a re-training of `other` (same preset and seed).
    fn declares(&self, other: &Training) -> bool {
        // "EXPERIMENT/VARIANT": an experiment's name (its file's stem) holds no '/', a variant's may.
        self.declared.as_deref().and_then(|d| d.split_once('/'))
            == Some((other.experiment.as_str(), other.variant.as_str()))
            && (self.preset.as_str(), self.seed) == (other.preset.as_str(), other.seed)
    }
}

/// The trainings of an experiment's rows (`summary`): each finished run it trained itself, once (a run
/// whose rows two machines' summaries both hold is carried once, `carry`).
pub(crate) fn from_summary(exp: &Experiment, summary: &Summary) -> Vec<Training> {
    let wall = summary.columns.iter().position(|c| c == crate::store::schema::WALL_SECONDS);
    let mut seen = std::collections::BTreeSet::new();
    summary
        .runs(exp)
        .into_iter()
        .filter(|(i, row)| exp.runs[*i].shared_from.is_none() && row.shared_from.is_empty() && seen.insert(*i))
        .map(|(i, row)| {
            // The numbers of the training itself: not its evaluations, cross-play or fitted rules (read-outs
            // made after it), nor its wall clock.
            let training = |c: &str| {
                !["eval_", "crossplay_", "distilled_"].iter().any(|p| c.starts_with(p))
                    && c != crate::store::schema::WALL_SECONDS
            };
            let bits = summary.columns.iter().zip(&row.values).filter(|(c, _)| training(c));
            Training {
                outcome: Some(bits.map(|(c, v)| (c.clone(), v.to_bits())).collect()),
                ..Training::new(exp, i, &row.binary, wall.map_or(0.0, |w| row.values[w]))
            }
        })
        .collect()
}

/// The trainings of an experiment before it is aggregated: its finished run folders (`data`), and the
/// runs its committed summary holds that are not here (finished elsewhere, or a clone without folders).
pub(crate) fn before_aggregation(
    exp: &Experiment,
    data: &BTreeMap<usize, RunData>,
) -> crate::error::Result<Vec<Training>> {
    let mut trainings: Vec<Training> = data
        .iter()
        .filter(|(i, _)| exp.runs[**i].shared_from.is_none())
        .map(|(i, d)| Training::new(exp, *i, &d.binaries.join(" "), d.wall_seconds))
        .collect();
    if let Some(committed) = Summary::read(&exp.summary_path())? {
        trainings.extend(from_summary(exp, &committed).into_iter().filter(|t| !data.contains_key(&t.run)));
    }
    Ok(trainings)
}

/// The first training number in which two trainings' outcomes differ (of the columns both hold), or
/// None when every one is equal to the bit; None too when either outcome is unknown (a run folder not yet
/// summarized).
fn outcome_difference(a: &Training, b: &Training) -> Option<String> {
    let (Some(a), Some(b)) = (&a.outcome, &b.outcome) else { return None };
    a.iter().find(|(c, v)| b.get(*c).is_some_and(|w| w != *v)).map(|(c, _)| c.clone())
}

/// Refuses a training found twice (the same scene and seed by the same binary) unless all but one of its
/// holders declare that one (`same_training_as`), and a declaration that is not true (the run it names,
/// when finished, is another training): one line naming both runs and the ways out. A declared
/// re-training by another binary is the same training when every training number of the two equals the
/// other's to the bit (checked where both are summarized: a re-training is not a second sample).
pub(crate) fn check_once(trainings: &[Training]) -> crate::error::Result<()> {
    for t in trainings {
        let other_training =
            |o: &&Training| o.key.0 != t.key.0 || (o.key.1 != t.key.1 && outcome_difference(o, t).is_some());
        if let Some(o) = trainings.iter().find(|o| t.declares(o)).filter(other_training) {
            let why = match o.key.0 == t.key.0 {
                true => format!(
                    "binaries {} and {}, whose {} differs",
                    o.key.1,
                    t.key.1,
                    outcome_difference(o, t).unwrap_or_default()
                ),
                false => "another scene".to_string(),
            };
            return Err(format!(
                "{} declares same_training_as \"{}/{}\", but {} is not the same training ({why}); nothing written: remove the declaration, or train both by one binary",
                t.name(),
                o.experiment,
                o.variant,
                o.name()
            )
            .into());
        }
    }
    let mut groups: Vec<Vec<&Training>> = Vec::new();
    for t in trainings {
        match groups.iter_mut().find(|g| g[0].key == t.key) {
            Some(g) => g.push(t),
            None => groups.push(vec![t]),
        }
    }
    for g in groups.iter().filter(|g| g.len() > 1) {
        // The holders that declare no other: one owner, or the repeat is undeclared.
        let owners: Vec<&&Training> = g.iter().filter(|t| !g.iter().any(|o| t.declares(o))).collect();
        let (o, t) = match owners.as_slice() {
            [_] => continue,
            [o, t, ..] => (**o, **t),
            [] => (g[0], g[1]),
        };
        return Err(format!(
            "{} and {} are one training (the same resolved scene and seed, by binary {}); nothing written: share the run (shared_from) or declare the re-training in one of the files (same_training_as: \"{}/{}\" in {}'s, or \"{}/{}\" in {}'s)",
            o.name(),
            t.name(),
            t.key.1,
            o.experiment,
            o.variant,
            t.experiment,
            t.experiment,
            t.variant,
            o.experiment
        )
        .into());
    }
    Ok(())
}

/// How many trainings are finished, how many distinct, and the wall-clock seconds of the distinct ones
/// (the first of each kept). A declared re-training ([`check_once`]) is its owner's training.
pub(crate) fn count(trainings: &[Training]) -> (usize, usize, f64) {
    let mut distinct: BTreeMap<&(String, String), f64> = BTreeMap::new();
    for t in trainings {
        let owner = trainings.iter().find(|o| t.declares(o)).map_or(&t.key, |o| &o.key);
        distinct.entry(owner).or_insert(t.seconds);
    }
    // + 0.0: an empty f64 sum is −0.0, which would print as "-0.0 h".
    (trainings.len(), distinct.len(), distinct.values().sum::<f64>() + 0.0)
}

/// Distinct trainings (of another scene) whose every training number equals another's of the same preset
/// and seed to the bit, in whichever experiment: a switch that never acted (the energy budget in 500-step
/// episodes). They are trained and counted; the report names each pair of variants and how many seeds.
pub(crate) fn same_outcomes(trainings: &[Training]) -> BTreeMap<(String, String), usize> {
    // The columns both rows have (files differ in evaluations, not in training columns), DoA among them.
    let same_numbers = |o: &Training, t: &Training| {
        matches!((&o.outcome, &t.outcome), (Some(a), Some(_)) if a.contains_key("doa_last100"))
            && outcome_difference(o, t).is_none()
    };
    let mut same = BTreeMap::new();
    for (k, t) in trainings.iter().enumerate() {
        let earlier = trainings[..k].iter().find(|o| {
            (o.preset.as_str(), o.seed) == (t.preset.as_str(), t.seed) && o.key.0 != t.key.0 && same_numbers(o, t)
        });
        if let Some(o) = earlier {
            let name = |t: &Training| format!("{}/{}", t.experiment, t.variant);
            *same.entry((name(o), name(t))).or_insert(0) += 1;
        }
    }
    same
}

#[cfg(test)]
mod tests {
    use super::*;

    fn training(experiment: &str, variant: &str, seed: u64, scene: &str, declared: Option<&str>) -> Training {
        Training {
            experiment: experiment.into(),
            run: seed as usize,
            preset: "paper".into(),
            variant: variant.into(),
            seed,
            key: (format!("{scene}{seed}"), "b".into()),
            declared: declared.map(String::from),
            seconds: 100.0,
            outcome: Some([("doa_last100".to_string(), seed), ("dos_last100".to_string(), 7)].into()),
        }
    }

    #[test]
    fn a_training_held_twice_is_refused_unless_declared_and_counted_once() {
        let owner = training("a", "seeing", 1, "s", None);
        let again = training("b", "again", 1, "s", None);
        let other_seed = training("b", "again", 2, "s", None);
        let e = check_once(&[owner.clone(), again.clone(), other_seed.clone()]).unwrap_err().to_string();
        assert!(e.starts_with("a/paper/seeing/seed1 and b/paper/again/seed1 are one training"), "{e}");
        assert!(e.contains("same_training_as: \"a/seeing\" in b's, or \"b/again\" in a's"), "{e}");
        // Declared: accepted, whichever comes first. A declaration of another variant is not one.
        let declared = training("b", "again", 1, "s", Some("a/seeing"));
        check_once(&[owner.clone(), declared.clone(), other_seed.clone()]).unwrap();
        check_once(&[declared.clone(), owner.clone()]).unwrap();
        assert!(check_once(&[owner.clone(), training("b", "again", 1, "s", Some("a/blind"))]).is_err());
        // Two files re-training one owner, the owner between them: one owner, two declarations.
        let third = training("c", "once more", 1, "s", Some("a/seeing"));
        check_once(&[declared.clone(), owner.clone(), third.clone()]).unwrap();
        // Two that declare nothing: refused, naming those two.
        let e = check_once(&[declared.clone(), owner.clone(), training("c", "once more", 1, "s", None)]).unwrap_err();
        assert!(e.to_string().starts_with("a/paper/seeing/seed1 and c/paper/once more/seed1"), "{e}");
        // The same scene and seed by one binary on another kernel family (`kernels:`): another training.
        let mut bf16 = training("a", "bf16", 1, "s", None);
        bf16.key.1 = Training::binary_on("b", Some("avx512-bf16"));
        check_once(&[owner.clone(), bf16]).unwrap();
        // Another binary that gives every training number to the bit: the same training, counted once.
        let mut rebuilt = owner.clone();
        rebuilt.key.1 = "other".into();
        check_once(&[rebuilt.clone(), declared.clone()]).unwrap();
        assert_eq!(count(&[rebuilt.clone(), declared.clone()]), (2, 1, 100.0));
        // A declaration that is not true: another binary whose training numbers differ.
        rebuilt.outcome.as_mut().unwrap().insert("dos_last100".into(), 8);
        let e = check_once(&[rebuilt.clone(), declared.clone()]).unwrap_err().to_string();
        assert!(
            e.starts_with("b/paper/again/seed1 declares same_training_as \"a/seeing\", but a/paper/seeing/seed1 is not the same training (binaries other and b, whose dos_last100 differs)"),
            "{e}"
        );
        // Numbers not yet at hand (a run folder before it is summarized): judged once they are.
        let mut unsummarized = rebuilt.clone();
        unsummarized.outcome = None;
        check_once(&[unsummarized, declared.clone()]).unwrap();
        assert_eq!(count(&[owner.clone(), declared, other_seed]), (3, 2, 200.0));
        assert_eq!(count(&[]), (0, 0, 0.0));
        // Another scene with the same training numbers: a switch that never acted, named with its twin.
        let idle = training("c", "switch", 1, "t", None);
        let same = same_outcomes(&[owner.clone(), idle.clone(), training("c", "switch", 2, "t", None)]);
        assert_eq!(same, [(("a/seeing".to_string(), "c/switch".to_string()), 1)].into());
        let mut moved = idle;
        moved.outcome.as_mut().unwrap().insert("dos_last100".into(), 8);
        assert!(same_outcomes(&[owner.clone(), moved]).is_empty());
        // The same scene by another binary is not "a switch that never acted".
        rebuilt.outcome = owner.outcome.clone();
        assert!(same_outcomes(&[owner, rebuilt]).is_empty());
    }
}
