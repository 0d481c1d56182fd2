//! Cooperative interruption of long computations, without IO.
//!
//! A blocking thread cannot be killed, so a caller with a time limit (a
//! service job) hands the algorithm an [`Interrupt`], and the algorithm
//! calls [`Interrupt::check`] at its step boundaries: between the steps of a
//! reconstruction pipeline, between the rounds of the L-system's Re-Pair.
//! A check reads the clock and nothing else. The default never interrupts,
//! and an algorithm that is not interrupted computes exactly what it did
//! without the checks.

use std::time::Instant;

/// When a computation should stop: a deadline, or never.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Interrupt {
    deadline: Option<Instant>,
}

/// A computation stopped by its [`Interrupt`], before `step`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("interrupted at its deadline before {step}")]
pub struct Interrupted {
    /// The step that was about to start, in words.
    pub step: &'static str,
}

impl Interrupt {
    /// Never interrupts.
    pub fn never() -> Self {
        Self::default()
    }

    /// Interrupts at `deadline`, or never when `None`.
    pub fn at(deadline: Option<Instant>) -> Self {
        Self { deadline }
    }

    /// Fails with [`Interrupted`] when the deadline has passed; `step` names
    /// what would start next, for the error.
    pub fn check(&self, step: &'static str) -> Result<(), Interrupted> {
        match self.deadline {
            Some(deadline) if Instant::now() >= deadline => Err(Interrupted { step }),
            _ => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_passed_deadline_interrupts_and_none_never_does() {
        assert_eq!(Interrupt::never().check("anything"), Ok(()));
        let passed = Interrupt::at(Some(Instant::now()));
        assert_eq!(
            passed.check("the graph"),
            Err(Interrupted { step: "the graph" })
        );
        let later = Interrupt::at(Some(Instant::now() + std::time::Duration::from_secs(3600)));
        assert_eq!(later.check("the graph"), Ok(()));
    }
}
