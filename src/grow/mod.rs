//! Growth: "grown by N years" variants of a skeleton.
//!
//! Will hold growth rules after multi-temporal-tree-growth §3 and the tip
//! growth of lsystem-from-adtree-skeletons §3.3. No IO.
