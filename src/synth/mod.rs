//! Synthetic trees with ground truth and simulated LiDAR scans (issue 2).
//!
//! Will hold a procedural generator after Weber & Penn and stochastic
//! L-systems (procedural-tree-generation-lsystem-weber-penn), and terrestrial
//! and airborne scan simulators. Deterministic for a given seed.
