//! The house's floors (`docs/src/reference/architecture.md`): each top-level room of `src/` imports only
//! rooms on the floors below it, so data flows one way and no import runs in a circle. Read from the
//! sources: every `crate::ROOM` path and every room named in a `use crate::{...}` group.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Each room's floor, bottom up. What a run leaves on disk (`store`) stands above the learning it saves and
/// below the run modes that ask it to. Rooms on one floor import neither each other: the claims and how they are
/// judged (`claims`) and the window (`viewer`) stand side by side above the single-run analyses, and the
/// lab that runs and assembles experiments (`experiment`) above the claims.
const FLOORS: [(&str, u32); 15] = [
    ("error", 1),
    ("parallel", 2),
    ("svg", 2),
    ("io", 3),
    ("scene", 4),
    ("sim", 5),
    ("learning", 6),
    ("store", 7),
    ("run", 8),
    ("analysis", 9),
    ("claims", 10),
    ("viewer", 10),
    ("experiment", 11),
    ("cli", 12),
    ("main", 13),
];

/// The rooms a source text names through `crate::` in its code (comments, doc links among them, are not
/// imports).
fn named_rooms(text: &str) -> BTreeSet<String> {
    let code: String = text
        .lines()
        .map(|line| match line.find("//") {
            // A comment, whole or after the code (a `//` inside a string literal is rare in these files and
            // would only hide a path, never add one).
            Some(at) => &line[..at],
            None => line,
        })
        .collect::<Vec<_>>()
        .join("\n");
    let text = code.as_str();
    let word = |s: &str| s.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect::<String>();
    let mut rooms = BTreeSet::new();
    for (at, _) in text.match_indices("crate::") {
        let rest = &text[at + "crate::".len()..];
        if let Some(group) = rest.strip_prefix('{') {
            // A group: the first word of each item at the group's own depth.
            let mut depth = 0;
            let mut start = true;
            for (i, c) in group.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 0 => break,
                    '}' => depth -= 1,
                    ',' if depth == 0 => start = true,
                    c if start && !c.is_whitespace() => {
                        rooms.insert(word(&group[i..]));
                        start = false;
                    }
                    _ => {}
                }
            }
        } else {
            rooms.insert(word(rest));
        }
    }
    rooms
}

/// Every `.rs` file under `dir` with its text.
fn sources(dir: &Path, out: &mut Vec<(std::path::PathBuf, String)>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            sources(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push((path.clone(), std::fs::read_to_string(&path).unwrap()));
        }
    }
}

#[test]
fn every_room_imports_only_the_floors_below_it() {
    let floor: BTreeMap<&str, u32> = FLOORS.into_iter().collect();
    let mut files = Vec::new();
    sources(Path::new("src"), &mut files);
    let mut wrong = Vec::new();
    for (path, text) in &files {
        let relative = path.strip_prefix("src").unwrap();
        let room = relative.iter().next().unwrap().to_string_lossy().trim_end_matches(".rs").to_string();
        if room == "lib" {
            continue;
        }
        let Some(&own) = floor.get(room.as_str()) else {
            wrong.push(format!("{}: a room with no floor in tests/it/layers.rs", path.display()));
            continue;
        };
        for named in named_rooms(text) {
            if named == room {
                continue;
            }
            match floor.get(named.as_str()) {
                Some(&theirs) if theirs < own => {}
                Some(_) => wrong.push(format!("{}: imports crate::{named}, on its floor or above", path.display())),
                // Not a room: a macro or an item of the crate root (`crate::outln!`, `crate::Result`).
                None => {}
            }
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

/// No top-level room holds more than a fifth of the source's lines: past that, a room holds several
/// concerns that want rooms of their own.
#[test]
fn no_room_holds_more_than_a_fifth_of_the_lines() {
    let mut files = Vec::new();
    sources(Path::new("src"), &mut files);
    let mut lines: BTreeMap<String, usize> = BTreeMap::new();
    for (path, text) in &files {
        let room = path.strip_prefix("src").unwrap().iter().next().unwrap().to_string_lossy().to_string();
        *lines.entry(room).or_default() += text.lines().count();
    }
    let total: usize = lines.values().sum();
    let big: Vec<String> = lines
        .iter()
        .filter(|(_, &n)| 5 * n > total)
        .map(|(room, n)| format!("src/{room}: {n} of {total} lines"))
        .collect();
    assert!(big.is_empty(), "{}", big.join("\n"));
}

#[test]
fn an_upward_import_is_found() {
    let rooms = named_rooms("use crate::{scene::Scene, experiment::{plot, stats}};\nlet x = crate::viewer::run();");
    assert_eq!(rooms, ["experiment", "scene", "viewer"].map(String::from).into_iter().collect());
}
