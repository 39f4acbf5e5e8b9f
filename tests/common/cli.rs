//! Running programs from tests: the `velour` binary Cargo built for this test run, and the
//! captured output of any command.

use std::ffi::OsStr;
use std::process::{Command, ExitStatus};

/// Path of the `velour` binary built for this test run.
pub const VELOUR: &str = env!("CARGO_BIN_EXE_velour");

/// A command running the `velour` binary, to which the caller adds arguments.
pub fn velour() -> Command {
    Command::new(VELOUR)
}

/// Runs `velour` with `args` and captures its output.
pub fn run_velour<I, S>(args: I) -> Captured
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    velour().args(args).capture()
}

/// What a finished command printed, and how it exited.
#[derive(Debug)]
pub struct Captured {
    /// The command line, for messages.
    pub command: String,
    /// The exit status.
    pub status: ExitStatus,
    /// Standard output (invalid UTF-8 replaced).
    pub stdout: String,
    /// Standard error (invalid UTF-8 replaced).
    pub stderr: String,
}

impl Captured {
    /// Whether the command exited with status 0.
    pub fn success(&self) -> bool {
        self.status.success()
    }

    /// Asserts that the command succeeded, showing its standard error when it did not.
    pub fn assert_success(&self) -> &Self {
        assert!(
            self.success(),
            "{} failed ({}); stderr: {}",
            self.command,
            self.status,
            self.stderr
        );
        self
    }

    /// Asserts that the command failed without panicking and that its standard error
    /// contains every one of `needles`.
    pub fn assert_failure_mentioning(&self, needles: &[&str]) -> &Self {
        assert!(
            !self.success(),
            "{} should have failed; stdout: {}",
            self.command,
            self.stdout
        );
        for n in needles {
            assert!(
                self.stderr.contains(n),
                "{}: `{n}` not in stderr: {}",
                self.command,
                self.stderr
            );
        }
        assert!(
            !self.stderr.contains("panicked"),
            "{}: a panic, not an error: {}",
            self.command,
            self.stderr
        );
        self
    }
}

/// Runs a [`Command`] to completion and captures its output.
pub trait Capture {
    /// Runs the command, panicking (with the command line) when it cannot be started.
    fn capture(&mut self) -> Captured;
}

impl Capture for Command {
    fn capture(&mut self) -> Captured {
        let out = self
            .output()
            .unwrap_or_else(|e| panic!("cannot run {self:?}: {e}"));
        Captured {
            command: format!("{self:?}"),
            status: out.status,
            stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
            stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
        }
    }
}
