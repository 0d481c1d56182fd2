//! DBF6 chain code: the smallest storage form of a skeleton, with level of
//! detail taken directly from the code.
//!
//! Follows Strnad et al., *Efficient representation of geometric tree models
//! with level-of-detail using compressed 3D chain code*
//! (chain-code-tree-compression-lod): §3.1 and Pseudocode 1 for the encoding
//! ([`encode`], [`decode`]), §3.2 and Pseudocode 2 for LOD reduction
//! ([`reduce_lod`]), §3.3 for interpolative compression
//! ([`ChainCode::compress`]). The exact format, the grammar and the error
//! guarantees are written down in `docs/chaincode.md`.
//!
//! # In short
//! - **Implicit voxelisation.** Node positions, taken relative to the root,
//!   are snapped to the centres of cubic voxels of edge `d`: the containing
//!   voxel (Eq. 1: `v = rtz(p/d + sgn(p)/2)`, rounding half away from zero)
//!   or, by default, the voxels within `√3·d/2` that code the whole tree in
//!   the fewest bits ([`Voxelisation`]).
//!   With [`Resolution::PerInternode`]`(r)`, `d = l̄ / r` where `l̄` is the
//!   skeleton's mean internode length (Eq. 2 with the paper's fixed internode
//!   length replaced by the mean); [`Resolution::VoxelSize`] sets `d` directly.
//! - **Symbols** 0–5 are unit moves +x, +y, +z, −x, −y, −z; 6 is a fork, 7 a
//!   tip, 8 the end of an internode (Table 1).
//! - **Traversal.** Each branch is followed along its main extension (first
//!   child); laterals go to the back of a FIFO queue and are resumed after a
//!   tip, in queue order.
//! - **Differential prediction.** The first internode of a branch is coded in
//!   full; every following internode codes only its correction from the
//!   previous internode's voxel step, or from a damped share of it
//!   ([`Prediction`]; the encoder keeps whichever weight codes shortest).
//! - **Multi-way forks** become a run of fork symbols: the first ends the
//!   internode, each further one is a zero-length internode at the same node
//!   that enqueues one more lateral.
//! - **Compression** ([`ChainCode::compress`]): the paper's BWT, MTF,
//!   cumulative sums and binary interpolative coding, applied either to the
//!   whole symbol string (kind 1, the paper's form) or, shorter on irregular
//!   skeletons, to split streams: tips, forks and lateral counts, per-axis
//!   corrections of branch-first and continuation internodes, and radii in
//!   the shortest [`RadiusLayout`]: tip-first, predicted from the fork node,
//!   or from the thickest child (kind 3, `split.rs`; kind 2 of container
//!   version 1 is still read).
//! - **Error bound.** Every decoded node lies within `√3·d/2` of its original
//!   position, independently of its depth (no drift: the voxel coordinates are
//!   exact integers). Each radius is within `radius_step_m / 2`.
//!
//! ```
//! use glam::{DVec3, Vec3};
//! use silva::encode::chaincode::{self, ChainCode, ChainOptions, Limits, Resolution};
//! use silva::{Anchor, NodeId, Skeleton};
//!
//! // Nodes added main extension first, the order the decoder returns them in.
//! let mut tree = Skeleton::new(Anchor::at(DVec3::new(155_000.0, 463_000.0, 0.0)), 0.30);
//! let a = tree.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 1.0), 0.25);
//! tree.add_child(a, Vec3::new(0.1, 0.0, 2.0), 0.20);
//! tree.add_child(a, Vec3::new(0.8, 0.0, 1.6), 0.05);
//!
//! let opts = ChainOptions { resolution: Resolution::PerInternode(5.0), ..Default::default() };
//! let code = chaincode::encode(&tree, &opts).unwrap();
//! let bytes = code.compress();
//! let back = ChainCode::decompress(&bytes, &Limits::default()).unwrap();
//! let decoded = chaincode::decode(&back).unwrap();
//! assert_eq!(decoded.len(), tree.len());
//! let bound = code.error_bound_m() as f32 + 1e-6;
//! let half_step = code.header().radius_step_m / 2.0 + 1e-6;
//! for id in tree.ids() {
//!     assert!(decoded.position(id).distance(tree.position(id)) <= bound);
//!     assert!((decoded.radius(id) - tree.radius(id)).abs() <= half_step);
//! }
//!
//! // Level of detail: drop the lateral thinner than 10 cm.
//! let lod = chaincode::decode(&chaincode::reduce_lod(&code, 0.10)).unwrap();
//! assert_eq!(lod.len(), 3);
//! ```

mod bits;
mod bwt;
mod container;
mod dbf6;
mod interpolative;
mod lod;
mod mtf;
mod plan;
mod radii;
mod split;
mod stats;

use glam::Vec3;

use crate::skeleton::{Anchor, SkeletonError};

pub use bwt::{bwt_forward, bwt_inverse};
pub use container::{
    CompressedSizes, MAGIC, VERSION, decode_bytes, decode_compressed, is_chain_code,
};
pub use dbf6::{decode, encode, encode_order};
pub use interpolative::{bic_decode, bic_encode};
pub use lod::{lod_thresholds, prune_like_lod, reduce_lod};
pub use mtf::{mtf_forward, mtf_inverse};
pub use split::RadiusLayout;
pub use stats::{ChainStats, LOD_LEVELS, LodStats, stats, stats_with};

/// Move one voxel in +x.
pub const MOVE_POS_X: u8 = 0;
/// Move one voxel in +y.
pub const MOVE_POS_Y: u8 = 1;
/// Move one voxel in +z.
pub const MOVE_POS_Z: u8 = 2;
/// Move one voxel in −x.
pub const MOVE_NEG_X: u8 = 3;
/// Move one voxel in −y.
pub const MOVE_NEG_Y: u8 = 4;
/// Move one voxel in −z.
pub const MOVE_NEG_Z: u8 = 5;
/// Fork: ends an internode at a fork node (or, directly after another fork
/// symbol, a zero-length internode) and enqueues one lateral branch.
pub const FORK: u8 = 6;
/// Tip: ends an internode at a branch tip; decoding resumes at the next
/// queued lateral.
pub const TIP: u8 = 7;
/// End of an internode whose node has exactly one child.
pub const END: u8 = 8;
/// Number of distinct symbols (0–8).
pub const ALPHABET: usize = 9;

/// How the voxel size `d` is chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Resolution {
    /// The paper's resolution `r` (Eq. 2): `d = l̄ / r`, where `l̄` is the mean
    /// length of the skeleton's non-degenerate internodes; an axis-aligned
    /// internode of mean length spans `r` voxels.
    PerInternode(f32),
    /// A fixed voxel edge length in metres.
    VoxelSize(f64),
}

/// How the encoder picks each node's voxel. All three keep every decoded
/// node within `√3·d/2` of its original position, and the decoder needs
/// no word of which was used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Voxelisation {
    /// Eq. 1: the voxel containing the node, whose centre is the nearest;
    /// the smallest mean error.
    Nearest,
    /// Among all voxels whose centre lies within `√3·d/2` of the node, the
    /// one nearest the predicted voxel (fewest correction moves), ties going
    /// to the nearer centre. The paper's "optimizing chain code generation
    /// for increased compressibility while maintaining control over the
    /// reconstruction error": a shorter code, the same bound, a larger mean
    /// error.
    Predictive,
    /// The default. Among the same voxels as [`Voxelisation::Predictive`],
    /// the choice for the whole tree at once that codes the corrections in
    /// the fewest estimated bits (dynamic programming over the tree,
    /// `plan.rs`), kept where it compresses shorter than the greedy
    /// choice. 1.5–2.5 % smaller on reconstructed skeletons
    /// (`docs/chaincode.md` §9), for a few more milliseconds of encoding.
    /// Skeletons of more than 2^20 nodes keep the greedy choice.
    Optimised,
}

/// How a continuation internode's voxel step is predicted from the
/// previous internode's step on the same branch: that step times
/// `quarters / 4`, rounded half away from zero per axis. Four quarters is
/// the paper's differential prediction (§3.1), right for trees whose
/// internodes follow on smoothly. Fewer quarters damp it: consecutive
/// internodes of a reconstruction from a point cloud turn by 40–60°
/// (median) and differ in length by a factor of 1.5, so the previous step
/// is a poor guess of the next, and on airborne reconstructions no
/// prediction at all codes shortest (`tools/chaincode_predictors.py`,
/// `docs/chaincode.md` §9). A branch's first internode is never predicted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Prediction(u8);

impl Prediction {
    /// The paper's differential prediction: the previous step itself.
    pub const DIFFERENTIAL: Self = Self(4);
    /// No prediction: every internode codes its whole step.
    pub const NONE: Self = Self(0);
    /// Every weight, the paper's first.
    pub const ALL: [Self; 5] = [Self(4), Self(3), Self(2), Self(1), Self(0)];

    /// The prediction weighted `quarters / 4`, if `quarters` is at most 4.
    pub fn from_quarters(quarters: u8) -> Option<Self> {
        (quarters <= 4).then_some(Self(quarters))
    }

    /// The weight in quarters, 0–4.
    pub fn quarters(self) -> u8 {
        self.0
    }

    /// The predicted step after a step `previous`: each axis times
    /// `quarters / 4`, rounded half away from zero, in exact integer
    /// arithmetic (no larger than `previous`, so it cannot overflow).
    ///
    /// ```
    /// use silva::encode::chaincode::Prediction;
    ///
    /// let half = Prediction::from_quarters(2).unwrap();
    /// assert_eq!(half.step([3, -3, 4]), [2, -2, 2]);
    /// let three = Prediction::from_quarters(3).unwrap();
    /// assert_eq!(three.step([-5, 2, 1]), [-4, 2, 1]);
    /// assert_eq!(Prediction::DIFFERENTIAL.step([7, -1, 0]), [7, -1, 0]);
    /// assert_eq!(Prediction::NONE.step([7, -1, 0]), [0, 0, 0]);
    /// assert_eq!(Prediction::from_quarters(5), None);
    /// ```
    #[inline(always)]
    pub fn step(self, previous: [i32; 3]) -> [i32; 3] {
        if self == Self::DIFFERENTIAL {
            return previous;
        }
        previous.map(|c| {
            // |c|·w/4 rounded up from a half: below 2^31 for w ≤ 3.
            let scaled = ((u64::from(c.unsigned_abs()) * u64::from(self.0) + 2) >> 2) as i32;
            if c < 0 { -scaled } else { scaled }
        })
    }
}

impl Default for Prediction {
    /// The paper's differential prediction.
    fn default() -> Self {
        Self::DIFFERENTIAL
    }
}

/// Encoder settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChainOptions {
    /// Voxel size choice; the paper's default is `r = 5`.
    pub resolution: Resolution,
    /// Voxel choice per node.
    pub voxelisation: Voxelisation,
    /// Radius quantisation step in metres: radii are stored as
    /// `round(radius_m / radius_step_m)`, so each is within half a step.
    pub radius_step_m: f32,
    /// The step prediction, or `None` to encode with each of
    /// [`Prediction::ALL`] and keep the code whose corrections compress
    /// shortest (see [`encode`]), the paper's on a tie.
    pub prediction: Option<Prediction>,
}

impl Default for ChainOptions {
    /// `r = 5`, predictive voxels, 1 mm radius steps (radii within
    /// ±0.5 mm) and the prediction whose corrections compress shortest.
    fn default() -> Self {
        Self {
            resolution: Resolution::PerInternode(5.0),
            voxelisation: Voxelisation::Optimised,
            radius_step_m: 0.001,
            prediction: None,
        }
    }
}

/// Everything except the symbols and radii needed to decode a chain code.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainHeader {
    /// Voxel edge length `d` in metres.
    pub voxel_size_m: f64,
    /// The resolution `r` the voxel size came from; `None` when the voxel
    /// size was given directly.
    pub resolution: Option<f32>,
    /// Radius quantisation step in metres.
    pub radius_step_m: f32,
    /// Georeference of the decoded skeleton (origin in `f64`, CRS).
    pub anchor: Anchor,
    /// Root (trunk base) position relative to the anchor, stored exactly;
    /// voxel `(0,0,0)` is centred on it.
    pub root_position: Vec3,
    /// How continuation internodes' steps are predicted.
    pub prediction: Prediction,
}

/// A DBF6 chain-coded skeleton: header, symbol stream and quantised radii.
///
/// Always well formed: every way to obtain one ([`encode`], [`reduce_lod`],
/// [`ChainCode::new`], [`ChainCode::from_bytes`], [`ChainCode::decompress`])
/// checks the symbol grammar and the radius count.
///
/// `radii_q` holds one quantised radius per node, in decoding order: the
/// root first, then the end node of each internode as its terminating symbol
/// (6, 7 or 8) is read. Zero-length fork internodes (repeated 6) carry no
/// radius: theirs is the fork node's.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainCode {
    header: ChainHeader,
    symbols: Vec<u8>,
    radii_q: Vec<u32>,
}

impl ChainCode {
    /// Checks and assembles a code from its parts.
    pub fn new(
        header: ChainHeader,
        symbols: Vec<u8>,
        radii_q: Vec<u32>,
    ) -> Result<Self, ChainError> {
        header.validate()?;
        lod::scan(&symbols, radii_q.len())?;
        if radii_q.iter().any(|&q| !radii::in_range(q)) {
            return Err(ChainError::Malformed("radius out of range"));
        }
        Ok(Self {
            header,
            symbols,
            radii_q,
        })
    }

    /// Voxel size, radius step, georeference and root position.
    pub fn header(&self) -> &ChainHeader {
        &self.header
    }

    /// The symbols 0–8 (see the constants of this module).
    pub fn symbols(&self) -> &[u8] {
        &self.symbols
    }

    /// Radii in units of `header().radius_step_m`, one per node in decoding order.
    pub fn radii_q(&self) -> &[u32] {
        &self.radii_q
    }

    /// The guaranteed bound on the distance between a decoded node and its
    /// original position: `√3·d/2`.
    pub fn error_bound_m(&self) -> f64 {
        3f64.sqrt() * self.header.voxel_size_m / 2.0
    }

    /// Number of internodes the code decodes to (one per stored radius, less
    /// the root's).
    pub fn internode_count(&self) -> usize {
        self.radii_q.len() - 1
    }

    /// Radius in metres of a quantised value.
    pub fn radius_m(&self, q: u32) -> f32 {
        (f64::from(q) * f64::from(self.header.radius_step_m)) as f32
    }
}

impl ChainHeader {
    /// Checks that the voxel size, radius step and resolution (if any) are
    /// positive and finite and that the root and anchor are finite.
    pub fn validate(&self) -> Result<(), ChainError> {
        if !(self.voxel_size_m.is_finite() && self.voxel_size_m > 0.0) {
            return Err(ChainError::Malformed("voxel size is not positive"));
        }
        if self.resolution.is_some_and(|r| !(r.is_finite() && r > 0.0)) {
            return Err(ChainError::Malformed("resolution is not positive"));
        }
        let step = self.radius_step_m;
        if !(step.is_finite() && step > 0.0) {
            return Err(ChainError::Malformed("radius step is not positive"));
        }
        if !self.root_position.is_finite() || !self.anchor.origin.is_finite() {
            return Err(ChainError::Malformed("root or anchor is not finite"));
        }
        Ok(())
    }
}

/// Bounds for decoding untrusted input: every allocation the decoders make is
/// proportional to these or to the input length.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Most symbols a stream may declare.
    pub max_symbols: usize,
    /// Most nodes (radii) a stream may declare.
    pub max_nodes: usize,
    /// Longest CRS string, in bytes.
    pub max_crs_bytes: usize,
}

impl Default for Limits {
    /// 16 Mi symbols, 4 Mi nodes (two orders of magnitude above a large tree),
    /// 256-byte CRS.
    fn default() -> Self {
        Self {
            max_symbols: 1 << 24,
            max_nodes: 1 << 22,
            max_crs_bytes: 256,
        }
    }
}

/// Why a skeleton could not be encoded or a chain code not decoded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ChainError {
    /// The resolution, voxel size or radius step is not a positive finite number.
    #[error("invalid chain code option: {0}")]
    InvalidOptions(&'static str),
    /// The skeleton spans too many voxels at this voxel size.
    #[error("skeleton spans more than 2^28 voxels from its root at voxel size {voxel_size_m} m")]
    TooFine {
        /// The voxel size that was asked for.
        voxel_size_m: f64,
    },
    /// A radius does not fit the quantisation.
    #[error("radius {radius_m} m cannot be quantised in steps of {step_m} m")]
    RadiusOutOfRange {
        /// The offending radius.
        radius_m: f32,
        /// The quantisation step.
        step_m: f32,
    },
    /// More symbols than the limit allows.
    #[error("chain code has {found} symbols, more than the limit {limit}")]
    TooManySymbols {
        /// Declared or produced count.
        found: usize,
        /// The limit.
        limit: usize,
    },
    /// More nodes than the limit allows.
    #[error("chain code has {found} nodes, more than the limit {limit}")]
    TooManyNodes {
        /// Declared count.
        found: usize,
        /// The limit.
        limit: usize,
    },
    /// A symbol outside 0–8.
    #[error("symbol {symbol} at position {position} is not a chain code symbol (0-8)")]
    InvalidSymbol {
        /// Index in the symbol stream.
        position: usize,
        /// The value found.
        symbol: u8,
    },
    /// The symbols end inside a branch or with laterals still queued.
    #[error("chain code ends inside a branch ({queued} laterals still queued)")]
    Unterminated {
        /// Laterals not yet decoded.
        queued: usize,
    },
    /// Symbols follow the tip that ends the last branch.
    #[error("{count} symbols follow the end of the last branch")]
    TrailingSymbols {
        /// How many symbols are left over.
        count: usize,
    },
    /// The number of radii does not match the nodes the symbols describe.
    #[error("chain code describes {nodes} nodes but carries {radii} radii")]
    RadiiCount {
        /// Nodes described by the symbols.
        nodes: usize,
        /// Radii present.
        radii: usize,
    },
    /// Voxel coordinates leave the 32-bit range.
    #[error("voxel coordinates overflow at symbol {position}")]
    CoordinateOverflow {
        /// Index in the symbol stream.
        position: usize,
    },
    /// The bytes do not start with the chain code magic `SLVC`.
    #[error("not a silva chain code (missing magic bytes \"SLVC\")")]
    BadMagic,
    /// A container version this build does not read.
    #[error("unsupported chain code version {0}")]
    UnsupportedVersion(u8),
    /// The container is structurally wrong.
    #[error("malformed chain code: {0}")]
    Malformed(&'static str),
    /// The bytes end before the declared content.
    #[error("chain code is truncated")]
    Truncated,
    /// The decoded nodes do not form a valid skeleton.
    #[error(transparent)]
    Skeleton(#[from] SkeletonError),
}
