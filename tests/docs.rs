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
