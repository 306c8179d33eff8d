//! Ctrl-C (SIGINT) and SIGTERM during `spslam run`: the first one asks the
//! frame loop to stop after the frame in progress, so that the outputs of
//! every frame processed so far are written; a second one ends the process
//! at once (exit code 128 + the signal's number), without writing.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;

use anyhow::{Context, Result};
use signal_hook::consts::{SIGINT, SIGTERM};
use signal_hook::flag;

/// Set by SIGINT or SIGTERM; the frame loop polls it between frames.
pub struct StopRequest {
    /// The last stopping signal's number, 0 while none came.
    signal: Arc<AtomicUsize>,
}

impl StopRequest {
    /// Replaces the default action of SIGINT and SIGTERM (ending the
    /// process) by setting this flag; a second signal still ends it.
    pub fn install() -> Result<Self> {
        let signal = Arc::new(AtomicUsize::new(0));
        let armed = Arc::new(AtomicBool::new(false));
        for sig in [SIGINT, SIGTERM] {
            // The order matters: the shutdown checks `armed` before the
            // next action sets it, so only a second signal ends the process.
            flag::register_conditional_shutdown(sig, 128 + sig, Arc::clone(&armed))
                .and_then(|_| flag::register(sig, Arc::clone(&armed)))
                .and_then(|_| flag::register_usize(sig, Arc::clone(&signal), sig as usize))
                .with_context(|| format!("cannot install the handler of signal {sig}"))?;
        }
        Ok(Self { signal })
    }

    /// The signal that asked to stop, if one did.
    pub fn requested(&self) -> Option<&'static str> {
        match self.signal.load(Ordering::SeqCst) {
            0 => None,
            s if s == SIGINT as usize => Some("SIGINT"),
            s if s == SIGTERM as usize => Some("SIGTERM"),
            _ => Some("a signal"),
        }
    }
}
