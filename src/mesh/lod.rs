//! The four levels of detail, defined once for every output (meshes, GLB,
//! OBJ, PLY, CityJSON) and shared with the chain code's LOD reduction.
//!
//! Pruning follows chain-code-tree-compression-lod §3.2, Pseudocode 2: a
//! *lateral* branch whose base radius is below a threshold `T` is dropped
//! with everything that grows from it, while main extensions are never
//! shortened (the principal chain of internodes is one unit branch). The
//! base radius of a lateral branch is the radius of its first node, i.e. of
//! the internode that leaves the fork: every non-root node owns the internode
//! that ends at it, which is the pairing of internodes and radii the chain
//! code's radius list uses.
//!
//! | level | keeps | ring segments |
//! |---|---|---|
//! | [`Lod::L0`] | trunk and the first-order branches kept by [`Lod::L1`] | 3–6 |
//! | [`Lod::L1`] | laterals with base radius ≥ 30 % of the trunk radius | 3–8 |
//! | [`Lod::L2`] | laterals with base radius ≥ 10 % of the trunk radius | 4–10 |
//! | [`Lod::L3`] | every branch | 4–12 |
//!
//! Levels nest: every branch of a level is in all finer levels. LOD 0 takes
//! LOD 1's scaffold and keeps only its first-order branches; taking *every*
//! first-order branch instead would keep the many thin twigs along the trunk
//! and give LOD 0 more triangles than LOD 1.

use crate::encode::chaincode::{self, ChainCode, ChainError};
use crate::skeleton::{NodeId, Skeleton};

/// A level of detail, coarsest ([`Lod::L0`]) to full ([`Lod::L3`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Lod {
    /// The trunk and its first-order branches.
    L0,
    /// Scaffold limbs: laterals of base radius at least 30 % of the trunk's.
    L1,
    /// Laterals of base radius at least 10 % of the trunk's.
    L2,
    /// Every branch, full ring resolution.
    L3,
}

/// Sweep resolution of one level: how finely rings and curves are sampled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RingResolution {
    /// Target distance between neighbouring ring vertices, in metres.
    pub chord_m: f32,
    /// Fewest vertices around a ring (thin twigs).
    pub min_segments: u32,
    /// Most vertices around a ring (thick trunks).
    pub max_segments: u32,
    /// Largest turn, in radians, one swept step may make along a bending
    /// branch before the smoothed curve is subdivided.
    pub max_turn_rad: f32,
    /// Most extra rings inserted into one internode.
    pub max_subdivisions: u32,
}

/// Lateral branches thinner than this fraction of the trunk radius are
/// pruned at [`Lod::L1`]. By the pipe model (da Vinci's rule) a branch's
/// cross-section is proportional to the crown it carries, so 30 % of the
/// trunk radius keeps the limbs that carry at least ~9 % of the crown each:
/// the scaffold that shapes a tree's silhouette.
const L1_RELATIVE_RADIUS: f32 = 0.30;
/// As [`L1_RELATIVE_RADIUS`] for [`Lod::L2`]: branches carrying at least ~1 %
/// of the crown.
const L2_RELATIVE_RADIUS: f32 = 0.10;

impl Lod {
    /// All levels, coarsest first.
    pub const ALL: [Lod; 4] = [Lod::L0, Lod::L1, Lod::L2, Lod::L3];

    /// The level as a number 0–3.
    pub fn level(self) -> u8 {
        self as u8
    }

    /// The level for a number 0–3, `None` otherwise.
    pub fn from_level(level: u8) -> Option<Lod> {
        Lod::ALL.get(usize::from(level)).copied()
    }

    /// The level as CityJSON writes it in a geometry's `"lod"`: `"0"`–`"3"`.
    pub fn as_str(self) -> &'static str {
        ["0", "1", "2", "3"][self as usize]
    }

    /// The chain-code branch radius threshold `T` of this level (Pseudocode 2):
    /// laterals whose base radius is below it are pruned.
    ///
    /// Thresholds are relative to the trunk radius ([`trunk_radius_m`]), not
    /// absolute: a fixed 5 cm would strip a young street tree to its stem and
    /// leave an old oak almost untouched, whereas a relative threshold removes
    /// the same share of the crown from every tree, which is what a viewer
    /// switching levels expects. `None` for [`Lod::L0`], which selects by
    /// branch order instead; `Some(0.0)` for [`Lod::L3`], which prunes nothing.
    pub fn radius_threshold_m(&self, skeleton: &Skeleton) -> Option<f32> {
        let trunk = trunk_radius_m(skeleton);
        match self {
            Lod::L0 => None,
            Lod::L1 => Some(L1_RELATIVE_RADIUS * trunk),
            Lod::L2 => Some(L2_RELATIVE_RADIUS * trunk),
            Lod::L3 => Some(0.0),
        }
    }

    /// `code` cut down to this level on the code itself, without decoding
    /// it into a skeleton and encoding again (chain-code-tree-compression-lod
    /// §3.2, Pseudocode 2), with this level's threshold
    /// ([`Lod::radius_threshold_m`]) taken from the trunk radius the code
    /// decodes to. The cut code decodes to [`select`] of the decoded
    /// skeleton at this level (docs/lod.md). `None` for [`Lod::L0`], which
    /// selects by branch order and has no single threshold.
    ///
    /// ```
    /// use glam::{DVec3, Vec3};
    /// use silva::encode::chaincode::{self, ChainOptions};
    /// use silva::mesh::{Lod, select};
    /// use silva::{Anchor, NodeId, Skeleton};
    ///
    /// let mut tree = Skeleton::new(Anchor::at(DVec3::new(85_000.0, 446_000.0, 0.0)), 0.20);
    /// let fork = tree.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 2.0), 0.15);
    /// tree.add_child(fork, Vec3::new(0.0, 0.0, 5.0), 0.10);
    /// let limb = tree.add_child(fork, Vec3::new(1.5, 0.0, 3.5), 0.08);
    /// tree.add_child(limb, Vec3::new(2.5, 0.0, 4.5), 0.05);
    /// tree.add_child(fork, Vec3::new(-0.6, 0.0, 2.6), 0.01);
    /// let code = chaincode::encode(&tree, &ChainOptions::default()).unwrap();
    /// let scaffold = Lod::L1.reduce_chain_code(&code).unwrap().unwrap();
    /// let decoded = chaincode::decode(&code).unwrap();
    /// assert_eq!(chaincode::decode(&scaffold).unwrap().len(), select(&decoded, Lod::L1).len());
    /// assert_eq!(select(&decoded, Lod::L1).len(), 5); // the 1 cm twig is gone
    /// assert!(Lod::L0.reduce_chain_code(&code).unwrap().is_none());
    /// ```
    pub fn reduce_chain_code(self, code: &ChainCode) -> Result<Option<ChainCode>, ChainError> {
        let Some(threshold_m) = self.radius_threshold_m(&chaincode::decode(code)?) else {
            return Ok(None);
        };
        Ok(Some(chaincode::reduce_lod(code, threshold_m)))
    }

    /// Ring and curve sampling of this level; coarser levels are viewed from
    /// further away, so they need fewer vertices per ring and per bend.
    pub fn resolution(self) -> RingResolution {
        let (chord_m, min_segments, max_segments, max_turn_deg, max_subdivisions) = match self {
            Lod::L0 => (0.20, 3, 6, 45.0f32, 1),
            Lod::L1 => (0.12, 3, 8, 30.0, 2),
            Lod::L2 => (0.08, 4, 10, 20.0, 2),
            Lod::L3 => (0.05, 4, 12, 15.0, 3),
        };
        RingResolution {
            chord_m,
            min_segments,
            max_segments,
            max_turn_rad: max_turn_deg.to_radians(),
            max_subdivisions,
        }
    }
}

impl RingResolution {
    /// Vertices around a ring of radius `radius_m`: about one per
    /// [`RingResolution::chord_m`] of circumference, within the level's bounds.
    /// Ring resolution thus drops both with the level and with the radius.
    pub fn segments(&self, radius_m: f32) -> u32 {
        let by_chord = (std::f32::consts::TAU * radius_m / self.chord_m).ceil();
        // `as` saturates and maps NaN to 0; the clamp then bounds it.
        (by_chord as u32).clamp(self.min_segments, self.max_segments)
    }
}

impl std::fmt::Display for Lod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "LOD {}", self.level())
    }
}

/// The radius the LOD thresholds are relative to: the root's (trunk base)
/// radius, or the largest trunk radius if the root has none recorded.
pub fn trunk_radius_m(skeleton: &Skeleton) -> f32 {
    let root = skeleton.radius(NodeId::ROOT);
    if root > 0.0 {
        return root;
    }
    let orders = skeleton.branch_orders();
    skeleton
        .ids()
        .filter(|id| orders[id.index()] == 0)
        .map(|id| skeleton.radius(id))
        .fold(0.0, f32::max)
}

/// The skeleton of one level: [`Lod::L1`] and [`Lod::L2`] prune thin
/// laterals ([`prune_thin_branches`]), [`Lod::L0`] keeps the branch orders 0
/// and 1 of the [`Lod::L1`] skeleton,
/// [`Lod::L3`] keeps everything. The result is in canonical depth-first order.
pub fn select(skeleton: &Skeleton, lod: Lod) -> Skeleton {
    match lod.radius_threshold_m(skeleton) {
        None => {
            let scaffold = select(skeleton, Lod::L1);
            let keep: Vec<bool> = scaffold.branch_orders().iter().map(|&o| o <= 1).collect();
            scaffold.retain(&keep)
        }
        Some(threshold_m) => prune_thin_branches(skeleton, threshold_m),
    }
}

/// Pseudocode 2 on the skeleton: drops every lateral branch whose base
/// radius is below `threshold_m`, with all branches growing from it. Main
/// extensions are kept whatever their radius. A threshold of 0 keeps every
/// node.
pub fn prune_thin_branches(skeleton: &Skeleton, threshold_m: f32) -> Skeleton {
    let mut keep = vec![true; skeleton.len()];
    // Parents precede children, so one forward pass sees a parent's verdict
    // before its children's.
    for id in skeleton.ids() {
        for (k, &child) in skeleton.children(id).iter().enumerate() {
            let thin_lateral = k > 0 && skeleton.radius(child) < threshold_m;
            keep[child.index()] = keep[id.index()] && !thin_lateral;
        }
    }
    skeleton.retain(&keep)
}
