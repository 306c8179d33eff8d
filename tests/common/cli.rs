//! Running the `spslam` binary from a test.

use std::process::{Command, Output};

/// A command for the `spslam` binary Cargo built for the tests.
pub fn spslam() -> Command {
    Command::new(env!("CARGO_BIN_EXE_spslam"))
}

/// A finished command's stdout and stderr, for an assertion's message.
pub fn logs(output: &Output) -> String {
    format!(
        "stdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    )
}
