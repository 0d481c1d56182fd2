//! Accuracy and speed evaluation behind `silva eval` (issue 3).
//!
//! Will hold skeleton-to-truth distances, branch recall and precision, and
//! point-to-surface fit for real clouds.

pub mod fit;
pub mod compare;
