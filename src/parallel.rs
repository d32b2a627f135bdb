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
pub fn threads() -> usize {
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
pub fn single_threaded_kernels() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let _ = rayon::ThreadPoolBuilder::new().num_threads(1).build_global();
    });
}

/// Runs `f` on every item, up to [`threads`] at a time; each item is processed exactly as it would be
/// sequentially (the caller keeps the items independent: their own buffers, their own random streams).
pub fn for_each_mut<T: Send>(items: &mut [T], f: impl Fn(&mut T) + Sync) {
    let workers = threads().min(items.len());
    if workers <= 1 {
        items.iter_mut().for_each(f);
        return;
    }
    // Contiguous groups, one per worker; the calling thread takes the first.
    let per = items.len().div_ceil(workers);
    std::thread::scope(|scope| {
        let mut groups = items.chunks_mut(per);
        let first = groups.next();
        for group in groups {
            let f = &f;
            scope.spawn(move || group.iter_mut().for_each(f));
        }
        if let Some(group) = first {
            group.iter_mut().for_each(&f);
        }
    });
}

/// Runs `f(chunk_index, chunk)` over consecutive chunks of `chunk_len` items of `data`, in parallel when
/// there is more than one chunk. The chunking depends only on `chunk_len`, never on the thread count.
pub fn for_each_chunk<T: Send>(data: &mut [T], chunk_len: usize, f: impl Fn(usize, &mut [T]) + Sync) {
    let mut chunks: Vec<(usize, &mut [T])> = data.chunks_mut(chunk_len.max(1)).enumerate().collect();
    for_each_mut(&mut chunks, |(i, c)| f(*i, c));
}

/// Per-agent work over populations up to this size runs on the calling thread: starting threads costs
/// more than the contacts of a thousand agents (3 + 1 000 steps ran 10 % slower split in chunks of 512).
pub const ALONE_UP_TO: usize = 4096;

/// The length of the chunks per-agent work over `n` agents is split into: all of them up to
/// [`ALONE_UP_TO`], else one chunk per worker thread.
pub fn chunk_len(n: usize) -> usize {
    if n > ALONE_UP_TO {
        n.div_ceil(threads())
    } else {
        n.max(1)
    }
}

/// Contiguous ranges of [`chunk_len`] covering `0..n`.
pub fn ranges(n: usize) -> impl Iterator<Item = std::ops::Range<usize>> {
    let len = chunk_len(n);
    (0..n).step_by(len).map(move |start| start..(start + len).min(n))
}

/// `f` of each of [`ranges`]`(n)`, on all worker threads, the results in range order. For work where each
/// item is computed alone: callers that then sum the items do so in item order, so neither the split nor
/// the thread count changes a number.
pub fn map_ranges<T: Send>(n: usize, f: impl Fn(std::ops::Range<usize>) -> T + Sync) -> Vec<T> {
    if chunk_len(n) >= n {
        return vec![f(0..n)]; // one range: no bookkeeping (the small groups of every training step)
    }
    let mut work: Vec<(std::ops::Range<usize>, Option<T>)> = ranges(n).map(|r| (r, None)).collect();
    for_each_mut(&mut work, |(r, out)| *out = Some(f(r.clone())));
    work.into_iter().map(|(_, out)| out.expect("every range is computed")).collect()
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
}
