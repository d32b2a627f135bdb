//! A pinned experiment's binary ([`Pin`], `results/NAME/binary/pin.ron`) made and checked: continuing such
//! an experiment rebuilds the pinned commit in a git worktree under `target/pinned/` and refuses to go on
//! unless the rebuild reproduces the pin's behavioural fingerprint; the runs are then made by the rebuild,
//! while this binary only orchestrates and aggregates (docs/src/guide/experiments.md, "Pinned binaries").

pub(crate) use crate::claims::pin::Pin;
use crate::error::Result;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// Where rebuilds are made: a worktree, its target folder and the executable per commit.
const PINNED: &str = "target/pinned";
/// The fixed run a fingerprint is taken of, on the AVX2-FMA kernels (every x86-64 machine coevo tests
/// has them): `COEVO_KERNELS=avx2 coevo --train --seed 1 --episodes 4`, in an empty folder (every pinned
/// commit has the shipped scenes built in, so it trains its own `scenes/standard.ron`).
const FINGERPRINT_RUN: [&str; 5] = ["--train", "--seed", "1", "--episodes", "4"];
const FINGERPRINT_KERNELS: &str = "avx2";

/// The executable an experiment's runs are made by, the kernel family they run on, and the experiment's
/// pin as it stands once that executable is recorded in it.
#[derive(Clone)]
pub(crate) struct Executable {
    pub(crate) path: PathBuf,
    /// Its BLAKE3 prefix (what its runs' provenance will say).
    pub(crate) blake3: String,
    pub(crate) kernels: String,
    pub(crate) pin: Option<Pin>,
}

/// The executable to make `exp`'s runs with: this one when the experiment is not pinned or this is its
/// binary; otherwise `given` (`--pinned-binary`) or a build of the pinned commit (kept from an earlier
/// call, else rebuilt), each used only after it reproduced the pin's fingerprint as a clean build of the
/// pinned commit, which then records it among the pin's rebuilds. What is checked is a copy named by its
/// hash (`target/pinned/coevo-COMMIT-HASH`), and that copy makes the runs: replacing the file it came
/// from changes nothing.
pub(crate) fn executable(exp: &super::Experiment, given: Option<&Path>) -> Result<Executable> {
    let me = std::env::current_exe().map_err(|e| format!("cannot find the coevo binary: {e}"))?;
    let this = crate::store::provenance::binary().to_string();
    let Some(pin) = &exp.pin else {
        if given.is_some() {
            return Err(not_pinned(exp));
        }
        return Ok(Executable {
            path: me,
            blake3: this,
            kernels: crate::learning::nets::kernels().name().into(),
            pin: None,
        });
    };
    if given.is_none() && pin.accepts(&this) {
        return Ok(Executable { path: me, blake3: this, kernels: pin.kernels.clone(), pin: Some(pin.clone()) });
    }
    // The pinned commit must be one of this repository before any build of it is trusted or made.
    resolve(exp, pin)?;
    let pinned = std::path::absolute(PINNED).map_err(|e| format!("{PINNED}: {e}"))?;
    let (path, blake3) = match given {
        Some(path) => {
            let path = std::path::absolute(path).map_err(|e| format!("--pinned-binary: {}: {e}", path.display()))?;
            checked(exp, pin, &pinned, &path)?
        }
        None => {
            let cached = built(&pinned, pin);
            match cached.is_file().then(|| checked(exp, pin, &pinned, &cached)) {
                Some(Ok(found)) => found,
                // None kept, or one that fails the check (another commit's, a damaged file): built anew.
                failed => {
                    if let Some(Err(e)) = failed {
                        crate::errln!("coevo: warning: {e}; building the commit again")?;
                    }
                    let built = rebuild(exp, pin)?;
                    checked(exp, pin, &pinned, &built)?
                }
            }
        }
    };
    let pin = record(exp, &blake3)?;
    Ok(Executable { path, blake3, kernels: pin.kernels.clone(), pin: Some(pin) })
}

/// Refuses a pin whose commit is not a commit of this repository (`git rev-parse --verify COMMIT^{commit}`
/// must name that same commit), before anything is built or run for it.
fn resolve(exp: &super::Experiment, pin: &Pin) -> Result<()> {
    // In the clone that holds the experiment file, wherever coevo is started from.
    let clone = exp.file.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let found = run(
        "git rev-parse",
        Command::new("git").arg("-C").arg(clone).args([
            "rev-parse",
            "--verify",
            "--quiet",
            "--end-of-options",
            &format!("{}^{{commit}}", pin.commit),
        ]),
    );
    let shown = Pin::path(&exp.root).display().to_string();
    match found {
        Ok(full) if full.trim() == pin.commit => Ok(()),
        // --quiet: a name that is no commit fails without a word; any other failure is git's to say.
        Err(e) if !e.message.ends_with(SILENT) => Err(format!(
            "{shown}: commit {} cannot be looked up in {}: {}; nothing built or run",
            pin.commit,
            clone.display(),
            e.message
        )
        .into()),
        _ => Err(format!(
            "{shown}: commit {} is not a commit of this repository (git rev-parse --verify finds none); nothing built or run",
            pin.commit
        )
        .into()),
    }
}

/// Opens a binary offered as the pinned one (`--pinned-binary`, or a kept build) for reading, refusing
/// anything but a regular executable file holding a program: a link (not followed), a FIFO (opened without
/// waiting for a writer, then refused), a device, a folder, or a script.
fn open_executable(exe: &Path) -> Result<std::fs::File> {
    use std::io::Read;
    use std::os::unix::fs::{OpenOptionsExt, PermissionsExt};
    let refuse = |why: &str| -> crate::error::Error { format!("{}: {why}", exe.display()).into() };
    let mut file =
        std::fs::File::options().read(true).custom_flags(libc::O_NONBLOCK | libc::O_NOFOLLOW).open(exe).map_err(
            |e| match e.raw_os_error() {
                Some(libc::ELOOP) => refuse("is a symbolic link; name the executable itself"),
                _ => refuse(&format!("cannot open: {e}")),
            },
        )?;
    let meta = file.metadata().map_err(|e| refuse(&format!("cannot read: {e}")))?;
    if !meta.is_file() {
        return Err(refuse("is not a regular file (a folder, FIFO or device); name a built coevo executable"));
    }
    if meta.permissions().mode() & 0o111 == 0 {
        return Err(refuse("is not executable"));
    }
    let mut magic = [0u8; 4];
    if file.read_exact(&mut magic).is_err() || magic != *b"\x7fELF" {
        return Err(refuse("is not a compiled program (no ELF header): a script or another file is not a coevo build"));
    }
    Ok(file)
}

/// Copies `exe` to `target/pinned/coevo-COMMIT-HASH` and checks that copy (unless the pin already lists
/// its hash): its path and hash. A copy that fails the check is removed.
fn checked(exp: &super::Experiment, pin: &Pin, pinned: &Path, exe: &Path) -> Result<(PathBuf, String)> {
    let mut source = open_executable(exe)?;
    std::fs::create_dir_all(pinned).map_err(|e| format!("{}: {e}", pinned.display()))?;
    let copy = pinned.join(format!(".coevo-{}.{}.tmp", pin.commit, unique()));
    let copied = (|| {
        use std::io::Seek;
        use std::os::unix::fs::OpenOptionsExt;
        source.rewind()?;
        let mut to = std::fs::File::options().write(true).create_new(true).mode(0o755).open(&copy)?;
        std::io::copy(&mut source, &mut to)?;
        to.sync_all()
    })();
    if let Err(e) = copied {
        let _ = std::fs::remove_file(&copy);
        return Err(format!("{}: cannot copy to {}: {e}", exe.display(), copy.display()).into());
    }
    let kept = blake3_prefix(&copy).and_then(|blake3| {
        let kept = pinned.join(format!("coevo-{}-{blake3}", pin.commit));
        std::fs::rename(&copy, &kept)
            .map_err(|e| format!("{}: cannot keep a copy as {}: {e}", exe.display(), kept.display()))?;
        Ok((kept, blake3))
    });
    let _ = std::fs::remove_file(&copy);
    let (kept, blake3) = kept?;
    if !pin.accepts(&blake3) {
        verify(pin, &kept).map_err(|e| {
            let _ = std::fs::remove_file(&kept);
            format!("{} ({}): {e}", exe.display(), Pin::path(&exp.root).display())
        })?;
        crate::errln!(
            "coevo: {} reproduced {}'s fingerprint {} as a clean build of it; its runs count as the pinned binary's",
            exe.display(),
            pin.commit,
            pin.fingerprint
        )?;
    }
    Ok((kept, blake3))
}

/// Adds `blake3` to the pin's verified rebuilds, read afresh from its file (another process may have added
/// its own since this one loaded it); the pin as it now stands.
fn record(exp: &super::Experiment, blake3: &str) -> Result<Pin> {
    let path = Pin::path(&exp.root);
    let mut pin =
        Pin::read(&exp.root)?.ok_or_else(|| format!("{}: removed while the experiment ran", path.display()))?;
    if !pin.accepts(blake3) {
        pin.rebuilds.push(blake3.to_string());
        crate::io::write_file(&path, crate::io::Existing::Replace, pin.to_ron().as_bytes())?;
    }
    Ok(pin)
}

/// A name part no other process uses at the same time, also on another node sharing the folder.
fn unique() -> String {
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos());
    format!("{}-{nanos}", std::process::id())
}

/// The refusal of `--pinned-binary` for an experiment that is not pinned.
pub(crate) fn not_pinned(exp: &super::Experiment) -> crate::error::Error {
    format!("--pinned-binary: {} is not pinned (it has no {})", exp.file.display(), Pin::path(&exp.root).display())
        .into()
}

/// A file's BLAKE3 prefix, as provenance names executables ([`crate::store::provenance::file_hash`]).
fn blake3_prefix(path: &Path) -> Result<String> {
    crate::store::provenance::file_hash(path).map_err(|e| format!("{}: cannot read: {e}", path.display()).into())
}

/// Runs a command to its end; Err is `what` with the last line it wrote.
/// What [`run`] says of a command that failed without a message.
const SILENT: &str = "failed without a message";

fn run(what: &str, command: &mut Command) -> Result<String> {
    let out = command.stdin(Stdio::null()).output().map_err(|e| format!("{what}: cannot start: {e}"))?;
    if !out.status.success() {
        let said = String::from_utf8_lossy(&out.stderr);
        let last = said.lines().rev().find(|l| !l.trim().is_empty()).unwrap_or(SILENT);
        return Err(format!("{what}: {last}").into());
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// Builds the pinned commit in a worktree of this clone (`target/pinned/src-COMMIT`, its own target
/// folder beside it): a worktree left there is used only when it is at the commit with nothing changed,
/// else made anew; its `Cargo.lock` must hash as the pin says. The built executable's path.
fn rebuild(exp: &super::Experiment, pin: &Pin) -> Result<PathBuf> {
    let pinned = std::path::absolute(PINNED).map_err(|e| format!("{PINNED}: {e}"))?;
    let source = pinned.join(format!("src-{}", pin.commit));
    let git = |dir: Option<&Path>, args: &[&str]| {
        let mut command = Command::new("git");
        if let Some(dir) = dir {
            command.arg("-C").arg(dir);
        }
        run(&format!("git {}", args.join(" ")), command.args(args))
    };
    // A commit of this repository ([`resolve`], before any build).
    let commit = pin.commit.as_str();
    let intact = source.join("Cargo.toml").is_file()
        && git(Some(&source), &["rev-parse", "HEAD"]).is_ok_and(|head| head.trim() == commit)
        && git(Some(&source), &["status", "--porcelain"]).is_ok_and(|changes| changes.trim().is_empty());
    if !intact {
        std::fs::create_dir_all(&pinned).map_err(|e| format!("{}: {e}", pinned.display()))?;
        let _ = std::fs::remove_dir_all(&source);
        let _ = git(None, &["worktree", "prune"]);
        let target = source.to_string_lossy().into_owned();
        git(None, &["worktree", "add", "--detach", "--force", &target, commit])?;
    }
    let lock = source.join("Cargo.lock");
    let lock_hash = blake3_prefix(&lock)?;
    if lock_hash != pin.cargo_lock {
        return Err(format!(
            "{}: {} hashes to {lock_hash}, the pin says {}; not built",
            Pin::path(&exp.root).display(),
            lock.display(),
            pin.cargo_lock
        )
        .into());
    }
    let toolchain = run("rustc --version", Command::new("rustc").arg("--version"))?;
    if toolchain.trim() != pin.toolchain {
        crate::errln!(
            "coevo: warning: {} was built with {}, this machine has {}; its fingerprint decides",
            pin.commit,
            pin.toolchain,
            toolchain.trim()
        )?;
    }
    crate::errln!(
        "coevo: {} is pinned to commit {}: building it in {} (cargo build --release --locked, some minutes)",
        exp.file.display(),
        pin.commit,
        source.display()
    )?;
    run(
        &format!("cargo build --release in {}", source.display()),
        Command::new("cargo")
            .args(["build", "--release", "--locked", "--quiet"])
            .current_dir(&source)
            .env("CARGO_TARGET_DIR", target_dir(&pinned, pin)),
    )?;
    Ok(built(&pinned, pin))
}

/// The pinned commit's own cargo target folder.
fn target_dir(pinned: &Path, pin: &Pin) -> PathBuf {
    pinned.join(format!("target-{}", pin.commit))
}

/// Where [`rebuild`] leaves the pinned commit's executable (kept for later calls).
fn built(pinned: &Path, pin: &Pin) -> PathBuf {
    target_dir(pinned, pin).join("release").join("coevo")
}

/// Runs the fixed fingerprint run with `exe` in an empty folder (so it trains its own built-in standard
/// scene, the commit's) and refuses unless it is a clean build of the pinned commit (its run's provenance
/// says so) that gives the pin's fingerprint.
fn verify(pin: &Pin, exe: &Path) -> Result<()> {
    let pinned = std::path::absolute(PINNED).map_err(|e| format!("{PINNED}: {e}"))?;
    let scratch = pinned.join(format!("fingerprint-{}-{}", pin.commit, unique()));
    std::fs::create_dir_all(&scratch).map_err(|e| format!("{}: {e}", scratch.display()))?;
    let out = scratch.join("run");
    let result = (|| {
        run(
            &format!("{} (the fingerprint run)", exe.display()),
            Command::new(exe)
                .args(FINGERPRINT_RUN)
                .args(["--quiet", "--out"])
                .arg(&out)
                .current_dir(&scratch)
                .env("COEVO_KERNELS", FINGERPRINT_KERNELS),
        )?;
        let commit = crate::store::RunDir::new(&out).read_provenance()?.map(|p| p.git_commit).unwrap_or_default();
        Ok::<_, crate::error::Error>((commit, crate::store::provenance::fingerprint(&out)?))
    })();
    let _ = std::fs::remove_dir_all(&scratch);
    let (commit, fingerprint) = result?;
    let (a, b) = (commit.as_str(), pin.commit.as_str());
    // The build names its commit abbreviated (build.rs); the pin names it in full (Pin::read).
    if commit.ends_with("-dirty") || a.len() < 7 || !b.starts_with(a) {
        return Err(format!(
            "it is a build of {commit}, not a clean build of the pinned commit {}; refusing to continue the experiment with it",
            pin.commit
        )
        .into());
    }
    if fingerprint != pin.fingerprint {
        return Err(format!(
            "it gives fingerprint {fingerprint} where the pin says {}: it does not compute what the pinned binary computed; refusing to continue the experiment with it",
            pin.fingerprint
        )
        .into());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pin() -> Pin {
        Pin {
            commit: "d0d37dbf394b1d02e9ecf17a13db44e974727c70".into(),
            blake3: "9c75d3d457b4067d".into(),
            toolchain: "rustc 1.95.0".into(),
            cargo_lock: "0".into(),
            kernels: "avx512".into(),
            fingerprint: "2eee7e2b9b23e15b".into(),
            rebuilds: vec!["aaaa".into()],
        }
    }

    #[test]
    fn the_original_and_its_verified_rebuilds_are_one_binary() {
        let p = pin();
        assert!(Pin::same(Some(&p), "9c75d3d457b4067d", "aaaa"));
        assert!(!Pin::same(Some(&p), "9c75d3d457b4067d", "bbbb"));
        assert!(!Pin::same(None, "9c75d3d457b4067d", "aaaa"));
        assert!(Pin::same(None, "bbbb", "bbbb"));
    }

    #[test]
    fn a_pin_reads_back_what_it_wrote_and_refuses_a_commit_that_is_not_one() {
        let dir = tempfile::tempdir().unwrap();
        let path = Pin::path(dir.path());
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, pin().to_ron()).unwrap();
        assert_eq!(Pin::read(dir.path()).unwrap(), Some(pin()));
        std::fs::write(&path, pin().to_ron().replace("d0d37dbf394b1d02e9ecf17a13db44e974727c70", "--help")).unwrap();
        let err = Pin::read(dir.path()).unwrap_err().to_string();
        assert!(err.contains("pin.ron") && err.contains("is not a commit"), "{err}");
        // Abbreviated, or in capitals: not the full name git prints.
        for commit in ["d0d37db", "D0D37DBF394B1D02E9ECF17A13DB44E974727C70", "0"] {
            std::fs::write(&path, pin().to_ron().replace("d0d37dbf394b1d02e9ecf17a13db44e974727c70", commit)).unwrap();
            let err = Pin::read(dir.path()).unwrap_err().to_string();
            assert!(err.contains("is not a commit's full name"), "{err}");
        }
        assert_eq!(Pin::read(&dir.path().join("elsewhere")).unwrap(), None);
    }
}
