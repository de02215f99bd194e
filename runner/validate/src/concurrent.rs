//! Running the same probe work on several threads at once, for the threads probes of both FMI
//! versions.

/// Runs `work(0)` .. `work(n - 1)` each on its own thread, all at once, and gives their
/// results in order; a thread that panicked gives `panicked()` instead.
pub(crate) fn concurrently<T: Send, E: Send>(
    n: usize,
    work: impl Fn(usize) -> Result<T, E> + Sync,
    panicked: impl Fn() -> E,
) -> Vec<Result<T, E>> {
    let work = &work;
    std::thread::scope(|scope| {
        let handles: Vec<_> = (0..n).map(|i| scope.spawn(move || work(i))).collect();
        handles.into_iter().map(|h| h.join().unwrap_or_else(|_| Err(panicked()))).collect()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every index runs once, results come back in index order, and a panicking thread becomes
    /// the given error rather than a panic of the caller.
    #[test]
    fn results_come_in_order_and_a_panic_is_an_error() {
        let got = concurrently(4, |i| if i == 2 { panic!("thread {i}") } else { Ok::<usize, String>(i * 10) }, || "panicked".to_owned());
        assert_eq!(got, vec![Ok(0), Ok(10), Err("panicked".to_owned()), Ok(30)]);
    }
}
