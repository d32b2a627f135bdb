//! RON errors in a user's words: the line of a field path, the field an error sits in, a file cut short.

/// Finds the line of a field path such as `species[prey].mass` or `world.drag` in scene text, so an
/// error can point at it; None when the value came from the preset.
pub(super) fn locate(text: &str, field: &str) -> Option<usize> {
    let lines: Vec<&str> = text.lines().collect();
    let has_key = |line: &str, key: &str| {
        let code = line.split("//").next().unwrap_or("");
        code.match_indices(key).any(|(i, _)| {
            let before_ok = code[..i].chars().last().is_none_or(|c| !(c.is_alphanumeric() || c == '_'));
            let rest = code[i + key.len()..].trim_start();
            before_ok && rest.starts_with(':')
        })
    };
    let (mut from, mut key) = (0usize, field);
    if let Some(rest) = field.strip_prefix("species[") {
        let (name, tail) = rest.split_once(']')?;
        let quoted = format!("\"{name}\"");
        from = lines
            .iter()
            .position(|l| has_key(l, "name") && l.contains(&quoted))
            .or_else(|| name.parse::<usize>().ok().and_then(|_| lines.iter().position(|l| has_key(l, "species"))))?;
        key = tail.trim_start_matches('.');
        if key.is_empty() {
            return Some(from + 1);
        }
    } else if let Some((section, last)) = field.rsplit_once('.') {
        from = lines.iter().position(|l| has_key(l, section))?;
        key = last;
    }
    lines.iter().enumerate().skip(from).find(|(_, l)| has_key(l, key)).map(|(i, _)| i + 1)
}

/// The key whose value a parse error points into: the last `name:` before (line, col), 1-based.
pub(super) fn field_before(text: &str, line: usize, col: usize) -> String {
    let mut before: Vec<&str> = text.lines().take(line).collect();
    if let Some(last) = before.last_mut() {
        *last = &last[..last.char_indices().nth(col.saturating_sub(1)).map_or(last.len(), |(i, _)| i)];
    }
    let joined = before.join("\n");
    let Some(colon) = joined.rfind(':') else {
        return String::new();
    };
    let key: String =
        joined[..colon].trim_end().chars().rev().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
    key.chars().rev().collect()
}

/// Whether brackets opened in `text` (outside strings and `//` comments) are left unclosed: a file cut
/// short, or a missing `)`.
fn unclosed(text: &str) -> bool {
    let mut depth = 0i64;
    for line in text.lines() {
        let mut in_string = false;
        let mut chars = line.chars().peekable();
        while let Some(c) = chars.next() {
            match c {
                '"' => in_string = !in_string,
                '\\' if in_string => {
                    chars.next();
                }
                '/' if !in_string && chars.peek() == Some(&'/') => break,
                '(' | '[' | '{' if !in_string => depth += 1,
                ')' | ']' | '}' if !in_string => depth -= 1,
                _ => {}
            }
        }
    }
    depth > 0
}

/// ron's message in a scene author's words: our patch types named as the sections they are, and the
/// common slips (a fraction where a whole number goes, a file cut short) said plainly.
pub(super) fn readable(text: &str, e: &ron::error::SpannedError) -> String {
    let (line, col) = (e.span.start.line, e.span.start.col);
    let rest: String =
        text.lines().nth(line.saturating_sub(1)).unwrap_or("").chars().skip(col.saturating_sub(1)).collect();
    let before: String =
        text.lines().nth(line.saturating_sub(1)).unwrap_or("").chars().take(col.saturating_sub(1)).collect();
    let number_before = before.trim_end().chars().last().is_some_and(|c| c.is_ascii_digit());
    if number_before && (rest.starts_with('.') || rest.starts_with('e') || rest.starts_with('E')) {
        let whole: String = before
            .chars()
            .rev()
            .take_while(|c| c.is_ascii_digit() || *c == '-')
            .collect::<Vec<_>>()
            .into_iter()
            .rev()
            .collect();
        let frac: String =
            rest.chars().take_while(|c| c.is_ascii_digit() || matches!(c, '.' | 'e' | 'E' | '-' | '+')).collect();
        return format!("must be a whole number (got {whole}{frac})");
    }
    if matches!(e.code, ron::Error::Eof) || unclosed(text) {
        return "the file ends too early: a closing `)` or `]` is missing, or the file was cut short".into();
    }
    [
        ("`ScenePatch`", "the scene"),
        ("`WorldParamsPatch`", "world"),
        ("`RewardParamsPatch`", "rewards"),
        ("`SpeciesPatch`", "a species"),
        ("`LearningParamsPatch`", "learning"),
    ]
    .iter()
    .fold(e.code.to_string(), |m, (from, to)| m.replace(from, to))
}
