//! One named worker thread (local mapping, loop closing, the global BA):
//! started with a name, joined with the panic's message kept, and every
//! failure reported as [`SlamError::Thread`] naming that thread.

use std::thread::JoinHandle;

use crate::error::SlamError;

/// A named thread whose body returns `T`.
#[derive(Debug)]
pub(crate) struct Worker<T> {
    name: &'static str,
    handle: Option<JoinHandle<T>>,
}

impl<T: Send + 'static> Worker<T> {
    /// Starts `body` on a thread called `name`; a failed spawn is
    /// [`SlamError::Thread`].
    pub(crate) fn spawn(
        name: &'static str,
        body: impl FnOnce() -> T + Send + 'static,
    ) -> Result<Self, SlamError> {
        let handle = std::thread::Builder::new()
            .name(name.into())
            .spawn(body)
            .map_err(|e| SlamError::Thread {
                name,
                reason: format!("cannot start it: {e}"),
            })?;
        Ok(Self {
            name,
            handle: Some(handle),
        })
    }

    /// This thread's error with `reason`.
    pub(crate) fn error(&self, reason: impl Into<String>) -> SlamError {
        SlamError::Thread {
            name: self.name,
            reason: reason.into(),
        }
    }

    /// Whether the body has returned (or panicked); `true` once joined.
    pub(crate) fn is_finished(&self) -> bool {
        self.handle.as_ref().is_none_or(JoinHandle::is_finished)
    }

    /// Waits for the body and returns its value; a panic is
    /// [`SlamError::Thread`] with the panic's message.
    pub(crate) fn join(&mut self) -> Result<T, SlamError> {
        let handle = self
            .handle
            .take()
            .ok_or_else(|| self.error("it was already stopped"))?;
        handle
            .join()
            .map_err(|payload| SlamError::thread_panicked(self.name, payload.as_ref()))
    }
}

#[cfg(test)]
mod tests {
    use super::Worker;
    use crate::error::SlamError;

    #[test]
    fn a_panic_is_an_error_with_the_threads_name_and_the_message() {
        let mut worker = Worker::<()>::spawn("test-worker", || panic!("planted panic {}", 7))
            .unwrap_or_else(|e| panic!("{e}"));
        let error = worker.join().err();
        assert!(
            matches!(&error, Some(SlamError::Thread { name: "test-worker", reason }) if reason.contains("planted panic 7")),
            "{error:?}"
        );
        assert!(worker.is_finished());
        // Joined once: a second join says so instead of hanging.
        assert!(
            matches!(worker.join(), Err(SlamError::Thread { reason, .. }) if reason.contains("already stopped"))
        );
    }

    #[test]
    fn a_returning_body_gives_its_value() {
        let mut worker = Worker::spawn("test-worker", || 42).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(worker.join().ok(), Some(42));
    }
}
