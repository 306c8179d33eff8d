//! Runs a job on every chunk, the chunks spread over scoped threads.

/// Calls `job` on each chunk: the first on this thread, the others on
/// scoped threads (one per chunk). With one chunk no thread is started.
pub(super) fn for_each_chunk<C: Send>(chunks: &mut [C], job: impl Fn(&mut C) + Sync) {
    match chunks {
        [] => {}
        [only] => job(only),
        [first, rest @ ..] => std::thread::scope(|scope| {
            let job = &job;
            for chunk in rest.iter_mut() {
                scope.spawn(move || job(chunk));
            }
            job(first);
        }),
    }
}
