//! `coevo --bench --bench-against OTHER`: is this build faster or slower than another, and does it still
//! train the same run? Both binaries train the same short run ([`EPISODES`] episodes of the default scene,
//! one thread, AVX2-FMA kernels, so any x86-64 machine with FMA compares like with like), in [`PAIRS`]
//! pairs, the order alternating from pair to pair so that a machine speeding up or slowing down during
//! the call weighs on both alike. Each run's CPU time (user + system, the operating system's accounting
//! of the finished child) is taken, and the median of the pairs' ratios printed beside the range. The
//! runs' `metrics.csv` are then compared, every column but the wall clock: identical says the other
//! binary trains what this one trains, to the bit. A benchmark, never a test: timings depend on the
//! machine and what else it runs.

use std::path::Path;
use std::process::{Command, Stdio};

/// Episodes of each timed training: long enough to include two checkpoints of full replay buffers (the
/// standard scene's prey fill theirs in 100 episodes), short enough for five pairs in a few minutes.
pub(crate) const EPISODES: usize = 200;

/// Timed pairs.
pub(crate) const PAIRS: usize = 5;

pub(crate) fn main(other: &Path) -> crate::error::Result<()> {
    match std::fs::metadata(other) {
        Ok(m) if m.is_file() => {}
        Ok(_) => return Err(format!("--bench-against {}: not a file", other.display()).into()),
        Err(e) => return Err(format!("--bench-against {}: {e}", other.display()).into()),
    }
    let this = std::env::current_exe().map_err(|e| format!("--bench-against: this program's path: {e}"))?;
    let scratch = std::env::temp_dir().join(format!("coevo-bench-against-{}", std::process::id()));
    crate::io::register_temporary(&scratch);
    let result = pairs(&this, other, &scratch);
    let _ = std::fs::remove_dir_all(&scratch);
    crate::io::unregister_temporary(&scratch);
    let (ratios, same) = result?;
    let mut sorted = ratios.clone();
    sorted.sort_by(f64::total_cmp);
    crate::outln!(
        "CPU time, this / other: median {:.3} (min {:.3}, max {:.3}) over {PAIRS} pairs of `--train --episodes {EPISODES} --threads 1 --kernels avx2`",
        sorted[PAIRS / 2],
        sorted[0],
        sorted[PAIRS - 1]
    )?;
    crate::outln!(
        "training metrics (every column of metrics.csv but the wall clock): {}",
        if same { "identical" } else { "DIFFERENT: the two binaries train different runs" }
    )
}

/// The pairs' CPU-time ratios (this / other) and whether the last pair's metrics agree.
fn pairs(this: &Path, other: &Path, scratch: &Path) -> crate::error::Result<(Vec<f64>, bool)> {
    let mut ratios = Vec::new();
    let mut same = true;
    for pair in 0..PAIRS {
        let mut cpu = [0.0; 2];
        let order = if pair % 2 == 0 { [0, 1] } else { [1, 0] };
        for which in order {
            let exe = if which == 0 { this } else { other };
            cpu[which] = timed_training(exe, &scratch.join(["this", "other"][which]))?;
        }
        let metrics = |name: &str| metrics_without_wall(&scratch.join(name).join("metrics.csv"));
        same &= metrics("this")? == metrics("other")?;
        crate::outln!(
            "pair {}: this {:.2} s, other {:.2} s CPU, ratio {:.3}",
            pair + 1,
            cpu[0],
            cpu[1],
            cpu[0] / cpu[1]
        )?;
        ratios.push(cpu[0] / cpu[1]);
    }
    Ok((ratios, same))
}

/// The CPU seconds (user + system) of one training by `exe` into `out` (replaced).
fn timed_training(exe: &Path, out: &Path) -> crate::error::Result<f64> {
    let _ = std::fs::remove_dir_all(out);
    std::fs::create_dir_all(out.parent().unwrap_or(Path::new("."))).map_err(|e| format!("{}: {e}", out.display()))?;
    let before = children_cpu();
    let episodes = EPISODES.to_string();
    let args = ["--train", "--episodes", &episodes, "--quiet", "--threads", "1", "--kernels", "avx2", "--out"];
    let done = Command::new(exe)
        .args(args)
        .arg(out)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .output()
        .map_err(|e| format!("--bench-against: cannot run {}: {e}", exe.display()))?;
    if !done.status.success() {
        let said = String::from_utf8_lossy(&done.stderr);
        return Err(format!("--bench-against: {} failed: {}", exe.display(), said.lines().next().unwrap_or("")).into());
    }
    Ok(children_cpu() - before)
}

/// User + system seconds of every child this process has waited for so far.
fn children_cpu() -> f64 {
    // SAFETY: getrusage writes one rusage into the zeroed value it is given and reads nothing else.
    let usage = unsafe {
        let mut usage: libc::rusage = std::mem::zeroed();
        libc::getrusage(libc::RUSAGE_CHILDREN, &mut usage);
        usage
    };
    let seconds = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    seconds(usage.ru_utime) + seconds(usage.ru_stime)
}

/// A run's metrics.csv without its wall-clock column (the one column two identical runs differ in).
fn metrics_without_wall(path: &Path) -> crate::error::Result<Vec<String>> {
    let text = crate::io::read_text(path, crate::io::MAX_TEXT_BYTES)?;
    let header: Vec<&str> = text.lines().next().unwrap_or("").split(',').collect();
    let wall = header.iter().position(|c| *c == crate::store::schema::WALL_SECONDS);
    Ok(text
        .lines()
        .map(|l| {
            l.split(',').enumerate().filter(|(i, _)| Some(*i) != wall).map(|(_, c)| c).collect::<Vec<_>>().join(",")
        })
        .collect())
}
