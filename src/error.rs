//! coevo's one error type: every failure is reported as one line naming the file (or flag) it concerns,
//! the line in it when known, and the field, then what is wrong: `file:line: field: message`. Parts that
//! are not known are left out, so an error made deep down (a field of a scene being validated) gains its
//! file where the file is known ([`Error::in_file`]).
//!
//! Each error also has a [`Kind`]: what went wrong, for programs that drive coevo (the Python package
//! raises one exception class per kind). The kind is set where a concern hands its error on (a scene
//! loaded, a checkpoint read, a run folder checked), the innermost first, and never printed.

use std::path::Path;

/// An error as one line: `[file[:line]: ][field: ]message`.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{}", self.line_text())]
pub struct Error {
    /// The file (or flag, such as `--eval-out x.csv`) the error concerns.
    pub(crate) file: Option<String>,
    /// The line in that file, when the error comes from reading it.
    pub(crate) line: Option<usize>,
    /// The field, as a path such as `species[prey].mass`.
    pub field: Option<String>,
    pub(crate) message: String,
    /// What went wrong, for programs (not printed).
    pub kind: Kind,
}

/// What an error concerns.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Kind {
    /// Not classified.
    #[default]
    Other,
    /// A scene file or scene value: unreadable, invalid, unstable, too large.
    Scene,
    /// A checkpoint or snapshot: missing, damaged, of another run, scene or species.
    Checkpoint,
    /// A run folder: in use, of another scene, not a run, shipped, incomplete data.
    RunFolder,
    /// An experiment file or its results.
    Experiment,
    /// A command-line flag or argument from a program.
    Input,
    /// The simulation left the physically possible (a NaN, an escaped body).
    Simulation,
    /// Reading or writing a file failed (permissions, full disk, a link where none may be).
    Io,
}

/// What coevo's fallible functions return.
pub(crate) type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// An error about a field: `field: message`.
    pub(crate) fn field(field: String, message: String) -> Error {
        Error { file: None, line: None, field: Some(field), message, kind: Kind::Other }
    }

    /// The error as one of `kind`, unless an inner concern already classified it.
    pub fn of_kind(mut self, kind: Kind) -> Error {
        if self.kind == Kind::Other {
            self.kind = kind;
        }
        self
    }

    /// The error as it concerns `file`, unless it already names one.
    pub(crate) fn in_file(mut self, file: &Path) -> Error {
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
        Error { file: None, line: None, field: None, message, kind: Kind::Other }
    }
}

/// `.kind(Kind::Scene)` on any coevo result: classifies its error ([`Error::of_kind`]).
pub(crate) trait ResultExt<T> {
    fn kind(self, kind: Kind) -> Result<T>;
}

impl<T, E: Into<Error>> ResultExt<T> for std::result::Result<T, E> {
    fn kind(self, kind: Kind) -> Result<T> {
        self.map_err(|e| e.into().of_kind(kind))
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
        assert_eq!(
            e.clone().in_file(Path::new("other.ron")).file.as_deref(),
            Some("s.ron"),
            "the first file named stays"
        );
        let classified = e.of_kind(Kind::Scene).of_kind(Kind::RunFolder);
        assert_eq!(classified.kind, Kind::Scene, "the innermost kind stays");
        assert_eq!(classified.to_string(), "s.ron: world.dt: must be > 0", "the kind is not printed");
    }
}
