//! Can `--distill` tell which terms a swarm's rule has? Prey that follow a known zonal rule, with and
//! without its alignment term, chased by the same rule-based predators, read as a trained swarm is read.

use super::record::coevo;

/// A zonal prey rule in the standard scene's metres (a 2 m torus): repulsion within 0.1 m, alignment to
/// 0.4 m with gain `alignment`, attraction to 1 m, evasion of predators within 0.6 m.
fn zonal(alignment: f64) -> String {
    format!(
        "Zonal((repulsion_radius: 0.1, alignment_radius: 0.4, attraction_radius: 1.0, evasion_radius: 0.6, \
         turn: (bias: 0.0, persistence: 0.0, repulsion: -0.3, alignment: {alignment}, attraction: 0.1, evasion: -0.4), \
         thrust: (bias: 0.6, speed: 0.0, repulsion: -0.2, attraction: 0.1, evasion: -0.3)))"
    )
}

/// Per form, the prey's terms as `--distill` reports them on a swarm of 50 prey following `rule` among
/// 3 chasing predators: (name, per-SD gain interval, held-out ΔR² interval).
type Terms = Vec<(String, [f64; 2], [f64; 2])>;

fn read(dir: &std::path::Path, name: &str, rule: &str) -> [Terms; 2] {
    let text = std::fs::read_to_string("scenes/standard.ron").unwrap();
    let scene = text
        .replace(
            r#"(name: "predator", count: 3, policy: Learned)"#,
            r#"(name: "predator", count: 3, policy: ChaseNearest)"#,
        )
        .replace(
            r#"(name: "prey", count: 10, policy: Learned)"#,
            &format!(r#"(name: "prey", count: 50, policy: {rule})"#),
        );
    let (file, run) = (dir.join(format!("{name}.ron")), dir.join(name));
    std::fs::write(&file, scene).unwrap();
    let (file, run) = (file.to_str().unwrap(), run.to_str().unwrap());
    // Nothing learns: one episode makes the run folder the read-out takes.
    let o = coevo(&["--train", "--scene", file, "--episodes", "1", "--out", run, "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = coevo(&["--distill", run, "--episodes", "2", "--steps", "300", "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let fitted =
        coevo::analysis::distill::DistilledFile::read(&std::path::Path::new(run).join("distilled.ron")).unwrap();
    [coevo::scene::RuleForm::Memoryless, coevo::scene::RuleForm::Binned].map(|form| {
        let prey = fitted
            .species
            .iter()
            .find(|d| d.species == "prey" && d.form == form)
            .expect("a rule fitted to the rule-driven prey");
        coevo::analysis::distill::term_intervals(prey)
    })
}

fn term<'a>(terms: &'a [(String, [f64; 2], [f64; 2])], name: &str) -> &'a (String, [f64; 2], [f64; 2]) {
    terms.iter().find(|t| t.0 == name).unwrap_or_else(|| panic!("no term {name} in {terms:?}"))
}

#[test]
fn the_read_out_finds_alignment_where_the_rule_has_it_and_not_where_it_has_none() {
    let dir = tempfile::tempdir().unwrap();
    let [with, with_binned] = read(dir.path(), "with", &zonal(0.3));
    let [without, without_binned] = read(dir.path(), "without", &zonal(0.0));
    // With alignment: its per-SD gain's interval lies above zero, and it adds held-out variance explained.
    let (_, gain, held_out) = term(&with, "turn.alignment");
    assert!(gain[0] > 0.0 && held_out[0] > 0.0, "with alignment: {with:?}");
    // Without: the gain's interval lies within ±0.02 per SD and the term adds nothing out of sample (at
    // most 0.005 of ΔR²): the margins `experiments/known-rules.ron` judges rules without alignment by (the
    // clamped actions can leave a gain of the order of 1e-5, whose interval need not hold zero exactly).
    let (_, gain, held_out) = term(&without, "turn.alignment");
    assert!(gain[0] > -0.02 && gain[1] < 0.02 && held_out[1] < 0.005, "without alignment: {without:?}");
    // Evasion is in both rules, and found in both.
    for terms in [&with, &without] {
        let (_, gain, held_out) = term(terms, "turn.evasion");
        assert!(gain[1] < 0.0 && held_out[0] > 0.0, "evasion: {terms:?}");
    }
    // The binned rule (a gain per distance bin) as a whole group per kind: alignment adds held-out
    // variance explained where the rule has it and at most 0.005 where it has none; evasion in both.
    let (_, _, held_out) = term(&with_binned, "turn.alignment");
    assert!(held_out[0] > 0.0, "binned, with alignment: {with_binned:?}");
    let (_, _, held_out) = term(&without_binned, "turn.alignment");
    assert!(held_out[1] < 0.005, "binned, without alignment: {without_binned:?}");
    for terms in [&with_binned, &without_binned] {
        let (_, _, held_out) = term(terms, "turn.evasion");
        assert!(held_out[0] > 0.0, "binned evasion: {terms:?}");
    }
}
