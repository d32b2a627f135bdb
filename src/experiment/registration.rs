//! Registration precedes data: what each claim tests ([`registry::test_fingerprint`]) is in its experiment
//! file's committed history before the first committed per-run row it judges — a row of a `summary.csv`,
//! the experiment's own or, for a shared variant, its owner's — unless the claim is marked `exploratory`.
//! Read from git each time an experiment is aggregated. Where there is no history to read (no repository,
//! a shallow clone, a file outside the repository) nothing is checked, and the aggregation says so.
//!
//! A claim's words may be edited later (`registry.rs` flags that in the reports); what it tests may not:
//! its variants, quantity, the paper's value, margin, tolerance, baseline, direction, scale and grid test.

use super::file::{Claim, Experiment};
use super::registry;
use crate::error::Result;
use std::collections::{BTreeSet, HashMap};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// Whether the history could be read.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum Checked {
    /// Every claim was registered before its first committed row, or is marked exploratory.
    Yes,
    /// Nothing checked, and why.
    Not(String),
}

/// Refuses an experiment one of whose claims was not committed before the first committed per-run row it
/// judges, naming the file, the claim, both commits and the way out. The history is read once for all of
/// `experiments` (one repository, each summary's versions once, however many experiments share from it).
pub(crate) fn check<'a>(experiments: impl IntoIterator<Item = &'a Experiment>) -> Result<Checked> {
    let mut repo: Option<Repo> = None;
    let mut rows = HashMap::new();
    for exp in experiments {
        let repo = match repo.as_ref() {
            Some(repo) => repo,
            None => match Repo::of(&exp.file) {
                Ok(made) => repo.insert(made),
                Err(why) => return Ok(Checked::Not(why)),
            },
        };
        let Some(file) = repo.relative(&exp.file) else {
            return Ok(Checked::Not(format!("{} is outside the repository", exp.file.display())));
        };
        let registered = repo.registered(&file)?;
        let first_rows = match FirstRows::of(exp, repo, &mut rows)? {
            Ok(first_rows) => first_rows,
            Err(why) => return Ok(Checked::Not(why)),
        };
        for claim in exp.spec.claims.iter().filter(|c| !c.exploratory) {
            let Some((row, summary)) = first_rows.of_claim(exp, claim) else { continue };
            let at = registered.get(&registry::test_fingerprint(claim)).copied();
            if at.is_some_and(|at| at < row) {
                continue;
            }
            let stated = match at {
                Some(at) => format!("what it tests was first committed in {}", repo.short(at)),
                None => "what it tests is in no commit of the file".to_string(),
            };
            return Err(format!(
                "{}: claim {:?}: {stated}, not before its first committed per-run row ({}, {}); nothing aggregated: mark it `exploratory: true`, or state it before its runs",
                exp.file.display(),
                claim.text,
                repo.short(row),
                summary.display(),
            )
            .into());
        }
    }
    Ok(Checked::Yes)
}

/// The repository an experiment file is in, with its commits in order (parents first).
struct Repo {
    top: PathBuf,
    commits: Vec<String>,
    position: HashMap<String, usize>,
}

impl Repo {
    /// The repository holding `file`, or why its history cannot be read.
    fn of(file: &Path) -> std::result::Result<Repo, String> {
        let dir = file.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
        let out = git(dir, &["rev-parse", "--show-toplevel", "--is-shallow-repository"])
            .ok_or_else(|| format!("{} is not in a git repository", file.display()))?;
        let mut lines = out.lines();
        let top = PathBuf::from(lines.next().unwrap_or_default());
        if lines.next() == Some("true") {
            return Err(format!("{} is in a shallow clone, whose history is cut", top.display()));
        }
        let listed = git(&top, &["rev-list", "--reverse", "--topo-order", "HEAD"])
            .ok_or_else(|| format!("{} has no commit", top.display()))?;
        let commits: Vec<String> = listed.lines().map(str::to_string).collect();
        let position = commits.iter().enumerate().map(|(i, c)| (c.clone(), i)).collect();
        Ok(Repo { top, commits, position })
    }

    /// `path` relative to the repository's top, None outside it. A folder that is not in the working tree
    /// (results removed, yet committed) is taken as written.
    fn relative(&self, path: &Path) -> Option<String> {
        let path = std::path::absolute(path).ok()?;
        let top = std::fs::canonicalize(&self.top).ok()?;
        let path = match std::fs::canonicalize(path.parent()?) {
            Ok(parent) => parent.join(path.file_name()?),
            Err(_) => path,
        };
        Some(path.strip_prefix(top).ok()?.to_string_lossy().into_owned())
    }

    fn short(&self, position: usize) -> &str {
        &self.commits[position][..12.min(self.commits[position].len())]
    }

    /// Every committed version of `path` (following renames of an experiment file), oldest first: the
    /// commit's position and the text, for the commits reachable from HEAD.
    fn versions(&self, path: &str, follow: bool) -> Result<Vec<(usize, String)>> {
        let mut args = vec!["log", "--format=@%H", "--name-only"];
        if follow {
            args.push("--follow");
        }
        args.extend(["--", path]);
        let Some(log) = git(&self.top, &args) else { return Ok(Vec::new()) };
        let mut specs = Vec::new();
        let mut commit = None;
        for line in log.lines().filter(|l| !l.is_empty()) {
            match line.strip_prefix('@') {
                Some(c) => commit = self.position.get(c).copied(),
                None => specs.extend(commit.take().map(|at| (at, format!("{}:{line}", self.commits[at])))),
            }
        }
        specs.sort();
        let input: String = specs.iter().map(|(_, spec)| format!("{spec}\n")).collect();
        let out = git_bytes(&self.top, &["cat-file", "--batch"], Some(input.as_bytes()))
            .ok_or_else(|| format!("git cat-file could not read the history of {path}"))?;
        let mut rest = &out[..];
        let mut texts = Vec::with_capacity(specs.len());
        for (at, spec) in specs {
            // "<sha> blob <size>\n<content>\n", or "<spec> missing\n" (a version deleted in that commit).
            let end = rest.iter().position(|&b| b == b'\n').ok_or("git cat-file: a truncated answer")?;
            let header = String::from_utf8_lossy(&rest[..end]).into_owned();
            rest = &rest[end + 1..];
            // "<spec> missing" names the spec as asked, which may hold spaces (a file's path).
            if header.ends_with(" missing") {
                continue;
            }
            let size = match header.split(' ').collect::<Vec<_>>()[..] {
                [_, "blob", size] => size.parse::<usize>().ok(),
                _ => None,
            };
            let Some(size) = size.filter(|size| rest.len() > *size) else {
                return Err(format!("git cat-file: an unexpected answer for {spec}: {header}").into());
            };
            texts.push((at, String::from_utf8_lossy(&rest[..size]).into_owned()));
            rest = &rest[size + 1..];
        }
        Ok(texts)
    }

    /// For each test fingerprint any committed version of the experiment file `path` states, the first
    /// commit stating it. A version that does not read as an experiment file's claims (the format of an
    /// older coevo) states nothing.
    fn registered(&self, path: &str) -> Result<HashMap<String, usize>> {
        /// Only the claims of a version; its other fields may be of any older format.
        #[derive(serde::Deserialize)]
        struct Claims {
            #[serde(default)]
            claims: Vec<Claim>,
        }
        let mut first = HashMap::new();
        for (at, text) in self.versions(path, true)? {
            let Ok(version) = crate::scene::parse_ron::<Claims>(&text, path) else { continue };
            for claim in &version.claims {
                first.entry(registry::test_fingerprint(claim)).or_insert(at);
            }
        }
        Ok(first)
    }
}

/// For each summary an experiment's rows are committed in, the first commit holding a row of each variant.
struct FirstRows<'a> {
    by_summary: &'a HashMap<PathBuf, HashMap<String, usize>>,
}

impl<'a> FirstRows<'a> {
    /// The first rows of every summary `exp` reads (read from the history into `read` when not there
    /// yet), or why one cannot be read from the history.
    fn of(
        exp: &Experiment,
        repo: &Repo,
        read: &'a mut HashMap<PathBuf, HashMap<String, usize>>,
    ) -> Result<std::result::Result<FirstRows<'a>, String>> {
        let summaries: BTreeSet<PathBuf> =
            exp.spec.variants.iter().flat_map(|v| sources(exp, &v.name)).map(|(s, _)| s).collect();
        for summary in summaries {
            if read.contains_key(&summary) {
                continue;
            }
            let mut first = HashMap::new();
            let Some(path) = repo.relative(&summary) else {
                return Ok(Err(format!("{} is outside the repository", summary.display())));
            };
            for (at, text) in repo.versions(&path, false)? {
                for variant in variants_in(&text) {
                    first.entry(variant).or_insert(at);
                }
            }
            read.insert(summary, first);
        }
        Ok(Ok(FirstRows { by_summary: read }))
    }

    /// The first commit holding a row the claim judges, and the summary it is in; None when none is
    /// committed.
    fn of_claim(&self, exp: &Experiment, claim: &Claim) -> Option<(usize, PathBuf)> {
        let variants: Vec<&str> = match claim.grid {
            Some(_) => exp.spec.variants.iter().filter(|v| !v.cell.is_empty()).map(|v| v.name.as_str()).collect(),
            None => std::iter::once(claim.variant.as_str()).chain(claim.versus.as_deref()).collect(),
        };
        variants
            .into_iter()
            .flat_map(|v| sources(exp, v))
            .filter_map(|(summary, variant)| Some((*self.by_summary.get(&summary)?.get(&variant)?, summary)))
            .min()
    }
}

/// Where a variant's rows are committed: the experiment's own summary, and for a shared variant its
/// owner's (under the owner's name for it).
fn sources(exp: &Experiment, variant: &str) -> Vec<(PathBuf, String)> {
    let mut out = vec![(exp.summary_path(), variant.to_string())];
    let shared = exp.spec.variants.iter().find(|v| v.name == variant).and_then(|v| v.shared_from.as_deref());
    if let Some((owner, name)) = shared.and_then(|s| s.split_once('/')) {
        let results = exp.root.parent().unwrap_or(Path::new("."));
        out.push((results.join(owner).join(super::load::SUMMARY), name.to_string()));
    }
    out
}

/// The variants a version of a `summary.csv` holds rows of (its `variant` column).
fn variants_in(text: &str) -> BTreeSet<String> {
    let mut reader = csv::ReaderBuilder::new().flexible(true).from_reader(text.as_bytes());
    let Some(column) = reader.headers().ok().and_then(|h| h.iter().position(|c| c == "variant")) else {
        return BTreeSet::new();
    };
    reader.records().filter_map(|r| Some(r.ok()?.get(column)?.to_string())).collect()
}

fn git(dir: &Path, args: &[&str]) -> Option<String> {
    git_bytes(dir, args, None).map(|out| String::from_utf8_lossy(&out).trim_end().to_string())
}

/// `git -C dir ARGS` with `input` on its standard input: its standard output when it succeeds.
fn git_bytes(dir: &Path, args: &[&str], input: Option<&[u8]>) -> Option<Vec<u8>> {
    let mut child = Command::new("git")
        .arg("-C")
        .arg(dir)
        .args(args)
        .stdin(if input.is_some() { Stdio::piped() } else { Stdio::null() })
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .ok()?;
    // Written from a thread, so that a large answer cannot block git while the question is still written.
    let writer = input.map(|bytes| {
        let mut stdin = child.stdin.take().expect("piped");
        let bytes = bytes.to_vec();
        std::thread::spawn(move || stdin.write_all(&bytes))
    });
    let out = child.wait_with_output().ok()?;
    if let Some(writer) = writer {
        writer.join().ok()?.ok()?;
    }
    out.status.success().then_some(out.stdout)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An experiment file of one variant (and, with `shared`, one shared from `owner.ron`) with `claims`.
    fn file(claims: &str, shared: bool) -> String {
        let shared = if shared { r#"(name: "shared", shared_from: Some("owner/standard")),"# } else { "" };
        format!(
            r#"(base: "scenes/paper.ron", seeds: [1], episodes: 3, variants: [(name: "5:3"), {shared}], claims: [{claims}])"#
        )
    }
    const OWNER: &str = r#"(base: "scenes/paper.ron", seeds: [1], episodes: 3, variants: [(name: "standard")])"#;
    const FALLS: &str = r#"(text: "DoS falls", variant: "5:3", quantity: DosChange)"#;

    /// A repository in a temporary folder, committed to step by step.
    struct History(tempfile::TempDir);

    impl History {
        fn new() -> History {
            let dir = tempfile::tempdir().unwrap();
            std::fs::create_dir_all(dir.path().join("experiments")).unwrap();
            std::fs::create_dir_all(dir.path().join("results/reg")).unwrap();
            std::fs::create_dir_all(dir.path().join("results/owner")).unwrap();
            std::fs::write(dir.path().join("experiments/owner.ron"), OWNER).unwrap();
            let history = History(dir);
            history.git(&["init", "-q"]);
            history
        }
        fn git(&self, args: &[&str]) {
            let ok = Command::new("git")
                .args(["-c", "user.name=coevo", "-c", "user.email=coevo@localhost", "-c", "commit.gpgsign=false"])
                .arg("-C")
                .arg(self.0.path())
                .args(args)
                .status()
                .unwrap()
                .success();
            assert!(ok, "git {args:?}");
        }
        /// Writes `path` and commits it.
        fn commit(&self, path: &str, text: &str) {
            std::fs::write(self.0.path().join(path), text).unwrap();
            self.git(&["add", path]);
            self.git(&["commit", "-q", "-m", path]);
        }
        fn check(&self) -> Result<Checked> {
            let dir = self.0.path();
            let exp = Experiment::load(&dir.join("experiments/reg.ron"), &dir.join("results")).unwrap();
            check([&exp])
        }
    }

    const ROWS: &str = "preset,variant,seed\npaper,5:3,1\n";

    #[test]
    fn a_claim_stated_after_its_first_committed_row_is_refused_unless_marked_exploratory() {
        let h = History::new();
        h.commit("results/reg/summary.csv", ROWS);
        h.commit("experiments/reg.ron", &file(FALLS, false));
        let refused = h.check().unwrap_err().message;
        assert!(refused.contains("reg.ron: claim \"DoS falls\"") && refused.contains("exploratory: true"), "{refused}");
        assert!(!refused.contains('\n'), "one line: {refused}");
        // Marked, it is reported as exploratory; the mark is no part of what it tests.
        h.commit("experiments/reg.ron", &file(&FALLS.replace("variant:", "exploratory: true, variant:"), false));
        assert_eq!(h.check().unwrap(), Checked::Yes);
        // Not yet committed at all, against a committed row: refused too.
        std::fs::write(h.0.path().join("experiments/reg.ron"), file(&FALLS.replace("DosChange", "DoaChange"), false))
            .unwrap();
        assert!(h.check().unwrap_err().message.contains("is in no commit of the file"));
    }

    #[test]
    fn a_claim_stated_before_its_rows_may_be_reworded_but_not_retested() {
        let h = History::new();
        h.commit("experiments/reg.ron", &file(FALLS, false));
        // No row committed yet: nothing to refuse, then rows after the claim.
        assert_eq!(h.check().unwrap(), Checked::Yes);
        h.commit("results/reg/summary.csv", ROWS);
        assert_eq!(h.check().unwrap(), Checked::Yes);
        h.commit("experiments/reg.ron", &file(&FALLS.replace("DoS falls", "DoS falls over training"), false));
        assert_eq!(h.check().unwrap(), Checked::Yes);
        h.commit("experiments/reg.ron", &file(&FALLS.replace("DosChange", "DosLast"), false));
        assert!(h.check().is_err());
    }

    #[test]
    fn a_shared_variants_rows_count_from_its_owners_summary() {
        let h = History::new();
        h.commit("results/owner/summary.csv", "preset,variant,seed\npaper,standard,1\n");
        let versus = r#"(text: "5:3 against the shared", variant: "5:3", versus: "shared", quantity: DosChange)"#;
        h.commit("experiments/reg.ron", &file(versus, true));
        let refused = h.check().unwrap_err().message;
        assert!(refused.contains("results/owner/summary.csv"), "{refused}");
        // A claim on its own variant alone is judged on its own rows, none committed yet.
        h.commit("experiments/reg.ron", &file(FALLS, true));
        assert_eq!(h.check().unwrap(), Checked::Yes);
    }

    #[test]
    fn outside_a_repository_nothing_is_checked_and_that_is_said() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(dir.path().join("experiments")).unwrap();
        std::fs::write(dir.path().join("experiments/reg.ron"), file(FALLS, false)).unwrap();
        let exp = Experiment::load(&dir.path().join("experiments/reg.ron"), &dir.path().join("results")).unwrap();
        assert!(matches!(check([&exp]).unwrap(), Checked::Not(why) if why.contains("not in a git repository")));
    }

    /// The project's own experiments, in this repository's history: every claim stated before the first
    /// committed row it judges, or marked exploratory. A shallow clone has no history to read: said, not
    /// checked.
    #[test]
    fn the_projects_claims_were_stated_before_their_rows_or_are_marked() {
        let experiments: Vec<Experiment> = Experiment::files(Path::new("experiments"))
            .unwrap()
            .iter()
            .map(|file| Experiment::load(file, Path::new("results")).unwrap())
            .collect();
        match check(&experiments) {
            Ok(Checked::Yes) => {}
            Ok(Checked::Not(why)) => eprintln!("not checked: {why}"),
            Err(e) => panic!("{}", e.message),
        }
    }
}
