//! The README and the book (`docs/src/`): every `coevo` command they show is one coevo accepts (parsed
//! as the binary parses it, not run), and the reference pages that print coevo's own output are current.

use std::path::{Path, PathBuf};

fn markdown_files() -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|e| e == "md") {
                out.push(path);
            }
        }
    }
    let mut files = vec![PathBuf::from("README.md")];
    walk(Path::new("docs/src"), &mut files);
    files.sort();
    files
}

/// The arguments of every coevo command in the file's `sh` blocks (`coevo …`, `cargo run … -- …`), with
/// the line each starts on. Comments (`# …`) and line continuations are handled as a shell would.
fn commands(text: &str) -> Vec<(usize, Vec<String>)> {
    let mut out = vec![];
    let mut in_sh = false;
    let mut pending: Option<(usize, String)> = None;
    for (i, line) in text.lines().enumerate() {
        let trimmed = line.trim();
        if trimmed.starts_with("```") {
            in_sh = trimmed == "```sh";
            continue;
        }
        if !in_sh {
            continue;
        }
        let (start, mut joined) = pending.take().unwrap_or((i + 1, String::new()));
        joined.push_str(trimmed.trim_end_matches('\\'));
        joined.push(' ');
        if trimmed.ends_with('\\') {
            pending = Some((start, joined));
            continue;
        }
        let words = shell_words::split(&joined).unwrap_or_else(|e| panic!("line {start}: {e}: {joined}"));
        let words: Vec<String> = words.into_iter().take_while(|w| !w.starts_with('#')).collect();
        let args = match words.first().map(String::as_str) {
            Some("coevo") => words[1..].to_vec(),
            Some("cargo") if words.get(1).map(String::as_str) == Some("run") => {
                match words.iter().position(|w| w == "--") {
                    Some(k) => words[k + 1..].to_vec(),
                    None => vec![],
                }
            }
            _ => continue,
        };
        out.push((start, args));
    }
    out
}

#[test]
fn every_command_shown_is_one_coevo_accepts() {
    let mut checked = 0;
    let mut wrong = vec![];
    for file in markdown_files() {
        let text = std::fs::read_to_string(&file).unwrap();
        for (line, args) in commands(&text) {
            checked += 1;
            if let Err(e) = coevo::cli::check_args(args.clone()) {
                wrong.push(format!("{}:{line}: coevo {}: {e}", file.display(), args.join(" ")));
            }
        }
    }
    assert!(wrong.is_empty(), "{} of {checked} commands are refused:\n{}", wrong.len(), wrong.join("\n"));
    assert!(checked > 40, "only {checked} commands found: is the extraction broken?");
}

#[test]
fn a_wrong_command_is_found() {
    // The check itself can fail: a flag that does not exist, and two modes at once.
    let text = "```sh\ncoevo --train --episodez 3   # typo\ncargo run --release -- --eval RUN \\\n  --train\n```\n";
    let found = commands(text);
    assert_eq!(found.len(), 2);
    assert_eq!(found[1].0, 3, "a continued command is reported on its first line");
    for (_, args) in found {
        assert!(coevo::cli::check_args(args).is_err());
    }
}

/// The fenced block of `page` that follows `marker`.
fn block_after(page: &str, marker: &str) -> String {
    let text = std::fs::read_to_string(page).unwrap();
    let from = text.find(marker).unwrap_or_else(|| panic!("{page}: no {marker:?}"));
    let rest = &text[from..];
    let open = rest.find("```text\n").expect("a text block after the marker") + "```text\n".len();
    let close = rest[open..].find("\n```").expect("the block closes") + open;
    rest[open..close].to_string()
}

#[test]
fn the_command_line_reference_is_coevos_help() {
    let help = coevo::cli::help();
    assert_eq!(
        block_after("docs/src/reference/cli.md", "<!-- coevo --help -->"),
        help.trim_end(),
        "docs/src/reference/cli.md is stale: paste the output of `coevo --help`"
    );
}

#[test]
fn the_scene_reference_is_coevos_description_of_the_default_scene() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_coevo"))
        .args(["--describe-scene", "scenes/standard.ron"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let described = String::from_utf8(out.stdout).unwrap();
    assert_eq!(
        block_after("docs/src/reference/scene.md", "<!-- coevo --describe-scene scenes/standard.ron -->"),
        described.trim_end(),
        "docs/src/reference/scene.md is stale: paste the output of `coevo --describe-scene scenes/standard.ron`"
    );
}

/// One claim's row of REPRODUCTION.md: its estimate as shown ("0.035 ± 0.028 (10)") and its verdict.
struct ClaimRow {
    ours: String,
    /// Holm-adjusted p ("–" for a level).
    p: String,
    verdict: String,
}

impl ClaimRow {
    /// An effect detected after Holm's adjustment, or a level told apart from chance.
    fn detected(&self) -> bool {
        let p = self.p.trim_start_matches("< ").parse::<f64>().is_ok_and(|p| p < 0.05);
        p || self.verdict.starts_with("measured: differs from chance") || self.verdict.contains("which excludes chance")
    }
}

/// Every claim row of REPRODUCTION.md by (experiment, preset, claim text).
fn claim_rows(md: &str) -> std::collections::BTreeMap<(String, String, String), Vec<ClaimRow>> {
    let mut rows = std::collections::BTreeMap::new();
    let mut experiment = String::new();
    for line in md.lines() {
        if let Some(name) = line.strip_prefix("## ") {
            experiment = name.trim().to_string();
            continue;
        }
        if !line.starts_with("| ") {
            continue;
        }
        // Cells split at `|` that are not escaped (`\|` inside a claim's text).
        let mut cells = vec![String::new()];
        let mut chars = line.trim().trim_matches('|').chars().peekable();
        while let Some(c) = chars.next() {
            match c {
                '\\' if chars.peek() == Some(&'|') => cells.last_mut().unwrap().push(chars.next().unwrap()),
                '|' => cells.push(String::new()),
                c => cells.last_mut().unwrap().push(c),
            }
        }
        let cells: Vec<String> = cells.into_iter().map(|c| c.trim().to_string()).collect();
        // preset | claim | quantity | paper | ours (adjusted) | level | unadjusted 95 % | p (Holm) | verdict |
        // hypothesis | family
        if cells.len() == 11 && cells[0] != "preset" {
            let key = (experiment.clone(), cells[0].clone(), cells[1].clone());
            let row = ClaimRow { ours: cells[4].clone(), p: cells[7].clone(), verdict: cells[8].clone() };
            rows.entry(key).or_insert_with(Vec::new).push(row);
        }
    }
    rows
}

/// A number as prose writes it (a − for a minus sign) and how many decimals it shows.
fn shown_number(text: &str) -> Option<(f64, usize)> {
    let text = text.replace('−', "-");
    let decimals = text.split_once('.').map_or(0, |(_, d)| d.len());
    text.parse().ok().map(|x| (x, decimals))
}

/// The REPRODUCTION.md rows a citation `EXPERIMENT / PRESET / CLAIM` names (None when it names none).
fn cited_rows<'r>(
    cited: &str,
    rows: &'r std::collections::BTreeMap<(String, String, String), Vec<ClaimRow>>,
) -> Option<&'r Vec<ClaimRow>> {
    match cited.splitn(3, " / ").collect::<Vec<_>>()[..] {
        [e, p, c] => rows.get(&(e.to_string(), p.to_string(), c.to_string())),
        _ => None,
    }
}

/// Every `MEAN ± CI<!-- claim: EXPERIMENT / PRESET / CLAIM -->` in `text` checked against REPRODUCTION.md:
/// the numbers are the claim's estimate rounded to the decimals shown, and a "detected" or "not detected"
/// written right after it is what the verdict says. Returns one line per disagreement.
fn check_cited_claims(
    text: &str,
    rows: &std::collections::BTreeMap<(String, String, String), Vec<ClaimRow>>,
) -> Vec<String> {
    const OPEN: &str = "<!-- claim: ";
    let mut wrong = vec![];
    for (i, line) in text.lines().enumerate() {
        let mut rest = line;
        let mut before_len = 0;
        while let Some(at) = rest.find(OPEN) {
            let before = &line[..before_len + at];
            let after_open = &rest[at + OPEN.len()..];
            let Some(close) = after_open.find("-->") else {
                wrong.push(format!("line {}: an unclosed claim citation", i + 1));
                break;
            };
            let cited = after_open[..close].trim();
            let after = &after_open[close + 3..];
            let row = match cited_rows(cited, rows).map(Vec::as_slice) {
                Some([one]) => one,
                found => {
                    let why = if found.is_some() { "names more than one row of" } else { "is not a claim of" };
                    wrong.push(format!("line {}: {cited:?} {why} REPRODUCTION.md", i + 1));
                    rest = after;
                    before_len = line.len() - rest.len();
                    continue;
                }
            };
            // The prose's "MEAN ± CI" just before the citation.
            let words: Vec<&str> = before.split_whitespace().collect();
            let prose = match words[..] {
                [.., m, "±", c] => shown_number(m.trim_start_matches(['(', '[', '*']))
                    .zip(shown_number(c.trim_end_matches([',', ';', ')', '*']))),
                _ => None,
            };
            let ours: Vec<&str> = row.ours.split_whitespace().collect();
            let data = match ours[..] {
                [m, "±", c, ..] => shown_number(m).zip(shown_number(c)),
                _ => None,
            };
            match (prose, data) {
                (Some(((m, dm), (c, dc))), Some(((dm_value, _), (dc_value, _)))) => {
                    // The table shows three decimals; prose rounds that (or the value) to fewer.
                    let agrees = |shown: f64, d: usize, value: f64| {
                        let rounding = if d >= 3 { 1e-9 } else { 0.5 * 10f64.powi(-(d as i32)) + 0.0005 };
                        (shown - value).abs() <= rounding
                    };
                    if !agrees(m, dm, dm_value) || !agrees(c, dc, dc_value) {
                        wrong.push(format!(
                            "line {}: {m} ± {c} but REPRODUCTION.md has {} for {cited:?}",
                            i + 1,
                            row.ours
                        ));
                    }
                }
                _ => wrong.push(format!(
                    "line {}: no \"MEAN ± CI\" before the citation of {cited:?} (data: {})",
                    i + 1,
                    row.ours
                )),
            }
            // A Holm p-value written right after the citation is the claim's.
            // (within the next 80 characters, before any other citation)
            let next = after.find(OPEN).unwrap_or(after.len());
            if let Some(at) = after[..next].find("Holm p = ").filter(|&at| at < 80) {
                let shown: String = after[at + "Holm p = ".len()..]
                    .chars()
                    .take_while(|c| c.is_ascii_digit() || *c == '.' || *c == '<' || *c == ' ')
                    .collect();
                let (shown, data) = (shown.trim().trim_start_matches("< "), row.p.trim_start_matches("< "));
                let agrees = match (shown_number(shown), shown_number(data)) {
                    (Some((a, d)), Some((b, _))) => (a - b).abs() <= 0.5 * 10f64.powi(-(d as i32)) + 0.0005,
                    _ => false,
                };
                if !agrees {
                    wrong.push(format!(
                        "line {}: Holm p = {shown} but REPRODUCTION.md has {} for {cited:?}",
                        i + 1,
                        row.p
                    ));
                }
            }
            // What the prose calls it, right after the citation.
            // The words up to the end of the clause: `|`, `;`, or a full stop (a `.` not inside a number).
            let said = {
                let b = after.as_bytes();
                let end = (0..b.len())
                    .find(|&k| {
                        b[k] == b'|' || b[k] == b';' || (b[k] == b'.' && !b.get(k + 1).is_some_and(u8::is_ascii_digit))
                    })
                    .unwrap_or(b.len());
                &after[..end]
            };
            let said = &said[..said.find(OPEN).unwrap_or(said.len())];
            let negative =
                ["not detected", "neither", "none", "no effect", "inconclusive"].iter().any(|w| said.contains(w));
            let detected = row.detected();
            if said.contains("detected") && !negative && !detected {
                wrong.push(format!("line {}: called detected, but the verdict is {:?}", i + 1, row.verdict));
            }
            // A number set in bold is a detected effect (the book's convention).
            if before.trim_end().ends_with("**") && !detected {
                wrong.push(format!("line {}: in bold, but the verdict is {:?}", i + 1, row.verdict));
            }
            // "reproduced", "direction reproduced" and "not reproduced" are three verdicts: each word said is
            // the verdict's own (a direction-only result is never called reproduced).
            let reproduced = row.verdict.starts_with("reproduced");
            let direction = row.verdict.starts_with("direction reproduced");
            let not = row.verdict.starts_with("not reproduced");
            let says_direction = said.contains("direction reproduced");
            let says_not = said.contains("not reproduced");
            let says_plain =
                said.replace("direction reproduced", "").replace("not reproduced", "").contains("reproduced");
            if says_not && !not {
                wrong.push(format!("line {}: called not reproduced, but the verdict is {:?}", i + 1, row.verdict));
            }
            if says_direction && !direction {
                wrong.push(format!(
                    "line {}: called direction reproduced, but the verdict is {:?}",
                    i + 1,
                    row.verdict
                ));
            }
            if says_plain && !reproduced {
                wrong.push(format!("line {}: called reproduced, but the verdict is {:?}", i + 1, row.verdict));
            }
            if negative && detected {
                wrong.push(format!("line {}: called not detected, but the verdict is {:?}", i + 1, row.verdict));
            }
            // An interval the reports mark as carrying no information (too few seeds, or wider than the
            // quantity's range) is said to be so where it is cited, not shown as a result.
            if row.ours.contains("uninformative") && !said.contains("uninformative") {
                wrong.push(format!("line {}: cites an uninformative interval ({}) without saying so", i + 1, row.ours));
            }
            // A verdict on a claim stated after its first results were committed is said to be exploratory
            // where it is cited: it is no confirmation.
            if row.verdict.contains("exploratory") && !said.contains("exploratory") {
                wrong.push(format!("line {}: cites an exploratory verdict ({cited}) without saying so", i + 1));
            }
            rest = after;
            before_len = line.len() - rest.len();
        }
    }
    wrong
}

#[test]
fn every_number_cited_from_a_claim_is_the_claims_estimate_and_verdict() {
    let rows = claim_rows(&std::fs::read_to_string("REPRODUCTION.md").unwrap());
    assert!(rows.len() > 100, "claim rows read from REPRODUCTION.md: {}", rows.len());
    let (mut cited, mut pages) = (0, vec![]);
    for path in markdown_files() {
        let text = std::fs::read_to_string(&path).unwrap();
        cited += text.matches("<!-- claim: ").count();
        let spelled = text
            .match_indices("<!--")
            .filter(|(at, _)| text[*at..].split("-->").next().is_some_and(|c| c.contains("claim")))
            .count();
        assert_eq!(
            spelled,
            text.matches("<!-- claim: ").count(),
            "{}: a citation not spelled `<!-- claim: `",
            path.display()
        );
        let wrong = check_cited_claims(&text, &rows);
        if !wrong.is_empty() {
            pages.push(format!("{}:\n{}", path.display(), wrong.join("\n")));
        }
    }
    assert!(pages.is_empty(), "{}", pages.join("\n"));
    assert!(cited >= 80, "{cited} citations");
    // A number that drifted from its claim, a wrong name and a verdict said wrongly are all found.
    let key = ("e".to_string(), "gym-pps".to_string(), "a | claim".to_string());
    let mut one = std::collections::BTreeMap::new();
    let row = ClaimRow {
        ours: "0.035 ± 0.028 (10)".into(),
        p: "0.284".into(),
        verdict: "no effect detected (inconclusive)".into(),
    };
    one.insert(key, vec![row]);
    assert!(check_cited_claims("x +0.04 ± 0.03<!-- claim: e / gym-pps / a | claim --> (not detected)", &one).is_empty());
    assert!(check_cited_claims("x 0.035 ± 0.028<!-- claim: e / gym-pps / a | claim -->", &one).is_empty());
    assert_eq!(check_cited_claims("x +0.05 ± 0.03<!-- claim: e / gym-pps / a | claim -->", &one).len(), 1);
    assert_eq!(check_cited_claims("x +0.04 ± 0.03<!-- claim: e / paper / a | claim -->", &one).len(), 1);
    assert_eq!(check_cited_claims("x +0.04 ± 0.03<!-- claim: e / gym-pps / a | claim -->, detected", &one).len(), 1);
    assert!(
        check_cited_claims("x +0.04 ± 0.03<!-- claim: e / gym-pps / a | claim --> (Holm p = 0.28)", &one).is_empty()
    );
    assert_eq!(
        check_cited_claims("x +0.04 ± 0.03<!-- claim: e / gym-pps / a | claim --> (Holm p = 0.20)", &one).len(),
        1
    );
    assert_eq!(check_cited_claims("x 0.036 ± 0.028<!-- claim: e / gym-pps / a | claim -->", &one).len(), 1);
    assert_eq!(check_cited_claims("x **+0.04 ± 0.03**<!-- claim: e / gym-pps / a | claim -->", &one).len(), 1);
    let late = "x +0.04 ± 0.03<!-- claim: e / gym-pps / a | claim --> is smaller than 0.17 and reproduced";
    assert_eq!(check_cited_claims(late, &one).len(), 1);
}

/// Words that claim two things are the same (equivalence), which only an equivalence test (TOST, within a
/// stated margin) can support: "no difference detected" is the honest report of a test that found nothing.
const EQUIVALENCE_WORDS: [&str; 13] = [
    "as much",
    "just as",
    "as well as seeing",
    "removes nothing",
    "does not need",
    "not needed",
    "(it does not)",
    "makes no difference",
    "no difference we can measure",
    "**herding**",
    "equally",
    "it is herding",
    "prey herd",
];

/// Words that say more than "not detected" or a size without saying which (an outcome, a winner, the
/// absence of anything), which need a cited claim that was detected or shown equivalent beside them.
const OVERREACH_WORDS: [&str; 5] = ["as often", "survive as well", "winning", "the answer is", "nothing of this"];

/// A verdict that decides (an effect detected, in whatever direction, or an equivalence shown).
fn decides(verdict: &str) -> bool {
    [
        "reproduced",
        "direction reproduced",
        "not reproduced: detected",
        "effect detected",
        "detected as",
        "detected opposite",
        "equivalent within",
    ]
    .iter()
    .any(|w| verdict.starts_with(w))
}

/// Every sentence of `text` that uses equivalence wording ([`EQUIVALENCE_WORDS`]) but cites no claim
/// whose verdict is an equivalence shown (TOST), or overreaching wording ([`OVERREACH_WORDS`]) but cites
/// no claim that decides: one line each.
fn unsupported_equivalence(
    text: &str,
    rows: &std::collections::BTreeMap<(String, String, String), Vec<ClaimRow>>,
) -> Vec<String> {
    let joined = text.replace('\n', " ");
    // Sentences end at a full stop, `;` or a table cell's `|` followed by a space (a `.` inside a number
    // or a file name is followed by no space); never inside a citation, whose claim text may hold them
    // ("(primary; equivalence within 0.05)"): there they are kept apart and put back when read.
    const KEPT: [(&str, &str); 3] = [(". ", "\u{1}"), ("; ", "\u{2}"), (" | ", "\u{3}")];
    let mut protected = String::new();
    let mut rest = joined.as_str();
    while let Some(at) = rest.find("<!--") {
        let end = rest[at..].find("-->").map_or(rest.len(), |e| at + e);
        protected.push_str(&rest[..at]);
        protected.push_str(&KEPT.iter().fold(rest[at..end].to_string(), |t, (from, to)| t.replace(from, to)));
        rest = &rest[end..];
    }
    protected.push_str(rest);
    let restore = |t: &str| KEPT.iter().fold(t.to_string(), |t, (from, to)| t.replace(to, from));
    let joined = protected;
    let mut wrong = vec![];
    for sentence in joined.split(". ").flat_map(|s| s.split("; ")).flat_map(|s| s.split(" | ")) {
        let lower = sentence.to_lowercase();
        let found = |words: &[&'static str]| words.iter().copied().find(|w| lower.contains(&w.to_lowercase()));
        let (word, needs, supported): (&str, &str, fn(&str) -> bool) =
            match (found(&EQUIVALENCE_WORDS), found(&OVERREACH_WORDS)) {
                (Some(w), _) => (w, "an equivalence verdict", |v| v.starts_with("equivalent within")),
                (None, Some(w)) => (w, "a verdict that decides (detected or equivalent)", decides),
                (None, None) => continue,
            };
        let backed = sentence.split("<!-- claim: ").skip(1).any(|c| {
            let cited = restore(c.split("-->").next().unwrap_or("").trim());
            cited_rows(&cited, rows).is_some_and(|r| r.iter().all(|r| supported(&r.verdict)))
        });
        if !backed {
            let shown: String = sentence.chars().take(120).collect();
            wrong.push(format!("{word:?} without {needs}: {shown}…"));
        }
    }
    wrong
}

#[test]
fn no_sentence_claims_equivalence_without_an_equivalence_verdict() {
    let rows = claim_rows(&std::fs::read_to_string("REPRODUCTION.md").unwrap());
    let mut wrong = vec![];
    // The book, the README, and the comments of scene and experiment files (what a user reads beside them).
    let ron = |dir: &str| -> Vec<std::path::PathBuf> {
        std::fs::read_dir(dir)
            .unwrap()
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|x| x == "ron"))
            .collect()
    };
    for path in markdown_files().into_iter().chain(ron("scenes")).chain(ron("experiments")) {
        let text = std::fs::read_to_string(&path).unwrap();
        wrong.extend(unsupported_equivalence(&text, &rows).into_iter().map(|w| format!("{}: {w}", path.display())));
    }
    assert!(wrong.is_empty(), "equivalence claimed without a test that shows it:\n{}", wrong.join("\n"));
    // The check itself: equivalence wording citing a claim of non-detection fails; citing a TOST verdict
    // passes; a non-detection said as such passes.
    let mut rows = std::collections::BTreeMap::new();
    let row =
        |verdict: &str| ClaimRow { ours: "0.001 ± 0.072 (10)".into(), p: "1.000".into(), verdict: verdict.into() };
    rows.insert(("e".into(), "gym-pps".into(), "a".into()), vec![row("no effect detected (inconclusive)")]);
    rows.insert(
        ("e".into(), "gym-pps".into(), "b".into()),
        vec![row("equivalent within ±0.05: the adjusted interval [-0.030, 0.030] lies inside (TOST, Holm p = 0.010)")],
    );
    // A claim whose text holds "; " is one citation, not two sentences.
    rows.insert(
        ("e".into(), "gym-pps".into(), "c (primary; within 0.05)".into()),
        vec![row("equivalent within ±0.05: the adjusted interval [-0.030, 0.030] lies inside (TOST, Holm p = 0.010)")],
    );
    let said = |text: &str| unsupported_equivalence(text, &rows).len();
    assert_eq!(said("Blind prey align as much (+0.00 ± 0.07<!-- claim: e / gym-pps / a -->). Next."), 1);
    assert_eq!(said("Blind prey align as much (+0.00 ± 0.07<!-- claim: e / gym-pps / b -->). Next."), 0);
    assert_eq!(said("No difference is detected (+0.00 ± 0.07<!-- claim: e / gym-pps / a -->)."), 0);
    assert_eq!(said("The answer is **herding**. It is."), 1);
    // Overreaching words: a non-detection does not back them, a detection does.
    assert_eq!(said("The prey are winning the race (+0.00 ± 0.07<!-- claim: e / gym-pps / a -->)."), 1);
    assert_eq!(said("They are caught as often (+0.00 ± 0.07<!-- claim: e / gym-pps / b -->)."), 0);
    assert_eq!(said("Nothing of this is seen."), 1);
    assert_eq!(
        said("Blind prey align as much (+0.00 ± 0.07<!-- claim: e / gym-pps / c (primary; within 0.05) -->)."),
        0
    );
}

/// The relative link targets of a Markdown text (`[text](target)` and `![alt](target)`), without anchors;
/// web and mail links, and links inside code spans or blocks, are left out.
fn link_targets(text: &str) -> Vec<String> {
    let mut out = vec![];
    let mut in_block = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            in_block = !in_block;
            continue;
        }
        if in_block {
            continue;
        }
        // Code spans hold no links: drop every other backtick-delimited piece.
        let prose: String = line.split('`').step_by(2).collect::<Vec<_>>().join(" ");
        let mut rest = prose.as_str();
        while let Some(i) = rest.find("](") {
            rest = &rest[i + 2..];
            let end = rest.find(')').unwrap_or(rest.len());
            let target = rest[..end].split('#').next().unwrap_or_default().trim();
            if !target.is_empty() && !target.contains("://") && !target.starts_with("mailto:") {
                out.push(target.to_string());
            }
            rest = &rest[end..];
        }
    }
    out
}

/// Every link and image of the README and the book points at a file of the repository, and no page of
/// the book links a Markdown file outside it: mdbook rewrites such a link to an `.html` page that the
/// built book does not have (the pages mirror `docs/src`, so other relative links still resolve in a
/// checkout's `docs/book/`).
fn broken_links(files: &[PathBuf]) -> Vec<String> {
    let book = std::fs::canonicalize("docs/src").unwrap();
    let mut broken = vec![];
    for file in files {
        let text = std::fs::read_to_string(file).unwrap();
        for target in link_targets(&text) {
            let path = file.parent().unwrap().join(&target);
            match std::fs::canonicalize(&path) {
                Err(_) => broken.push(format!("{}: {target} does not exist", file.display())),
                Ok(p) if file.starts_with("docs/src") && !p.starts_with(&book) && target.ends_with(".md") => broken
                    .push(format!(
                        "{}: {target} is outside the book (mdbook would link a missing .html)",
                        file.display()
                    )),
                Ok(_) => {}
            }
        }
    }
    broken
}

#[test]
fn every_link_and_image_of_the_readme_and_the_book_resolves() {
    let files = markdown_files();
    let broken = broken_links(&files);
    assert!(broken.is_empty(), "{}", broken.join("\n"));
    // The book shows its pictures: the GIFs and one figure per results chapter at least.
    let intro = std::fs::read_to_string("docs/src/introduction.md").unwrap();
    assert!(intro.contains("](../../assets/standard.gif)") && intro.contains("](../../assets/confined-penalty.gif)"));
    for page in ["does-it-learn", "flocking-or-herding", "coevolution"] {
        let text = std::fs::read_to_string(format!("docs/src/results/{page}.md")).unwrap();
        assert!(link_targets(&text).iter().any(|t| t.ends_with(".svg")), "{page} shows no figure");
    }
    // The check finds what it is for.
    let dir = tempfile::tempdir().unwrap();
    let page = dir.path().join("page.md");
    std::fs::write(&page, "See [this](missing.md), `[not](a-link)` and ![x](gone.png).\n").unwrap();
    assert_eq!(broken_links(&[page]).len(), 2);
}

/// Numbers shown with three decimals (0.967, −0.110), a minus sign written either way, as `controls.txt`
/// prints them (sign dropped: the file writes +0.967).
fn three_decimal_numbers(text: &str) -> Vec<String> {
    let chars: Vec<char> = text.chars().collect();
    let mut found = vec![];
    let mut i = 0;
    while i < chars.len() {
        if chars[i].is_ascii_digit() && (i == 0 || !(chars[i - 1].is_ascii_digit() || chars[i - 1] == '.')) {
            let start = i;
            while i < chars.len() && chars[i].is_ascii_digit() {
                i += 1;
            }
            if i + 1 < chars.len() && chars[i] == '.' && chars[i + 1].is_ascii_digit() {
                let dot = i;
                i += 1;
                while i < chars.len() && chars[i].is_ascii_digit() {
                    i += 1;
                }
                if i - dot - 1 == 3 {
                    found.push(chars[start..i].iter().collect());
                }
            }
        } else {
            i += 1;
        }
    }
    found
}

#[test]
fn every_ippo_number_shown_is_in_the_committed_controls_output() {
    // The IPPO runs' folders are not committed; what is, is controls.py's whole output of each set of runs
    // (`docs/src/results/ippo/`). So every number the
    // README's IPPO row and the book's "What came out" show to three decimals must be one of its numbers.
    // The runs shown (controls.txt), the same runs with the time limit terminal, and the earlier runs.
    let committed: std::collections::BTreeSet<String> =
        ["controls.txt", "controls-time-limit.txt", "controls-terminal-consecutive.txt"]
            .iter()
            .flat_map(|f| {
                three_decimal_numbers(&std::fs::read_to_string(format!("docs/src/results/ippo/{f}")).unwrap())
            })
            .collect();
    let page = std::fs::read_to_string("docs/src/guide/python.md").unwrap();
    let section = page.split("**What came out**").nth(1).unwrap().split("Training curves").next().unwrap();
    let readme = std::fs::read_to_string("README.md").unwrap();
    let row = readme.lines().find(|l| l.contains("Another learner: IPPO")).unwrap();
    // "p < 0.001" is a bound on the file's p values (8.56e-05 …), not one of its numbers.
    let (section, row) = (section.replace("p < 0.001", "p < ·"), row.replace("p < 0.001", "p < ·"));
    let shown: Vec<String> = three_decimal_numbers(&section).into_iter().chain(three_decimal_numbers(&row)).collect();
    assert!(shown.len() >= 15, "the section shows its numbers: {shown:?}");
    let missing: Vec<&String> = shown.iter().filter(|n| !committed.contains(*n)).collect();
    assert!(missing.is_empty(), "shown but in none of the committed controls outputs: {missing:?}");
    // It can fail: the per-seed figures earlier versions showed are read as numbers and are in none of the files.
    let earlier = three_decimal_numbers("each seed 0.960–0.972; (DoA 0.998, polarization 0.96, DoS 0.052)");
    assert_eq!(earlier, ["0.960", "0.972", "0.998", "0.052"]);
    assert!(earlier.iter().all(|n| !committed.contains(n)));
}

#[test]
fn the_books_tables_from_reports_are_inlined_and_current() {
    // GitHub shows no mdbook include: every table a page takes from a report is written into it, and is the
    // committed report's as `coevo --plot all` writes it.
    for page in markdown_files() {
        let text = std::fs::read_to_string(&page).unwrap();
        assert!(!text.contains("{{#include"), "{}: an mdbook include, which GitHub does not show", page.display());
    }
    use coevo::experiment::paper_table::{inline_tables, INLINING_PAGES};
    for page in INLINING_PAGES {
        let text = std::fs::read_to_string(page).unwrap();
        let inlined = inline_tables(&text, &|report: &str| std::fs::read_to_string(report).ok()).unwrap();
        assert!(
            inlined == text,
            "{page} is not what `coevo --plot all` makes of the committed reports: run it and commit"
        );
    }
}

/// Words that say a result is still being made: a page says what came out, and work under way is no result.
const IN_PROGRESS: [&str; 7] = [
    "being re-tested",
    "being re-run",
    "are being tested",
    "is being tested",
    "not yet run",
    "still running",
    "will be re-tested",
];

/// Each sentence of `text` that says a result is still being made ([`IN_PROGRESS`]).
fn in_progress_statements(text: &str) -> Vec<String> {
    let lower = text.to_lowercase();
    IN_PROGRESS.iter().filter_map(|w| lower.find(w).map(|at| format!("{w:?} at byte {at}"))).collect()
}

#[test]
fn no_page_says_a_result_is_still_being_made() {
    let mut stale = vec![];
    for page in markdown_files() {
        let text = std::fs::read_to_string(&page).unwrap();
        stale.extend(in_progress_statements(&text).into_iter().map(|s| format!("{}: {s}", page.display())));
    }
    assert!(stale.is_empty(), "statements of work in progress, stale once it is done:\n{}", stale.join("\n"));
    // The check itself.
    assert_eq!(in_progress_statements("contrasts are inconclusive and are being re-tested at thirty").len(), 1);
    assert!(in_progress_statements("contrasts are inconclusive at thirty seeds").is_empty());
}

/// A verdict's kind, from REPRODUCTION.md's verdict cell: what it says before its reasons.
fn verdict_kind(verdict: &str) -> &str {
    ["not reproduced", "direction reproduced", "reproduced", "equivalent", "inconclusive", "detected", "measured"]
        .into_iter()
        .find(|k| verdict.starts_with(k))
        .unwrap_or(verdict)
}

/// The sources of the paper's statements that do not answer them (`experiments/the-paper/statements.ron`:
/// a statement's answer is its first source judged on a preset) and whose verdict is of another kind than
/// the answer's, as `EXPERIMENT / PRESET / CLAIM`, each with the answer's.
fn overruled_sources(
    rows: &std::collections::BTreeMap<(String, String, String), Vec<ClaimRow>>,
) -> Vec<(String, String)> {
    let text = std::fs::read_to_string("experiments/the-paper/statements.ron").unwrap();
    let file: ron::Value = ron::from_str(&text).unwrap();
    let field = |v: &ron::Value, name: &str| match v {
        ron::Value::Map(m) => m.get(&ron::Value::String(name.into())).cloned(),
        _ => None,
    };
    let Some(ron::Value::Seq(statements)) = field(&file, "statements") else { panic!("statements.ron: no statements") };
    let mut overruled = vec![];
    for s in &statements {
        let Some(ron::Value::Seq(from)) = field(s, "from") else { continue };
        let sources: Vec<String> = from.iter().filter_map(|f| f.clone().into_rust::<String>().ok()).collect();
        for preset in ["paper", "gym-pps"] {
            let judged: Vec<(String, &str)> = sources
                .iter()
                .filter_map(|src| {
                    let (e, c) = src.split_once(" / ")?;
                    let cited = format!("{e} / {preset} / {c}");
                    let row = cited_rows(&cited, rows)?.first()?;
                    // A source not judged yet (no run, or some still running) answers nothing.
                    let waiting = row.verdict.starts_with("not run yet") || row.verdict.starts_with("in progress");
                    (!waiting).then(|| (cited, verdict_kind(&row.verdict)))
                })
                .collect();
            let Some((answer, kind)) = judged.first().cloned() else { continue };
            overruled.extend(judged[1..].iter().filter(|(_, k)| *k != kind).map(|(c, _)| (c.clone(), answer.clone())));
        }
    }
    overruled
}

/// Each citation in `text` of an overruled source ([`overruled_sources`]) followed, before the next
/// citation or the end of its sentence, by a verdict word: a second verdict for one statement of the paper.
fn second_verdicts(text: &str, overruled: &[(String, String)]) -> Vec<String> {
    const OPEN: &str = "<!-- claim: ";
    let mut found = vec![];
    let starts: Vec<usize> = text.match_indices(OPEN).map(|(at, _)| at).collect();
    for (k, &at) in starts.iter().enumerate() {
        let rest = &text[at + OPEN.len()..];
        let Some(close) = rest.find("-->") else { continue };
        let cited = rest[..close].trim();
        let Some((_, answer)) = overruled.iter().find(|(c, _)| c == cited) else { continue };
        // What is said of it: its sentence, between the citations before and after it.
        let before_from = [
            k.checked_sub(1).and_then(|j| text[starts[j]..at].find("-->").map(|c| starts[j] + c + 3)),
            text[..at].rfind(". ").map(|d| d + 2),
            text[..at].rfind(".\n").map(|d| d + 2),
        ]
        .into_iter()
        .flatten()
        .max()
        .unwrap_or(0);
        let after = &rest[close + 3..];
        let end = [after.find(OPEN), after.find(". "), after.find(".\n")].into_iter().flatten().min();
        let said = format!("{} {}", &text[before_from..at], &after[..end.unwrap_or(after.len())]);
        if ["reproduced", "inconclusive", "detected", "equivalent"].iter().any(|w| said.contains(w)) {
            found.push(format!("{cited:?} is given a verdict, but the statement's is {answer:?}'s"));
        }
    }
    found
}

#[test]
fn no_page_gives_a_statement_of_the_paper_a_second_verdict() {
    let rows = claim_rows(&std::fs::read_to_string("REPRODUCTION.md").unwrap());
    let overruled = overruled_sources(&rows);
    let mut wrong = vec![];
    for page in markdown_files() {
        let text = std::fs::read_to_string(&page).unwrap();
        wrong.extend(second_verdicts(&text, &overruled).into_iter().map(|w| format!("{}: {w}", page.display())));
    }
    assert!(wrong.is_empty(), "a statement of the paper with two verdicts:\n{}", wrong.join("\n"));
    // The check itself: an overruled source's number alone passes; with a verdict beside it, not.
    let one = [("e / paper / a".to_string(), "f / paper / b".to_string())];
    assert!(second_verdicts("0.68 ± 0.03<!-- claim: e / paper / a --> with paper.", &one).is_empty());
    assert_eq!(second_verdicts("0.68 ± 0.03<!-- claim: e / paper / a --> (reproduced).", &one).len(), 1);
}

/// The pages a reader meets results on: every results page of the book, its introduction and the README.
fn results_pages() -> Vec<PathBuf> {
    let mut pages: Vec<PathBuf> = std::fs::read_dir("docs/src/results")
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .collect();
    pages.extend([PathBuf::from("README.md"), PathBuf::from("docs/src/introduction.md")]);
    pages
}

#[test]
fn every_results_page_and_the_readme_point_to_the_definitions() {
    // A reader who meets DoS, DoA, C_nn or a verdict mark on any results page finds its definition from
    // that page (the-paper.md is generated and says it too).
    let pages = results_pages();
    let missing: Vec<_> = pages
        .iter()
        .filter(|p| !std::fs::read_to_string(p).unwrap().contains("reference/definitions.md"))
        .map(|p| p.display().to_string())
        .collect();
    assert!(missing.is_empty(), "pages that do not link the terms' definitions: {missing:?}");
}

/// Each term and mark the book defines, by the anchor of its row in `docs/src/reference/definitions.md`
/// and the words a page uses it by.
const TERMS: &[(&str, &str)] = &[
    ("dos", "DoS"),
    ("doa", "DoA"),
    ("d", "D"),
    ("r-pred", "R_pred"),
    ("polarization", "polarization"),
    ("milling", "milling"),
    ("c-nn", "C_nn"),
    ("xi", "ξ"),
    ("edge-rank", "edge rank"),
    ("catches", "catches"),
    ("halfway", "halfway episode"),
    ("common-level", "common level"),
    ("flocking-share", "flocking share"),
    ("holm", "Holm"),
    ("tost", "TOST"),
    ("marks", "✓"),
    ("marks", "◐"),
    ("marks", "✗"),
    ("uninformative", "uninformative"),
    ("exploratory", "exploratory"),
    ("ciao", "CIAO"),
    ("tau", "τ"),
    ("d-o", "d_o"),
];

/// `text` with what is not prose blanked out, byte for byte (so positions stay): fenced and inline code,
/// HTML comments and tags, images, link targets, and headings.
fn prose_only(text: &str) -> Vec<u8> {
    let mut out = text.as_bytes().to_vec();
    let mut blank =
        |from: usize, to: usize| out[from..to].iter_mut().for_each(|b| *b = if *b == b'\n' { b'\n' } else { b' ' });
    let spans = |open: &str, close: &str, within_line: bool| -> Vec<(usize, usize)> {
        let mut found = vec![];
        let mut at = 0;
        while let Some(start) = text[at..].find(open).map(|s| s + at) {
            let from = start + open.len();
            let Some(end) = text[from..].find(close).map(|e| e + from + close.len()) else { break };
            if !(within_line && text[start..end].contains('\n')) {
                found.push((start, end));
                at = end;
            } else {
                at = from;
            }
        }
        found
    };
    for (open, close, line) in
        [("```", "```", false), ("<!--", "-->", false), ("`", "`", true), ("](", ")", true), ("<", ">", true)]
    {
        for (a, b) in spans(open, close, line) {
            blank(a, b);
        }
    }
    // Images: `![alt](target)`, alt text included; headings: the whole line.
    for (a, _) in text.match_indices("![") {
        if let Some(end) = text[a..].find(']').map(|e| a + e + 1) {
            blank(a, end);
        }
    }
    let mut at = 0;
    for line in text.split_inclusive('\n') {
        if line.starts_with('#') {
            blank(at, at + line.len());
        }
        at += line.len();
    }
    out
}

/// The byte position of the first use of `term` in the prose of `text`, as a whole word.
fn first_use(text: &str, term: &str) -> Option<usize> {
    let prose = prose_only(text);
    let word = |c: Option<char>| c.is_some_and(|c| c.is_alphanumeric() || "_-'’".contains(c));
    let mut at = 0;
    while let Some(i) = text[at..].find(term).map(|i| i + at) {
        let end = i + term.len();
        let blanked = prose[i..end] != text.as_bytes()[i..end];
        if !blanked && !word(text[..i].chars().next_back()) && !word(text[end..].chars().next()) {
            return Some(i);
        }
        at = i + 1;
        while !text.is_char_boundary(at) {
            at += 1;
        }
    }
    None
}

/// The target of the Markdown link whose text holds position `i`, if any.
fn link_around(text: &str, i: usize) -> Option<&str> {
    let open = text[..i].rfind('[')?;
    if text[..i].rfind(']').is_some_and(|c| c > open) {
        return None;
    }
    let close = open + text[open..].find("](")?;
    if close < i || text[open..close].contains("\n\n") || text[i..close].contains(']') {
        return None;
    }
    let end = close + text[close..].find(')')?;
    Some(&text[close + 2..end])
}

#[test]
fn every_term_links_to_its_definition_where_a_page_first_uses_it() {
    let definitions = std::fs::read_to_string("docs/src/reference/definitions.md").unwrap();
    for (anchor, _) in TERMS {
        assert!(definitions.contains(&format!("<a id=\"{anchor}\"></a>")), "no definition anchored {anchor:?}");
    }
    let pages = results_pages();
    let mut wrong = vec![];
    for page in &pages {
        let text = std::fs::read_to_string(page).unwrap();
        for (anchor, term) in TERMS {
            let Some(i) = first_use(&text, term) else { continue };
            let target = format!("definitions.md#{anchor}");
            if !link_around(&text, i).is_some_and(|t| t.ends_with(&target)) {
                let line = text[..i].matches('\n').count() + 1;
                wrong.push(format!("{}:{line}: the first {term:?} does not link to {target}", page.display()));
            }
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
    // It finds a first use that links nowhere, one that links elsewhere, and skips code and headings.
    let page = "# DoS\n\n`DoS` and [DoS](x.md) then DoS";
    assert_eq!(first_use(page, "DoS"), Some(page.find("[DoS]").unwrap() + 1));
    assert_eq!(link_around(page, page.find("[DoS]").unwrap() + 1), Some("x.md"));
    assert_eq!(first_use("DoSes and DoS's, then DoS.", "DoS"), Some(22));
    assert_eq!(link_around("see [the DoS](d.md#dos) here", 9), Some("d.md#dos"));
    assert_eq!(link_around("a [b](c) DoS", 9), None);
}

#[test]
fn the_readmes_layout_names_every_top_level_folder() {
    // "Where things are": a reader finds every folder of the checkout in it (build output aside).
    let readme = std::fs::read_to_string("README.md").unwrap();
    let table = readme.split("## Where things are").nth(1).expect("README: no \"Where things are\"");
    let table = table.split("\n## ").next().unwrap();
    let tracked = std::process::Command::new("git").args(["ls-files"]).output();
    let files = match tracked {
        Ok(out) if out.status.success() => String::from_utf8(out.stdout).unwrap(),
        // Not a git checkout (a source archive): nothing to compare with.
        _ => return,
    };
    let folders: std::collections::BTreeSet<&str> =
        files.lines().filter_map(|f| f.split_once('/').map(|(d, _)| d)).collect();
    assert!(folders.contains("src") && folders.contains(".ci"), "tracked folders read: {folders:?}");
    let missing: Vec<_> = folders.iter().filter(|d| !table.contains(&format!("`{d}/"))).collect();
    assert!(missing.is_empty(), "README's \"Where things are\" does not name {missing:?}");
}

/// The README's "Where things are" names every top-level folder of the repository and every room of
/// `src/`, so its layout table matches the tree.
#[test]
fn the_readme_layout_names_every_folder_and_room() {
    let readme = std::fs::read_to_string("README.md").unwrap();
    let section = readme.split("## Where things are").nth(1).unwrap();
    let table = section.split("\n## ").next().unwrap();
    let mut missing = Vec::new();
    for entry in std::fs::read_dir(".").unwrap().map(|e| e.unwrap()) {
        let name = entry.file_name().to_string_lossy().to_string();
        let shown = if entry.path().is_dir() { format!("`{name}/`") } else { format!("`{name}`") };
        let skipped = ["target", ".git", "src"].contains(&name.as_str()) || (name.starts_with('.') && name != ".ci");
        if entry.path().is_dir() && !skipped && !table.contains(&shown) {
            missing.push(shown);
        }
    }
    for entry in std::fs::read_dir("src").unwrap().map(|e| e.unwrap()) {
        let name = entry.file_name().to_string_lossy().to_string();
        let shown = if entry.path().is_dir() { format!("`src/{name}/`") } else { format!("`src/{name}`") };
        if name != "lib.rs" && !table.contains(&shown) {
            missing.push(shown);
        }
    }
    assert!(missing.is_empty(), "README.md's \"Where things are\" does not name {}", missing.join(", "));
}
