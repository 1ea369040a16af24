//! Items run on a few threads, each thread with state of its own (a planner link, say), and
//! the results kept in the items' order.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

use crate::error::{Result, SimClientError};

/// Runs `run` on every item on `threads` threads (at least one, at most one per item); each
/// thread makes its state with `new_worker` and takes the next item when it is free.
/// `on_done` is called after each item. The first error stops the others from taking new
/// items and is returned (the first in item order when several fail).
pub fn run_ordered<I, W, R>(
    items: &[I],
    threads: usize,
    new_worker: impl Fn() -> W + Sync,
    run: impl Fn(&mut W, &I) -> Result<R> + Sync,
    on_done: &(dyn Fn() + Sync),
) -> Result<Vec<R>>
where
    I: Sync,
    R: Send,
{
    let next = AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    let slots: Mutex<Vec<Option<Result<R>>>> = Mutex::new((0..items.len()).map(|_| None).collect());
    std::thread::scope(|scope| {
        for _ in 0..threads.clamp(1, items.len().max(1)) {
            scope.spawn(|| {
                let mut worker = new_worker();
                while !failed.load(Ordering::Relaxed) {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(item) = items.get(i) else { break };
                    let outcome = run(&mut worker, item);
                    if outcome.is_err() {
                        failed.store(true, Ordering::Relaxed);
                    }
                    slots.lock().expect("no worker panics while holding the lock")[i] = Some(outcome);
                    on_done();
                }
            });
        }
    });
    let slots = slots.into_inner().expect("the workers are done");
    let mut out = Vec::with_capacity(slots.len());
    for slot in slots {
        match slot {
            Some(Ok(r)) => out.push(r),
            Some(Err(e)) => return Err(e),
            None => {} // skipped after another item failed; that error is returned above
        }
    }
    if out.len() == items.len() {
        Ok(out)
    } else {
        Err(SimClientError::Config("a run was aborted".into()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn results_keep_the_items_order_and_each_thread_keeps_its_state() {
        let items: Vec<u32> = (0..50).collect();
        let out = run_ordered(
            &items,
            3,
            || 0u32,
            |seen, &i| {
                *seen += 1;
                Ok((i * 2, *seen))
            },
            &|| {},
        )
        .unwrap();
        assert_eq!(
            out.iter().map(|r| r.0).collect::<Vec<_>>(),
            (0..50).map(|i| i * 2).collect::<Vec<_>>()
        );
        // Each thread counted its own items from 1: one first item per thread that ran.
        let firsts = out.iter().filter(|r| r.1 == 1).count();
        assert!((1..=3).contains(&firsts), "{firsts} threads");
    }

    #[test]
    fn the_first_error_in_item_order_is_returned() {
        let items: Vec<u32> = (0..20).collect();
        let r = run_ordered(
            &items,
            2,
            || (),
            |_, &i| {
                if i == 5 {
                    Err(SimClientError::Config(format!("item {i}")))
                } else {
                    Ok(i)
                }
            },
            &|| {},
        );
        match r {
            Err(SimClientError::Config(m)) => assert!(m == "item 5" || m == "a run was aborted", "{m}"),
            other => panic!("expected an error, got {other:?}"),
        }
    }
}
