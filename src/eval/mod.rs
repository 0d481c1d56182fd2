//! Accuracy and speed evaluation behind `silva eval` (issue 3, item 7).
//!
//! - [`compare`]: skeleton against a known truth (recall, precision,
//!   symmetric distances), for synthetic trees;
//! - [`fit`]: point-to-surface fit of the reconstructed cylinders, for real
//!   clouds without truth;
//! - [`mesh_fit`]: the same figures for the swept triangle mesh users
//!   download;
//! - [`run`]: one report row per tree (reconstruction timed as a median);
//! - [`report`]: the report's table rendering and timing helpers;
//! - [`targets`]: how many synthetic trees meet each of issue 3's per-tree
//!   accuracy targets.
//!
//! Plain computation; the CLI does the file IO.

pub mod compare;
pub mod fit;
pub mod mesh_fit;
pub mod report;
pub mod run;
pub mod targets;
