//! A two-thread hand-off for iterations whose steps split into two independent halves: the
//! loop posts one half, a helper running beside it on the rayon pool claims and computes it,
//! and the loop collects the result (computing it itself when no helper has claimed it).
//!
//! Used by the doubling of the DARE (`sda.rs`). The helper spins between steps, yielding its core every
//! [`SPINS_PER_YIELD`] spins: a step of a 60-state problem takes tens of microseconds, the order
//! of what waking a sleeping pool thread costs, so a `rayon::join` per step would lose more than
//! it gains. Inside a busy pool (the two Riccati equations of loopshaping solved in parallel)
//! nobody claims the posted halves and the loop computes them itself. Which thread computes a
//! half does not change its arithmetic, so results are bit-identical either way.
//!
//! Run the loop as the *first* closure of `rayon::join` and [`Board::help`] as the second,
//! calling [`Board::close`] when the loop ends: when both closures end up on one thread, the
//! loop then runs first and the helper returns at once.

use crate::error::{HinfError, Result};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

/// Spins between two yields of a waiting thread.
const SPINS_PER_YIELD: usize = 256;

/// What the loop and the helper share: the posted half `J`, its result `R`, and counters.
pub(crate) struct Board<J, R> {
    /// The posted half with its step number (the helper reports that number as done, not the
    /// counter it saw: the loop may have computed that step itself and posted the next one
    /// before the helper took the job).
    posted: Mutex<Option<(usize, J)>>,
    result: Mutex<Option<R>>,
    /// Steps posted so far.
    seq: AtomicUsize,
    /// Steps whose posted half the helper has finished.
    done: AtomicUsize,
    finished: AtomicBool,
}

impl<J, R> Default for Board<J, R> {
    fn default() -> Self {
        Board {
            posted: Mutex::new(None),
            result: Mutex::new(None),
            seq: AtomicUsize::new(0),
            done: AtomicUsize::new(0),
            finished: AtomicBool::new(false),
        }
    }
}

impl<J, R> Board<J, R> {
    /// The helper: computes every posted half it claims with `work` until the loop closes.
    pub(crate) fn help(&self, work: impl Fn(J) -> R) {
        let mut seen = 0;
        let mut spins = 0;
        while !self.finished.load(Ordering::Acquire) {
            let p = self.seq.load(Ordering::Acquire);
            if p > seen {
                seen = p;
                let job = self.posted.lock().ok().and_then(|mut j| j.take());
                if let Some((k, job)) = job {
                    let r = work(job);
                    if let Ok(mut slot) = self.result.lock() {
                        *slot = Some(r);
                    }
                    self.done.store(k, Ordering::Release);
                }
                continue;
            }
            pause(&mut spins);
        }
    }

    /// Tells the helper the loop has ended.
    pub(crate) fn close(&self) {
        self.finished.store(true, Ordering::Release);
    }

    /// Posts step `k`'s half (steps numbered from 1).
    pub(crate) fn post(&self, job: J, k: usize) -> Result<()> {
        *self.posted.lock().map_err(|_| poisoned())? = Some((k, job));
        self.seq.store(k, Ordering::Release);
        Ok(())
    }

    /// Step `k`'s half: computed here with `work` when the helper has not claimed it, else the
    /// helper's result once it is there.
    pub(crate) fn collect(&self, k: usize, work: impl Fn(J) -> R) -> Result<R> {
        let unclaimed = self.posted.lock().map_err(|_| poisoned())?.take();
        if let Some((_, job)) = unclaimed {
            return Ok(work(job));
        }
        let mut spins = 0;
        while self.done.load(Ordering::Acquire) < k {
            pause(&mut spins);
        }
        self.result
            .lock()
            .map_err(|_| poisoned())?
            .take()
            .ok_or_else(|| HinfError::Numerical("a posted half-step went missing".into()))
    }
}

fn poisoned() -> HinfError {
    HinfError::Numerical("a helper thread failed".into())
}

/// One spin, and a yield of the core every [`SPINS_PER_YIELD`].
pub(crate) fn pause(spins: &mut usize) {
    *spins += 1;
    if *spins % SPINS_PER_YIELD == 0 {
        std::thread::yield_now();
    } else {
        std::hint::spin_loop();
    }
}
