//! Synthetic trees with ground truth and simulated LiDAR scans (issue 2).
//!
//! Accuracy can only be measured against a known answer, and tests should
//! not need outside data. This module makes both: a procedural tree whose
//! true [`Skeleton`](crate::Skeleton) (with radii) is known exactly, and
//! point clouds that a terrestrial or airborne scanner would record of it.
//!
//! - [`generate`]: a Weber & Penn generator written as a stochastic
//!   parametric L-system (procedural-tree-generation paper, §2.3 and §3.2,
//!   Appendix C), with [`Species`] presets via [`TreeParams::preset`].
//! - [`simulate_tls`]: terrestrial scan: points on the bark surfaces with
//!   Gaussian noise and optional self-occlusion from a few scanner positions.
//! - [`simulate_als`]: airborne scan: near-nadir pulses at a chosen density
//!   over a square clip, mostly crown hits, few trunk hits and ground returns
//!   around the tree, unclassified by default, as an AHN3 clip.
//!
//! Everything is deterministic for a given seed, on every machine (see the
//! `random` module for how), and plain synchronous Rust without IO.
//!
//! ```
//! use glam::DVec3;
//! use silva::Anchor;
//! use silva::synth::{AlsOptions, Species, TreeParams, generate, simulate_als};
//!
//! let anchor = Anchor::at(DVec3::new(85_000.0, 446_000.0, 0.0));
//! let tree = generate(&TreeParams::preset(Species::Birch), 1, anchor);
//! let cloud = simulate_als(&tree, &AlsOptions::default(), 1);
//! assert_eq!(cloud.offset, tree.anchor().origin);
//! assert!(cloud.len() > 1000);
//! ```

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

mod als;
mod geometry;
mod presets;
mod random;
mod tls;
mod weber_penn;

pub use als::{AlsOptions, Foliage, Leaves, MAX_ALS_POINTS, simulate_als};
pub use tls::{MAX_TLS_POINTS, ScannerPlacement, TlsGround, TlsOptions, simulate_tls};
pub use weber_penn::{CrownShape, LevelParams, MAX_NODES, TreeParams, generate};

/// The scanner's seed for the tree of seed `seed` in scan draw `draw`
/// (`silva synth --scan-draw`, `silva eval --scan-draw`): the tree's own
/// seed for draw 0, so that one seed gives one tree and one scan
/// everywhere; for other draws the seed moved by `draw` times an odd 64-bit
/// constant (the golden ratio's), so that no small draw of one tree repeats
/// a draw of another nearby seed. The tree is always generated from `seed`
/// itself: another draw scans the same tree with other pulses.
///
/// ```
/// use silva::synth::scan_seed;
/// assert_eq!(scan_seed(7, 0), 7);
/// assert_ne!(scan_seed(7, 1), scan_seed(8, 0));
/// assert_ne!(scan_seed(7, 1), scan_seed(8, 1));
/// ```
pub fn scan_seed(seed: u64, draw: u64) -> u64 {
    seed.wrapping_add(draw.wrapping_mul(0x9E37_79B9_7F4A_7C15))
}

/// A tree species with a generator preset ([`TreeParams::preset`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Species {
    /// Pedunculate oak: broad hemispherical crown on a stout trunk.
    Oak,
    /// Silver birch: slender trunk, drooping twigs.
    Birch,
    /// Lombardy poplar: tall and columnar.
    Poplar,
    /// Scots pine: conical, whorled branches, strong leader.
    Pine,
}

impl Species {
    /// All species with a preset.
    pub const ALL: [Species; 4] = [Species::Oak, Species::Birch, Species::Poplar, Species::Pine];

    /// Sheds its leaves in winter (all but the pine).
    pub fn is_deciduous(self) -> bool {
        self != Species::Pine
    }

    /// Lower-case name, as accepted by [`FromStr`].
    pub fn name(self) -> &'static str {
        match self {
            Species::Oak => "oak",
            Species::Birch => "birch",
            Species::Poplar => "poplar",
            Species::Pine => "pine",
        }
    }
}

impl fmt::Display for Species {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A species name that has no preset.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown species {0:?}; expected one of oak, birch, poplar, pine")]
pub struct UnknownSpecies(pub String);

impl FromStr for Species {
    type Err = UnknownSpecies;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Species::ALL
            .into_iter()
            .find(|sp| sp.name().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| UnknownSpecies(s.to_owned()))
    }
}
