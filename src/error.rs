//! coevo's one error type: every failure is reported as one line naming the file (or flag) it concerns,
//! the line in it when known, and the field, then what is wrong: `file:line: field: message`. Parts that
//! are not known are left out, so an error made deep down (a field of a scene being validated) gains its
//! file where the file is known ([`Error::in_file`]).

use std::path::Path;

/// An error as one line: `[file[:line]: ][field: ]message`.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{}", self.line_text())]
pub struct Error {
    /// The file (or flag, such as `--eval-out x.csv`) the error concerns.
    pub file: Option<String>,
    /// The line in that file, when the error comes from reading it.
    pub line: Option<usize>,
    /// The field, as a path such as `species[prey].mass`.
    pub field: Option<String>,
    pub message: String,
}

/// What coevo's fallible functions return.
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// An error about a field: `field: message`.
    pub fn field(field: String, message: String) -> Error {
        Error { file: None, line: None, field: Some(field), message }
    }

    /// The error as it concerns `file`, unless it already names one.
    pub fn in_file(mut self, file: &Path) -> Error {
        self.file.get_or_insert_with(|| file.display().to_string());
        self
    }

    fn line_text(&self) -> String {
        let mut out = String::new();
        if let Some(file) = &self.file {
            out.push_str(file);
            if let Some(line) = self.line {
                out.push_str(&format!(":{line}"));
            }
            out.push_str(": ");
        }
        if let Some(field) = self.field.as_ref().filter(|f| !f.is_empty()) {
            out.push_str(field);
            out.push_str(": ");
        }
        out.push_str(&self.message);
        out
    }
}

impl From<String> for Error {
    fn from(message: String) -> Error {
        Error { file: None, line: None, field: None, message }
    }
}

impl From<&str> for Error {
    fn from(message: &str) -> Error {
        Error::from(message.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_line_with_what_is_known() {
        assert_eq!(Error::from("no run").to_string(), "no run");
        assert_eq!(Error::field("world.dt".into(), "must be > 0".into()).to_string(), "world.dt: must be > 0");
        let e = Error::field("world.dt".into(), "must be > 0".into()).in_file(Path::new("s.ron"));
        assert_eq!(e.to_string(), "s.ron: world.dt: must be > 0");
        assert_eq!(Error { line: Some(3), ..e.clone() }.to_string(), "s.ron:3: world.dt: must be > 0");
        assert_eq!(e.in_file(Path::new("other.ron")).file.as_deref(), Some("s.ron"), "the first file named stays");
    }
}
