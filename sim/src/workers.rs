//! Work shared out to one worker per rayon thread: each worker sets up its own state once
//! (a sensor, an estimator: what is dear to build), then takes indices in turn until none
//! is left or one has failed. What an index gives must not depend on which worker took it.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

use crate::{Error, Result};

/// Runs `work(state, i)` for every i in `0..count`, each worker with its own state from
/// `setup`, and returns the results in index order. After an error no further index is
/// begun; the error returned is a failed setup's, else that of the first failed index.
pub(crate) fn each_index<S, T: Send>(
    count: usize,
    setup: impl Fn() -> Result<S> + Sync,
    work: impl Fn(&mut S, usize) -> Result<T> + Sync,
) -> Result<Vec<T>> {
    let done: Vec<Mutex<Option<Result<T>>>> = (0..count).map(|_| Mutex::new(None)).collect();
    let next = AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    let setup_error: Mutex<Option<Error>> = Mutex::new(None);
    let worker = || {
        let mut state = match setup() {
            Ok(state) => state,
            Err(e) => {
                failed.store(true, Ordering::Relaxed);
                setup_error.lock().expect("an error slot").get_or_insert(e);
                return;
            }
        };
        while !failed.load(Ordering::Relaxed) {
            let i = next.fetch_add(1, Ordering::Relaxed);
            if i >= count {
                break;
            }
            let result = work(&mut state, i);
            if result.is_err() {
                failed.store(true, Ordering::Relaxed);
            }
            *done[i].lock().expect("a result slot") = Some(result);
        }
    };
    let threads = rayon::current_num_threads().clamp(1, count.max(1));
    rayon::scope(|s| {
        for _ in 0..threads {
            s.spawn(|_| worker());
        }
    });
    if let Some(e) = setup_error.into_inner().expect("an error slot") {
        return Err(e);
    }
    // Indices are taken in order and every one taken is finished, so any index not done
    // lies after the first failed one.
    let mut results = Vec::with_capacity(count);
    for slot in done {
        match slot.into_inner().expect("a result slot") {
            Some(result) => results.push(result?),
            None => return Err(Error::Other("work stopped before every index was done".to_string())),
        }
    }
    Ok(results)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn results_come_in_index_order_on_any_pool() {
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let got = pool.install(|| {
                each_index(
                    50,
                    || Ok(0u64),
                    |calls, i| {
                        *calls += 1;
                        Ok(i * i)
                    },
                )
            });
            assert_eq!(got.unwrap(), (0..50).map(|i| i * i).collect::<Vec<_>>());
        }
    }

    #[test]
    fn the_first_failed_index_is_reported() {
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let got = pool.install(|| {
                each_index(
                    40,
                    || Ok(()),
                    |_, i| if i == 7 || i == 9 { Err(Error::Other(format!("index {i}"))) } else { Ok(i) },
                )
            });
            assert_eq!(got.unwrap_err().to_string(), Error::Other("index 7".into()).to_string());
            let setup = pool.install(|| each_index(5, || Err::<(), _>(Error::Other("setup".into())), |_, i| Ok(i)));
            assert_eq!(setup.unwrap_err().to_string(), Error::Other("setup".into()).to_string());
        }
    }
}
