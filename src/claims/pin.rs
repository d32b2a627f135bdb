//! A pinned experiment's record of its binary, `results/NAME/binary/pin.ron`: the commit every run of the
//! experiment is made at, recorded instead of the executable (git keeps no executables), and which
//! executables' runs count as that binary's. Building and checking the binary is `experiment::pin`'s.
//!
//! Two builds of one commit are different files (codegen is not byte-reproducible here) that compute the
//! same numbers, so a verified rebuild's BLAKE3 prefix is added to the pin's `rebuilds`: the runner and
//! aggregation count runs of the original and of its verified rebuilds as one binary's.

use crate::error::Result;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The folder of an experiment's results that records its binary (`results/NAME/binary/`).
pub(crate) const BINARY_DIR: &str = "binary";
/// The pin itself, in that folder.
pub(crate) const PIN: &str = "pin.ron";

/// What a pinned experiment records of its binary.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Pin {
    /// The commit the binary is built at (`cargo build --release`, no viewer).
    pub(crate) commit: String,
    /// The original executable's BLAKE3 prefix: every run's `provenance.ron` `binary`.
    pub(crate) blake3: String,
    /// `rustc --version` of the original build (a rebuild with another is warned about; its
    /// fingerprint decides).
    pub(crate) toolchain: String,
    /// BLAKE3 prefix of the commit's `Cargo.lock`: a worktree holding another is not built.
    pub(crate) cargo_lock: String,
    /// The matrix-product kernel family of its runs (`provenance.ron`'s `kernels`): its runs are
    /// continued on it, whatever this machine would pick.
    pub(crate) kernels: String,
    /// `coevo --fingerprint` of the fixed run above, by the original.
    pub(crate) fingerprint: String,
    /// BLAKE3 prefixes of rebuilds that reproduced the fingerprint; their runs count as the original's.
    #[serde(default)]
    pub rebuilds: Vec<String>,
}

impl Pin {
    /// `results/NAME/binary/pin.ron` of the experiment whose results folder is `root`.
    pub(crate) fn path(root: &Path) -> PathBuf {
        root.join(BINARY_DIR).join(PIN)
    }

    /// The pin of the experiment whose results folder is `root`, None when it is not pinned.
    pub fn read(root: &Path) -> Result<Option<Pin>> {
        let path = Pin::path(root);
        if !path.exists() {
            return Ok(None);
        }
        let text = crate::io::read_text(&path, crate::io::MAX_TEXT_BYTES)?;
        let pin: Pin = crate::scene::parse_ron(&text, &path.display().to_string())?;
        // A full name only: an abbreviation may name another commit once the history grows, and a prefix
        // test against it would accept any build whose name begins alike.
        if !matches!(pin.commit.len(), 40 | 64)
            || !pin.commit.chars().all(|c| c.is_ascii_digit() || ('a'..='f').contains(&c))
        {
            return Err(format!(
                "{}: commit {:?} is not a commit's full name (40 lowercase hexadecimal digits, as `git rev-parse COMMIT` prints it)",
                path.display(),
                pin.commit
            )
            .into());
        }
        Ok(Some(pin))
    }

    /// Whether runs by the executable with this BLAKE3 prefix are the pinned binary's.
    pub(crate) fn accepts(&self, blake3: &str) -> bool {
        blake3 == self.blake3 || self.rebuilds.iter().any(|r| r == blake3)
    }

    /// Whether two executables' runs are one binary's: the same file, or both the pin's.
    pub(crate) fn same(pin: Option<&Pin>, a: &str, b: &str) -> bool {
        a == b || pin.is_some_and(|p| p.accepts(a) && p.accepts(b))
    }

    pub(crate) fn to_ron(&self) -> String {
        let config = ron::ser::PrettyConfig::new().struct_names(false);
        ron::ser::to_string_pretty(self, config).expect("a pin serializes") + "\n"
    }
}
