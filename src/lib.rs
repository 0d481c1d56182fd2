//! silva: tree skeletons from LiDAR point clouds, stored compactly and served.
//!
//! The crate follows the pipeline, one module per stage, data flowing one way:
//!
//! | stage | module | what it does |
//! |---|---|---|
//! | input | [`cloud`] | read XYZ, PLY, LAS, LAZ; clean points |
//! | test data | [`synth`] | procedural trees with known skeletons; simulated TLS/ALS scans |
//! | skeleton | [`reconstruct`] | dense (AdTree) and airborne (Hu et al.) reconstruction, radii, metrics |
//! | storage forms | [`encode`] | L-system (LsJSON) and DBF6 chain code |
//! | outputs | [`mesh`], [`cityjson`], [`grow`] | meshes and LOD, CityJSON 2.0, growth |
//! | service | [`store`], [`jobs`], [`api`] | persistence, job queue, REST API |
//!
//! Every stage shares one domain type, [`Skeleton`]. The algorithm modules are
//! plain synchronous Rust without IO; only readers, `store`, `jobs`, `api` and
//! the CLI touch files, sockets or the database.
//!
//! # A skeleton, georeferenced
//! ```
//! use glam::{DVec3, Vec3};
//! use silva::{Anchor, NodeId, Skeleton};
//!
//! let mut tree = Skeleton::new(Anchor::at(DVec3::new(85_000.0, 446_000.0, 0.0)), 0.25);
//! tree.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 3.0), 0.2);
//! assert_eq!(tree.internode_count(), 1);
//! let json = tree.to_json();
//! assert_eq!(Skeleton::from_json(&json).unwrap(), tree);
//! ```
#![deny(missing_docs, unsafe_code, unreachable_pub)]

pub mod api;
pub mod cityjson;
pub mod cloud;
pub mod encode;
pub mod error;
pub mod eval;
pub mod grow;
pub mod interrupt;
pub mod jobs;
pub mod mesh;
pub mod reconstruct;
pub mod skeleton;
pub mod spatial;
pub mod store;
pub mod synth;

pub use cloud::PointCloud;
pub use error::{Error, Result};
pub use skeleton::{Anchor, Node, NodeId, Skeleton};
