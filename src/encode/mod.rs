//! Compact skeleton encodings (issue 4).
//!
//! Will hold the L-system writer/reader (LsJSON, lsystem-from-adtree-skeletons
//! §3.2–3.3) and the DBF6 chain code with LOD reduction and interpolative
//! compression (chain-code-tree-compression-lod §3). No IO.

pub mod chaincode;
pub mod lsystem;
