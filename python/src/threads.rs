//! The threads a vector environment steps its environments on: the calling thread and a pool
//! of the others. Each call splits the environments into one contiguous block per thread; the
//! calling thread steps the first block itself while the pool steps the others, so the caller
//! never sits idle waiting for a pool to wake up, and one thread means no pool at all. Written
//! over rayon's `in_place_scope`.

use crate::errors::runtime_error;
use pyo3::PyErr;
use pyo3::PyResult;
use std::sync::Mutex;

/// Most threads a vector environment may use.
pub(crate) const MAX_THREADS: usize = 1024;

/// The calling thread and `count − 1` pool threads.
pub(crate) struct Threads {
    count: usize,
    /// `None` with one thread: everything runs on the calling thread.
    pool: Option<rayon::ThreadPool>,
}

impl Threads {
    /// `count` threads in all; 0: `RAYON_NUM_THREADS` when set, else one per core.
    pub(crate) fn new(count: usize) -> PyResult<Threads> {
        let count = match count {
            0 => std::env::var("RAYON_NUM_THREADS")
                .ok()
                .and_then(|v| v.parse::<usize>().ok())
                .filter(|&n| n > 0)
                .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get())),
            n => n,
        }
        .min(MAX_THREADS);
        let pool = if count > 1 {
            Some(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(count - 1)
                    .thread_name(|i| format!("dupac-vecenv-{}", i + 1))
                    .build()
                    .map_err(runtime_error)?,
            )
        } else {
            None
        };
        Ok(Threads { count, pool })
    }

    pub(crate) fn count(&self) -> usize {
        self.count
    }

    /// `f` on every item of `work`, in contiguous blocks, one per thread; the first error
    /// (in no particular order when several blocks fail) is returned once every block is done.
    pub(crate) fn for_each<W: Send>(
        &self,
        work: &mut [W],
        f: impl Fn(&mut W) -> PyResult<()> + Sync,
    ) -> PyResult<()> {
        let Some(pool) = self.pool.as_ref().filter(|_| work.len() > 1) else {
            return work.iter_mut().try_for_each(f);
        };
        let size = work.len().div_ceil(self.count);
        let first_error: Mutex<Option<PyErr>> = Mutex::new(None);
        let run = |block: &mut [W]| {
            if let Err(e) = block.iter_mut().try_for_each(&f)
                && let Ok(mut slot) = first_error.lock()
            {
                slot.get_or_insert(e);
            }
        };
        pool.in_place_scope(|s| {
            let mut blocks = work.chunks_mut(size);
            let mine = blocks.next();
            for block in blocks {
                let run = &run;
                s.spawn(move |_| run(block));
            }
            if let Some(block) = mine {
                run(block);
            }
        });
        match first_error.into_inner() {
            Ok(Some(e)) => Err(e),
            Ok(None) => Ok(()),
            Err(_) => Err(runtime_error("a stepping thread panicked")),
        }
    }
}
