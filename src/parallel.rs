//! Coarse-grained parallelism that never changes a result.
//!
//! The networks' matrices are small (256 × 64 at most in an update, a few rows per step in inference): split
//! across threads they spend more time synchronising than computing, and the default rayon pool made a
//! training run ~2× slower with two threads than with one. So dfdx's kernels always run on one thread
//! ([`single_threaded_kernels`]), and the cores are used at a coarser grain: one learned species per
//! thread in the DDPG updates, chunks of agents in perception and inference. Every piece of work is
//! computed exactly as it would be alone (same inputs, same random stream, same chunking, or chunks of
//! agents each computed alone, where the chunking cannot matter), so the number of threads decides only
//! how long a run takes, never what it computes.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Once;

static THREADS: AtomicUsize = AtomicUsize::new(0);

/// Worker threads for coarse-grained work: set by `--threads`, else `COEVO_THREADS`, else the machine's
/// available cores.
pub(crate) fn threads() -> usize {
    match THREADS.load(Ordering::Relaxed) {
        0 => {
            let n = std::env::var("COEVO_THREADS")
                .ok()
                .and_then(|v| v.parse::<usize>().ok())
                .filter(|&n| n > 0)
                .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
            THREADS.store(n, Ordering::Relaxed);
            n
        }
        n => n,
    }
}

/// Sets the number of worker threads (at least 1).
pub fn set_threads(n: usize) {
    THREADS.store(n.max(1), Ordering::Relaxed);
}

/// Makes dfdx's matrix products run on the calling thread: dfdx asks rayon's global pool how many
/// threads to split a product over, so that pool gets one thread (whatever `RAYON_NUM_THREADS` says).
/// Called once per process, before the first network is built; a no-op when the embedding program has
/// already built rayon's global pool (results are the same, only slower).
pub(crate) fn single_threaded_kernels() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let _ = rayon::ThreadPoolBuilder::new().num_threads(1).build_global();
    });
}

/// Runs `f` on every item, up to [`threads`] at a time; each item is processed exactly as it would be
/// sequentially (the caller keeps the items independent: their own buffers, their own random streams).
///
/// The items are handed out one at a time, first come first served, to the calling thread and to the
/// idle threads of a pool that lives as long as the process ([`Pool`]). So a worker that the machine does
/// not schedule (other work on its core) takes no item and holds nothing up: the calling thread does its
/// share, and waits only for items a worker has actually begun. Which thread computes an item never
/// changes what it computes.
pub(crate) fn for_each_mut<T: Send>(items: &mut [T], f: impl Fn(&mut T) + Sync) {
    for_each_mut_on(items, threads(), f);
}

/// [`for_each_mut`] on at most `workers` threads (at least one, at most [`threads`]).
pub(crate) fn for_each_mut_on<T: Send>(items: &mut [T], workers: usize, f: impl Fn(&mut T) + Sync) {
    let workers = workers.clamp(1, threads()).min(items.len());
    if workers <= 1 {
        items.iter_mut().for_each(f);
        return;
    }
    on_pool(items, workers - 1, f);
}

/// `f` on every item, on the calling thread and up to `helpers` threads of the [`Pool`].
fn on_pool<T: Send>(items: &mut [T], helpers: usize, f: impl Fn(&mut T) + Sync) {
    let base = SendPtr(items.as_mut_ptr());
    let run = move |i: usize| {
        // The whole wrapper, so the closure is Sync whatever T is.
        let base = &base;
        // SAFETY: `Job` hands out each index below `items.len()` exactly once, and `Pool::run` returns
        // only when every item handed out is finished, so each &mut is unique and outlives no borrow.
        f(unsafe { &mut *base.0.add(i) })
    };
    Pool::global().run(items.len(), helpers, &run);
}

/// Learns, for work repeated many times over (a `VecEnv` step), whether one thread or all of them
/// ([`threads`]) finishes it sooner, from the wall time of the last calls: on a busy machine a step on
/// all threads can wait for a thread the machine runs late, and one thread is then faster. Every
/// [`Adaptive::EXPLORE_EVERY`]th call tries the other choice, so a change in the machine's load is seen.
/// Only speed depends on it: which thread computes an item never changes what it computes.
#[derive(Clone, Debug, Default)]
pub(crate) struct Adaptive {
    /// Running mean of seconds per call, on one thread (0) and on all (1); None until tried.
    seconds: [Option<f64>; 2],
    /// Calls made with each choice.
    tried: [u64; 2],
    calls: u64,
}

impl Adaptive {
    /// One call in this many runs on the choice that looks slower.
    pub(crate) const EXPLORE_EVERY: u64 = 32;
    /// Weight of the newest call in the running means.
    const WEIGHT: f64 = 0.125;
    /// All threads are chosen when their mean time is below this fraction of one thread's.
    const MARGIN: f64 = 0.9;

    /// Runs `f` with the worker count to use (1, or `cap` threads: None for [`threads`], never more)
    /// and learns from its wall time.
    pub(crate) fn run_at_most<R>(&mut self, cap: Option<usize>, f: impl FnOnce(usize) -> R) -> R {
        self.run_among(cap.map_or(threads(), |c| c.clamp(1, threads())), f)
    }

    fn run_among<R>(&mut self, all: usize, f: impl FnOnce(usize) -> R) -> R {
        if all <= 1 {
            return f(1);
        }
        let (choice, explored) = match self.seconds {
            [None, _] => (0, true),
            [_, None] => (1, true),
            [Some(one), Some(many)] => {
                // All threads only when clearly faster: when the two are about even (a busy machine), a
                // step on all of them risks waiting for a thread the machine runs late, one thread does not.
                let better = usize::from(many < Self::MARGIN * one);
                if self.calls % Self::EXPLORE_EVERY == Self::EXPLORE_EVERY - 1 {
                    (1 - better, true)
                } else {
                    (better, false)
                }
            }
        };
        self.calls += 1;
        let start = std::time::Instant::now();
        let out = f(if choice == 0 { 1 } else { all });
        let took = start.elapsed().as_secs_f64();
        // A choice's first call (which may start the pool's threads) is replaced by its second, and a
        // choice tried only now and then is as fast as its last try says: a mean from before the machine's
        // load changed would otherwise keep the slower choice for hundreds of calls.
        self.tried[choice] += 1;
        let mean = &mut self.seconds[choice];
        *mean = Some(match *mean {
            Some(m) if !explored && self.tried[choice] > 2 => m + Self::WEIGHT * (took - m),
            _ => took,
        });
        out
    }
}

/// A pointer to the items that the pool's threads may share; each index is dereferenced by one thread.
struct SendPtr<T>(*mut T);
// SAFETY: the items are `Send`, and no two threads ever touch the same item (see `for_each_mut`).
unsafe impl<T: Send> Send for SendPtr<T> {}
unsafe impl<T: Send> Sync for SendPtr<T> {}

/// Threads started once and kept waiting for work: starting a thread per parallel section made
/// `VecEnv` steps 2–4× slower on two threads than on one whenever other processes held the cores (issue
/// 41), since each step then waited for a new thread to be scheduled and finish its fixed half.
///
/// Not rayon's pool: dfdx splits a matrix product over `rayon::current_num_threads()`, which inside a
/// rayon pool is that pool's size, so the DDPG updates run here would change their kernels' blocking.
/// These are plain threads, where that count stays the single-threaded global pool's
/// ([`single_threaded_kernels`]).
struct Pool {
    state: std::sync::Mutex<PoolState>,
    wake: std::sync::Condvar,
}

#[derive(Default)]
struct PoolState {
    /// Bumped for every job published, so a waiting thread knows there is news.
    generation: u64,
    job: Option<std::sync::Arc<Job>>,
    started: usize,
}

/// One call's items: `next` hands out indices, `finished` counts items done (the caller sleeps on
/// `all_done` until it reaches `len`).
struct Job {
    len: usize,
    next: AtomicUsize,
    /// Pool threads that may still join (so no more than [`threads`] threads work on one call).
    seats: AtomicUsize,
    finished: AtomicUsize,
    done_lock: std::sync::Mutex<()>,
    all_done: std::sync::Condvar,
    panic: std::sync::Mutex<Option<Box<dyn std::any::Any + Send>>>,
    /// The caller's closure, lifetime erased: only called for an index claimed below `len`, and the
    /// caller waits for every such call to return before its closure goes out of scope.
    run: *const (dyn Fn(usize) + Sync),
}
// SAFETY: `run` points to a `Sync` closure that outlives every call made through it (see `Job::run`).
unsafe impl Send for Job {}
unsafe impl Sync for Job {}

impl Job {
    /// Takes items until none is left; a panic is kept for the caller, and the item still counts as done.
    fn work(&self) {
        loop {
            let i = self.next.fetch_add(1, Ordering::Relaxed);
            if i >= self.len {
                return;
            }
            // SAFETY: i < len was claimed by this thread alone, and the caller waits for it (`Pool::run`).
            let run = unsafe { &*self.run };
            if let Err(p) = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| run(i))) {
                self.panic.lock().unwrap_or_else(|e| e.into_inner()).get_or_insert(p);
            }
            if self.finished.fetch_add(1, Ordering::AcqRel) + 1 == self.len {
                let _guard = self.done_lock.lock().unwrap_or_else(|e| e.into_inner());
                self.all_done.notify_all();
            }
        }
    }
}

impl Pool {
    fn global() -> &'static Pool {
        static POOL: std::sync::OnceLock<Pool> = std::sync::OnceLock::new();
        POOL.get_or_init(|| Pool { state: Default::default(), wake: std::sync::Condvar::new() })
    }

    /// Calls `run(i)` for every i in `0..len`, on this thread and up to `helpers` pool threads; returns
    /// when all calls have returned (re-raising the first panic among them).
    fn run(&'static self, len: usize, helpers: usize, run: &(dyn Fn(usize) + Sync)) {
        // SAFETY (lifetime erased): this function returns only once `finished == len`, after which no
        // thread calls `run` again (every index below `len` has been claimed and finished).
        let run: *const (dyn Fn(usize) + Sync + '_) = run;
        let run: *const (dyn Fn(usize) + Sync) = unsafe { std::mem::transmute(run) };
        let job = std::sync::Arc::new(Job {
            len,
            next: AtomicUsize::new(0),
            seats: AtomicUsize::new(helpers),
            finished: AtomicUsize::new(0),
            done_lock: Default::default(),
            all_done: Default::default(),
            panic: Default::default(),
            run,
        });
        {
            let mut state = self.state.lock().unwrap_or_else(|e| e.into_inner());
            // A thread the system refuses to start is done without: the caller takes every item itself.
            while state.started < helpers {
                let started = std::thread::Builder::new().name("coevo-worker".into()).spawn(move || self.serve());
                if started.is_err() {
                    break;
                }
                state.started += 1;
            }
            state.generation += 1;
            state.job = Some(job.clone());
        }
        self.wake.notify_all();
        job.work();
        let mut guard = job.done_lock.lock().unwrap_or_else(|e| e.into_inner());
        while job.finished.load(Ordering::Acquire) < len {
            guard = job.all_done.wait(guard).unwrap_or_else(|e| e.into_inner());
        }
        drop(guard);
        {
            let mut state = self.state.lock().unwrap_or_else(|e| e.into_inner());
            if state.job.as_ref().is_some_and(|j| std::sync::Arc::ptr_eq(j, &job)) {
                state.job = None;
            }
        }
        let panic = job.panic.lock().unwrap_or_else(|e| e.into_inner()).take();
        if let Some(p) = panic {
            std::panic::resume_unwind(p);
        }
    }

    /// A pool thread: waits for a job, helps with it if a seat is free, waits again.
    fn serve(&self) {
        let mut seen = 0;
        loop {
            let job = {
                let mut state = self.state.lock().unwrap_or_else(|e| e.into_inner());
                while state.generation == seen {
                    state = self.wake.wait(state).unwrap_or_else(|e| e.into_inner());
                }
                seen = state.generation;
                state.job.clone()
            };
            let Some(job) = job else { continue };
            if job.seats.fetch_update(Ordering::AcqRel, Ordering::Acquire, |s| s.checked_sub(1)).is_ok() {
                job.work();
            }
        }
    }
}

/// Runs `f(chunk_index, chunk)` over consecutive chunks of `chunk_len` items of `data`, in parallel when
/// there is more than one chunk. The chunking depends only on `chunk_len`, never on the thread count.
pub(crate) fn for_each_chunk<T: Send>(data: &mut [T], chunk_len: usize, f: impl Fn(usize, &mut [T]) + Sync) {
    let mut chunks: Vec<(usize, &mut [T])> = data.chunks_mut(chunk_len.max(1)).enumerate().collect();
    for_each_mut(&mut chunks, |(i, c)| f(*i, c));
}

/// Per-agent work over populations up to this size runs on the calling thread: starting threads costs
/// more than the contacts of a thousand agents (3 + 1 000 steps ran 10 % slower split in chunks of 512).
pub(crate) const ALONE_UP_TO: usize = 4096;

/// The length of the chunks per-agent work over `n` agents is split into: all of them up to
/// [`ALONE_UP_TO`], else one chunk per worker thread.
pub(crate) fn chunk_len(n: usize) -> usize {
    if n > ALONE_UP_TO {
        n.div_ceil(threads())
    } else {
        n.max(1)
    }
}

/// Contiguous ranges of [`chunk_len`] covering `0..n`.
pub(crate) fn ranges(n: usize) -> impl Iterator<Item = std::ops::Range<usize>> {
    let len = chunk_len(n);
    (0..n).step_by(len).map(move |start| start..(start + len).min(n))
}

/// `f` of each of [`ranges`]`(n)`, on all worker threads, the results in range order. For work where each
/// item is computed alone: callers that then sum the items do so in item order, so neither the split nor
/// the thread count changes a number.
pub(crate) fn map_ranges<T: Send>(n: usize, f: impl Fn(std::ops::Range<usize>) -> T + Sync) -> Vec<T> {
    if chunk_len(n) >= n {
        return vec![f(0..n)]; // one range: no bookkeeping (the small groups of every training step)
    }
    let mut work: Vec<(std::ops::Range<usize>, Option<T>)> = ranges(n).map(|r| (r, None)).collect();
    for_each_mut(&mut work, |(r, out)| *out = Some(f(r.clone())));
    work.into_iter().map(|(_, out)| out.expect("every range is computed")).collect()
}

/// Runs `step` repeatedly for about `budget` (at least `min_iters` times) and returns calls per second: the
/// one timing loop of `--bench` and of the kernels' peak measurement.
pub(crate) fn per_second(budget: std::time::Duration, min_iters: usize, mut step: impl FnMut()) -> f64 {
    let start = std::time::Instant::now();
    let mut iters = 0usize;
    while iters < min_iters || start.elapsed() < budget {
        step();
        iters += 1;
    }
    iters as f64 / start.elapsed().as_secs_f64()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_item_is_processed_once_and_in_order_whatever_the_thread_count() {
        let before = threads();
        for n in [1, 2, 3, 8] {
            set_threads(n);
            let mut items: Vec<u64> = (0..37).collect();
            for_each_mut(&mut items, |x| *x = *x * *x + 1);
            assert_eq!(items, (0..37).map(|x| x * x + 1).collect::<Vec<u64>>());
            let mut data = vec![0usize; 100];
            for_each_chunk(&mut data, 16, |i, c| c.iter_mut().for_each(|x| *x = i));
            assert_eq!(data, (0..100).map(|j| j / 16).collect::<Vec<_>>());
            // Ranges: every item once, in order; split only above ALONE_UP_TO. (In this test, as the thread
            // count is one global that tests running at once would race on.)
            for len in [0, 1, 17, ALONE_UP_TO, ALONE_UP_TO + 1, 3 * ALONE_UP_TO + 5] {
                let all: Vec<usize> = ranges(len).flatten().collect();
                assert_eq!(all, (0..len).collect::<Vec<_>>(), "{len} items, {n} threads");
                let split = if len > ALONE_UP_TO { n } else { len.min(1) };
                assert_eq!(ranges(len).count(), split, "{len} items, {n} threads");
                let mapped: Vec<usize> = map_ranges(len, |r| r.map(|i| i * 3).collect::<Vec<_>>()).concat();
                assert_eq!(mapped, (0..len).map(|i| i * 3).collect::<Vec<_>>());
            }
        }
        set_threads(before);
    }

    #[test]
    fn adaptive_threading_settles_on_the_faster_choice_and_keeps_checking_the_other() {
        // Calls that take 2 ms on one thread and 0.2 ms on four, then the other way round (the machine
        // got busy): the choice follows, and the slower one is still tried once in EXPLORE_EVERY calls.
        let pause = |ms: f64| std::thread::sleep(std::time::Duration::from_secs_f64(ms / 1000.0));
        let mut adaptive = Adaptive::default();
        // `calls` calls taking `one` ms on one thread and `all` ms on four: the worker count each used.
        let mut phase = |calls: usize, one: f64, all: f64| -> Vec<usize> {
            (0..calls)
                .map(|_| {
                    adaptive.run_among(4, |w| {
                        pause(if w == 1 { one } else { all });
                        w
                    })
                })
                .collect()
        };
        let used = phase(256, 2.0, 0.2);
        let on_all = used[64..].iter().filter(|&&w| w == 4).count();
        assert!(on_all >= 180, "all threads were faster, used {on_all} times of 192");
        assert!(used[64..].contains(&1), "one thread still tried");
        let used = phase(256, 0.2, 2.0);
        let on_one = used[128..].iter().filter(|&&w| w == 1).count();
        assert!(on_one >= 115, "one thread became faster, used {on_one} times of 128");
        // And back, after a long spell that left all threads' mean ten times one thread's: within a few
        // explorations, not hundreds of calls.
        let used = phase(192, 2.0, 0.2);
        let on_all = used[64..].iter().filter(|&&w| w == 4).count();
        assert!(on_all >= 115, "all threads faster again, used {on_all} times of 128");
        assert_eq!(Adaptive::default().run_among(1, |w| w), 1, "one thread when there is one");
    }

    #[test]
    fn the_pool_survives_a_panic_nesting_and_callers_on_many_threads() {
        // The pool itself, with two helpers whatever `threads()` is (a global other tests change).
        fn each<T: Send>(items: &mut [T], f: impl Fn(&mut T) + Sync) {
            on_pool(items, 2, f);
        }
        // A panic in one item reaches the caller, after every other item has finished.
        let mut items: Vec<usize> = (0..64).collect();
        let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            each(&mut items, |x| {
                if *x == 17 {
                    panic!("item 17");
                }
                *x += 100;
            })
        }));
        assert!(caught.is_err(), "the panic of item 17 reaches the caller");
        assert_eq!(items.iter().filter(|&&x| x >= 100).count(), 63, "every other item finished");
        // The pool still works, also nested (an item that is itself split) and from several callers at once.
        std::thread::scope(|scope| {
            for caller in 0..3u64 {
                scope.spawn(move || {
                    for round in 0..50u64 {
                        let mut outer: Vec<Vec<u64>> = (0..8).map(|i| vec![i; 10]).collect();
                        each(&mut outer, |inner| each(inner, |x| *x = *x * 3 + caller + round));
                        let expected: Vec<Vec<u64>> = (0..8).map(|i| vec![i * 3 + caller + round; 10]).collect();
                        assert_eq!(outer, expected);
                    }
                });
            }
        });
    }
}
