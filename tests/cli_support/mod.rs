//! The `silva` binary as the CLI tests run it.
//!
//! The CLI tests run the binary as a user's shell would and check what it
//! writes. This module is the one place that knows where Cargo put the binary,
//! what a failed run must show in the test's panic message, and what every
//! refusal promises a user: one line on stderr that starts with `silva: `,
//! nothing on stdout, and no panic.

#![allow(dead_code)] // each test binary uses a different subset

use std::process::{Command, Output};

/// A `silva` command with no arguments yet: the binary Cargo built for this
/// test run.
pub fn silva() -> Command {
    Command::new(env!("CARGO_BIN_EXE_silva"))
}

/// Running a `silva` command and checking how it ended.
pub trait Run {
    /// Runs the command, which must succeed; panics with its stderr if not.
    fn succeeds(&mut self) -> Output;

    /// Runs the command, which must be refused with one line; returns that
    /// line (stderr without its final newline).
    fn fails_with_one_line(&mut self) -> String;
}

impl Run for Command {
    fn succeeds(&mut self) -> Output {
        let out = self.output().expect("the silva binary runs");
        assert!(
            out.status.success(),
            "{self:?} failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        out
    }

    fn fails_with_one_line(&mut self) -> String {
        let out = self.output().expect("the silva binary runs");
        let stderr = String::from_utf8_lossy(&out.stderr).trim_end().to_owned();
        assert!(!out.status.success(), "{self:?} was accepted");
        assert!(!stderr.contains("panicked"), "{self:?}: {stderr}");
        assert!(stderr.starts_with("silva: "), "{self:?}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{self:?}: {stderr}");
        assert!(out.stdout.is_empty(), "{self:?} wrote to stdout");
        stderr
    }
}
