//! An experiment on a real Slurm cluster: one node on this machine (Debian's `slurmctld`, `slurmd` and
//! `munge`, which `.ci/run` installs), started with a minimal `slurm.conf` written here (no cgroups, no
//! accounting), the scripts `--emit-slurm` writes submitted as a user submits them. The results must equal
//! the same experiment run locally with `--jobs 2`, also after `scancel` killed the array mid-run and it was
//! submitted again. Starting daemons needs root: as another user the test says so and passes.

use super::experiment::{coevo, summary_of as summary, workspace_with};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The tiny experiment of `experiment.rs` with runs long enough to be killed between two checkpoints.
const SWEEP: &str = r#"(
    description: "a tiny sweep on a cluster",
    base: "scenes/paper.ron",
    seeds: [1, 2],
    episodes: 40,
    variants: [
        (name: "1:1", patch: (episode_steps: 60, learning: (hidden: 16, batch_size: 32, warmup_transitions: 32, updates_per_episode: 3, checkpoint_every: 1))),
        (name: "5:3", patch: (episode_steps: 60, species: [(name: "prey", max_speed: 0.1)], learning: (hidden: 16, batch_size: 32, warmup_transitions: 32, updates_per_episode: 3, checkpoint_every: 1))),
    ],
    evaluations: [(name: "50 prey", counts: [("prey", 50)], episodes: 2, steps: 20)],
    claims: [
        (text: "5:3 against 1:1", variant: "5:3", versus: "1:1", quantity: DosLast),
        (text: "DoA rises", variant: "1:1", quantity: FromStart("doa")),
    ],
)"#;

/// A one-node cluster of this machine: its daemons are children of the test, stopped when it ends.
struct Cluster {
    conf: PathBuf,
    daemons: Vec<Child>,
    _dir: tempfile::TempDir,
}

impl Cluster {
    /// Starts munge (unless one answers already), slurmctld and slurmd on ports free now; None (with why)
    /// where this user cannot start daemons.
    fn start() -> Option<Cluster> {
        // SAFETY: geteuid has no preconditions and cannot fail.
        if unsafe { libc::geteuid() } != 0 {
            eprintln!(
                "slurm: skipped: starting slurmctld, slurmd and munged needs root (bash .ci/run runs it as root)"
            );
            return None;
        }
        for daemon in ["/usr/sbin/slurmctld", "/usr/sbin/slurmd", "/usr/sbin/munged", "/usr/bin/sbatch"] {
            assert!(
                Path::new(daemon).exists(),
                "{daemon} is missing: install Debian's slurmctld slurmd munge (bash .ci/run installs them)"
            );
        }
        let dir = tempfile::tempdir().unwrap();
        let mut daemons = Vec::new();
        if !munge_answers() {
            std::fs::create_dir_all("/run/munge").unwrap();
            assert!(Command::new("chown").args(["munge:munge", "/run/munge"]).status().unwrap().success());
            // As the munge user (munged refuses root), itself the child, so that it stops with the test.
            let id = |flag: &str| -> u32 {
                let out = Command::new("id").args([flag, "munge"]).output().unwrap();
                String::from_utf8_lossy(&out.stdout).trim().parse().expect("a munge user (Debian's munge package)")
            };
            let munged = Command::new("/usr/sbin/munged")
                .arg("--foreground")
                .uid(id("-u"))
                .gid(id("-g"))
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .unwrap();
            daemons.push(munged);
            wait_for("munged to answer", Duration::from_secs(20), munge_answers);
        }
        let host = hostname();
        let port = || std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
        let (ctld_port, d_port) = (port(), port());
        let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
        let d = dir.path().display();
        for sub in ["state", "spool"] {
            std::fs::create_dir(dir.path().join(sub)).unwrap();
        }
        // The node offers the memory `--emit-slurm`'s scripts ask for (2 GB a run, 4 GB the aggregation);
        // memory is not a consumable resource (CR_Core), so this is a bound, not a reservation.
        let conf = format!(
            "ClusterName=coevo-test\nSlurmctldHost={host}(127.0.0.1)\nSlurmUser=root\nSlurmdUser=root\n\
             AuthType=auth/munge\nCredType=cred/munge\nStateSaveLocation={d}/state\nSlurmdSpoolDir={d}/spool\n\
             SlurmctldPidFile={d}/slurmctld.pid\nSlurmdPidFile={d}/slurmd.pid\n\
             SlurmctldLogFile={d}/slurmctld.log\nSlurmdLogFile={d}/slurmd.log\n\
             SlurmctldPort={ctld_port}\nSlurmdPort={d_port}\n\
             ProctrackType=proctrack/linuxproc\nTaskPlugin=task/none\nMpiDefault=none\n\
             SchedulerType=sched/backfill\nSelectType=select/cons_tres\nSelectTypeParameters=CR_Core\n\
             ReturnToService=2\nJobAcctGatherType=jobacct_gather/none\nAccountingStorageType=accounting_storage/none\n\
             KillWait=10\n\
             NodeName={host} NodeAddr=127.0.0.1 CPUs={cpus} RealMemory=4096 State=UNKNOWN\n\
             PartitionName=test Nodes=ALL Default=YES MaxTime=INFINITE State=UP\n"
        );
        let path = dir.path().join("slurm.conf");
        std::fs::write(&path, conf).unwrap();
        for (daemon, flags) in [("/usr/sbin/slurmctld", &["-D", "-i"][..]), ("/usr/sbin/slurmd", &["-D"][..])] {
            let child = Command::new(daemon)
                .args(flags)
                .env("SLURM_CONF", &path)
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .unwrap();
            daemons.push(child);
        }
        let cluster = Cluster { conf: path, daemons, _dir: dir };
        wait_for("the node to be idle", Duration::from_secs(60), || {
            cluster.client("sinfo", &["-h", "-o", "%T"]).trim() == "idle"
        });
        Some(cluster)
    }

    /// A Slurm client command's standard output (it must succeed).
    fn client(&self, program: &str, args: &[&str]) -> String {
        let out = Command::new(program).args(args).env("SLURM_CONF", &self.conf).output().unwrap();
        assert!(out.status.success(), "{program} {args:?}: {}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8_lossy(&out.stdout).into_owned()
    }

    /// Runs one of the guide's commands in `root`, as a user does (`coevo` on the PATH).
    fn run(&self, root: &Path, command: &str) {
        let bin = Path::new(env!("CARGO_BIN_EXE_coevo")).parent().unwrap();
        let path = format!("{}:{}", bin.display(), std::env::var("PATH").unwrap_or_default());
        let out = Command::new("bash")
            .args(["-c", command])
            .env("SLURM_CONF", &self.conf)
            .env("PATH", path)
            .current_dir(root)
            .output()
            .unwrap();
        assert!(out.status.success(), "{command}: {}", String::from_utf8_lossy(&out.stderr));
    }

    /// Waits until no job is queued or running.
    fn drain(&self, within: Duration) {
        wait_for("the queue to empty", within, || self.client("squeue", &["-h"]).trim().is_empty());
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        for child in self.daemons.iter_mut().rev() {
            // SAFETY: kill has no memory preconditions; the PID is our own child's, not yet reaped.
            unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) };
            let _ = child.wait();
        }
    }
}

fn munge_answers() -> bool {
    Command::new("sh")
        .args(["-c", "munge -n | unmunge"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

fn hostname() -> String {
    let mut buf = [0u8; 256];
    // SAFETY: the buffer is writable for its length; gethostname NUL-terminates within it on success.
    assert_eq!(unsafe { libc::gethostname(buf.as_mut_ptr().cast(), buf.len()) }, 0);
    let end = buf.iter().position(|&b| b == 0).unwrap();
    String::from_utf8_lossy(&buf[..end]).split('.').next().unwrap().to_string()
}

fn wait_for(what: &str, within: Duration, mut done: impl FnMut() -> bool) {
    let start = Instant::now();
    while !done() {
        assert!(start.elapsed() < within, "waited {within:?} for {what}");
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// Every run's `metrics.csv` under `root`'s results, without its wall-clock column, by run folder.
fn metrics(root: &Path) -> Vec<(String, String)> {
    let mut runs = Vec::new();
    for variant in ["1-1", "5-3"] {
        for seed in ["seed1", "seed2"] {
            let run = format!("results/sweep/paper/{variant}/{seed}");
            let text = std::fs::read_to_string(root.join(&run).join("metrics.csv")).unwrap();
            let wall = text.lines().next().unwrap().split(',').position(|c| c == "wall_seconds").unwrap();
            let kept: Vec<String> = text
                .lines()
                .map(|l| {
                    l.split(',').enumerate().filter(|(i, _)| *i != wall).map(|(_, c)| c).collect::<Vec<_>>().join(",")
                })
                .collect();
            runs.push((run, kept.join("\n")));
        }
    }
    runs
}

/// REPORT.md without the training time (wall clock) of its runs.
fn report(root: &Path) -> String {
    let text = std::fs::read_to_string(root.join("results/sweep/REPORT.md")).unwrap();
    text.lines().filter(|l| !l.contains(" h | `")).collect::<Vec<_>>().join("\n")
}

/// The commands of the experiments guide's "On a cluster" section, for the experiment `sweep` (the guide's
/// `standard`): emit, submit, look at the queue, cancel the array, cancel the aggregation, submit again.
fn guide_commands() -> Vec<String> {
    let guide = std::fs::read_to_string("docs/src/guide/experiments.md").unwrap();
    let section = guide.split("## On a cluster (Slurm)").nth(1).expect("the guide's section \"On a cluster (Slurm)\"");
    let block = section.split("```sh\n").nth(1).unwrap().split("```").next().unwrap();
    let commands: Vec<String> = block
        .lines()
        .map(|l| l.split('#').next().unwrap().trim().replace("standard", "sweep"))
        .filter(|l| !l.is_empty())
        .collect();
    assert_eq!(
        commands,
        [
            "coevo --experiment experiments/sweep.ron --emit-slurm",
            "bash results/sweep/slurm/submit.sh",
            "squeue --name sweep",
            "scancel --name sweep",
            "scancel --name sweep-aggregate",
            "bash results/sweep/slurm/submit.sh",
        ],
        "the guide shows what this test runs"
    );
    commands
}

#[test]
fn an_experiment_on_a_real_slurm_cluster_equals_the_local_run_also_after_scancel() {
    let [emit, submit, queue, cancel, cancel_aggregate, resubmit] = <[String; 6]>::try_from(guide_commands()).unwrap();
    let Some(cluster) = Cluster::start() else { return };
    let local = workspace_with("sweep", SWEEP);
    let out = coevo(local.path(), &["--experiment", "experiments/sweep.ron", "--jobs", "2", "--quiet"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));

    // Submitted whole: the array, then the aggregation once every task succeeded.
    let remote = workspace_with("sweep", SWEEP);
    cluster.run(remote.path(), &emit);
    cluster.run(remote.path(), &submit);
    cluster.run(remote.path(), &queue);
    cluster.drain(Duration::from_secs(600));
    let logs = remote.path().join("results/sweep/slurm");
    let aggregated = std::fs::read_to_string(logs.join("aggregate.log")).unwrap_or_default();
    assert!(aggregated.contains("wrote results/sweep/summary.csv"), "the aggregation ran: {aggregated}");
    assert_eq!(metrics(remote.path()), metrics(local.path()), "training metrics");
    assert_eq!(summary(remote.path(), "sweep"), summary(local.path(), "sweep"), "summary.csv");
    assert_eq!(report(remote.path()), report(local.path()), "REPORT.md");

    // Cancelled mid-run after a checkpoint, then submitted again: the killed runs resume.
    let killed = workspace_with("sweep", SWEEP);
    cluster.run(killed.path(), &emit);
    cluster.run(killed.path(), &submit);
    let first = killed.path().join("results/sweep/paper/1-1/seed1");
    wait_for("a checkpoint of the first run", Duration::from_secs(300), || first.join("checkpoint/state.ron").exists());
    cluster.run(killed.path(), &cancel);
    wait_for("the array to end", Duration::from_secs(120), || {
        cluster.client("squeue", &["-h", "--name", "sweep"]).trim().is_empty()
    });
    // The aggregation waits for a success that will not come.
    cluster.run(killed.path(), &cancel_aggregate);
    cluster.drain(Duration::from_secs(60));
    let state = std::fs::read_to_string(first.join("checkpoint/state.ron")).unwrap();
    let done: usize = state.split("episodes_done: ").nth(1).unwrap().split(',').next().unwrap().trim().parse().unwrap();
    assert!(done < 40, "the run was stopped before its end (it had {done} episodes)");
    assert!(!killed.path().join("results/sweep/summary.csv").exists(), "nothing aggregated from a cancelled array");
    cluster.run(killed.path(), &resubmit);
    cluster.drain(Duration::from_secs(600));
    assert_eq!(metrics(killed.path()), metrics(local.path()), "training metrics after the cancel");
    assert_eq!(summary(killed.path(), "sweep"), summary(local.path(), "sweep"), "summary.csv after the cancel");
    assert_eq!(report(killed.path()), report(local.path()), "REPORT.md after the cancel");
}
