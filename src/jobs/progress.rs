//! Progress of a running job and its time limit, shared between the worker
//! (async: heartbeat, deadline) and the processing step (a blocking thread).
//!
//! A blocking thread cannot be killed, so the limit is cooperative: the step
//! calls [`Progress::enter`] between its stages, and the reconstruction and
//! L-system stages also check the deadline between their own steps through
//! [`Progress::interrupt`] (the pipelines' steps, the writer's passes, each
//! Re-Pair round; see [`crate::interrupt`]). Either check fails with
//! [`JobError::TimedOut`] once the deadline has passed, and the worker stops
//! waiting for the step at the deadline itself (see `Worker::run_step`).
//! What is bounded: the job's record (failed at the deadline, with the
//! stage it had reached) and the worker (free for the next job at once).
//! What is not: the step running at the deadline goes on to its end on the
//! blocking thread, and its result is dropped. In reconstruction and
//! L-system encoding that is one step (one pass of the dense pipeline's
//! graph, skeletonisation or simplification, of the airborne pipeline's
//! Algorithm 2, one writing pass or Re-Pair round); reading the scan and
//! chain-code encoding are not interrupted and run to their end. Each step
//! is bounded by the input limits (`--max-points`,
//! [`crate::reconstruct::MAX_TREE_HEIGHT_M`] and
//! [`crate::reconstruct::MAX_TREE_WIDTH_M`]).

use std::sync::Arc;
use std::sync::atomic::{AtomicU8, AtomicU32, Ordering};
use std::time::{Duration, Instant};

use super::JobError;
use crate::interrupt::{Interrupt, Interrupted};

/// The stages of [`super::process`], in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Reading the stored LAZ.
    Reading,
    /// Reconstructing the skeleton, radii and metrics.
    Reconstructing,
    /// Encoding the skeleton as LsJSON.
    EncodingLsystem,
    /// Encoding the skeleton as chain code.
    EncodingChainCode,
    /// Assembling the stored forms.
    Finishing,
}

impl Stage {
    const ALL: [Stage; 5] = [
        Stage::Reading,
        Stage::Reconstructing,
        Stage::EncodingLsystem,
        Stage::EncodingChainCode,
        Stage::Finishing,
    ];

    /// What the stage does, in words.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Reading => "reading the scan",
            Stage::Reconstructing => "reconstruction",
            Stage::EncodingLsystem => "L-system encoding",
            Stage::EncodingChainCode => "chain-code encoding",
            Stage::Finishing => "storing the model",
        }
    }

    /// The job's progress (0–1) when the stage starts.
    fn fraction(self) -> f32 {
        match self {
            Stage::Reading => 0.0,
            Stage::Reconstructing => 0.1,
            Stage::EncodingLsystem => 0.8,
            Stage::EncodingChainCode => 0.9,
            Stage::Finishing => 0.95,
        }
    }
}

/// Progress of the running step and its deadline, shared with the
/// heartbeat (the fraction is an `f32` in bits).
#[derive(Debug, Clone)]
pub struct Progress {
    fraction: Arc<AtomicU32>,
    stage: Arc<AtomicU8>,
    deadline: Option<Instant>,
    limit: Duration,
}

impl Default for Progress {
    fn default() -> Self {
        Self::with_limit(None)
    }
}

impl Progress {
    /// Progress of a step that must end within `limit` from now (`None`,
    /// or a limit past what the clock can represent: no limit).
    pub fn with_limit(limit: Option<Duration>) -> Self {
        Self {
            fraction: Arc::default(),
            stage: Arc::default(),
            // `Instant + Duration` panics past the clock's range
            // (`--job-time-limit-secs 1e19` did, in every worker).
            deadline: limit.and_then(|l| Instant::now().checked_add(l)),
            limit: limit.unwrap_or(Duration::MAX),
        }
    }

    /// Starts `stage`, or fails with [`JobError::TimedOut`] when the
    /// deadline has passed.
    pub fn enter(&self, stage: Stage) -> Result<(), JobError> {
        if self.deadline.is_some_and(|d| Instant::now() >= d) {
            return Err(self.timed_out());
        }
        self.stage.store(stage as u8, Ordering::Relaxed);
        self.set(stage.fraction());
        Ok(())
    }

    /// When the step must have ended, if it must.
    pub fn deadline(&self) -> Option<Instant> {
        self.deadline
    }

    /// The deadline as an [`Interrupt`] for the algorithms a stage runs.
    pub fn interrupt(&self) -> Interrupt {
        Interrupt::at(self.deadline)
    }

    /// The error of a step stopped at its deadline, in its current stage.
    pub fn timed_out(&self) -> JobError {
        JobError::TimedOut {
            limit_s: self.limit.as_secs_f64(),
            stage: self.stage().name(),
            step: None,
        }
    }

    /// The error of a step that the current stage's own [`Interrupt`]
    /// stopped, naming the step within the stage.
    pub fn timed_out_at(&self, interrupted: Interrupted) -> JobError {
        JobError::TimedOut {
            limit_s: self.limit.as_secs_f64(),
            stage: self.stage().name(),
            step: Some(interrupted.step),
        }
    }

    /// The stage last entered.
    pub fn stage(&self) -> Stage {
        Stage::ALL[usize::from(self.stage.load(Ordering::Relaxed)).min(Stage::ALL.len() - 1)]
    }

    /// Records progress in `0..=1`.
    pub fn set(&self, fraction: f32) {
        self.fraction
            .store(fraction.clamp(0.0, 1.0).to_bits(), Ordering::Relaxed);
    }

    /// The last recorded progress.
    pub fn get(&self) -> f32 {
        f32::from_bits(self.fraction.load(Ordering::Relaxed))
    }
}

#[cfg(test)]
impl Progress {
    /// Moves the deadline to now, so that the next check fails whatever
    /// the machine's speed: for tests of checks inside a stage.
    pub(super) fn expire_now(&mut self) {
        self.deadline = Some(Instant::now());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stages_are_entered_in_time_and_refused_after_the_deadline() {
        let free = Progress::default();
        free.enter(Stage::EncodingLsystem).unwrap();
        assert_eq!((free.stage(), free.get()), (Stage::EncodingLsystem, 0.8));
        let late = Progress::with_limit(Some(Duration::ZERO));
        let err = late.enter(Stage::Reading).unwrap_err();
        assert!(
            matches!(err, JobError::TimedOut { limit_s, stage: "reading the scan", step: None } if limit_s == 0.0),
            "{err}"
        );
        assert!(err.to_string().contains("time limit of 0"), "{err}");
    }

    #[test]
    fn a_limit_past_the_clocks_range_is_no_deadline() {
        let far = Progress::with_limit(Some(Duration::MAX));
        assert_eq!(far.deadline(), None);
        far.enter(Stage::Reading).unwrap();
        let secs = Duration::from_secs_f64(1e19);
        assert_eq!(Progress::with_limit(Some(secs)).deadline(), None);
    }
}
