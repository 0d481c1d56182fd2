//! The central domain type: a georeferenced tree skeleton with radii.
//!
//! Every stage speaks [`Skeleton`]: reconstruction produces it, the L-system
//! and chain-code encoders consume and return it, meshes, CityJSON and growth
//! are built from it, and the store persists its encodings. There is no other
//! skeleton representation in the crate.
//!
//! # Model
//! - A rooted tree of [`Node`]s. Node 0 is the root (the trunk base). Every
//!   other node has a parent with a *smaller* index, so a forward pass visits
//!   parents before children and a reverse pass visits children first.
//! - An edge parent→child is an *internode*. A node with two or more children
//!   is a *fork*; a node with none is a *tip*.
//! - Children are ordered: the first child continues the parent's axis (its
//!   *main extension*), the others are laterals. [`Skeleton::order_main_extension_first`]
//!   establishes that order from subtree length.
//! - Positions are `f32` metres *relative to* the [`Anchor`], which is kept in
//!   `f64`. National grids put x near 155,000 m (EPSG:28992), where an `f32`
//!   absolute coordinate would lose centimetres; relative to an anchor at the
//!   trunk base, a 100 m tree keeps sub-10 µm resolution.

use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};
use smallvec::SmallVec;

/// Index of a node in a [`Skeleton`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(transparent)]
pub struct NodeId(u32);

impl NodeId {
    /// The root node (trunk base) of every skeleton.
    pub const ROOT: NodeId = NodeId(0);

    /// The node's position in [`Skeleton::nodes`].
    pub fn index(self) -> usize {
        self.0 as usize
    }

    /// The id of the node stored at `index`.
    ///
    /// # Panics
    /// If `index` does not fit in 32 bits (skeletons are far smaller).
    pub fn from_index(index: usize) -> Self {
        NodeId(u32::try_from(index).expect("skeletons hold fewer than 2^32 nodes"))
    }
}

/// One skeleton node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Node {
    /// Position relative to the skeleton's anchor, in metres.
    pub position: Vec3,
    /// Branch radius at this node, in metres.
    pub radius_m: f32,
    /// The parent node; `None` only for the root.
    pub parent: Option<NodeId>,
}

/// Where a skeleton sits in the world.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Anchor {
    /// Origin of the relative coordinates, in CRS units (metres), full precision.
    pub origin: DVec3,
    /// Coordinate reference system, e.g. `"EPSG:28992"`; `None` when unknown.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crs: Option<String>,
}

impl Anchor {
    /// An anchor at `origin` with no known CRS.
    pub fn at(origin: DVec3) -> Self {
        Self { origin, crs: None }
    }
}

/// Why a set of nodes is not a valid skeleton.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SkeletonError {
    /// No nodes at all; a skeleton has at least its root.
    #[error("skeleton has no nodes")]
    Empty,
    /// The first node must be the root and only it may lack a parent.
    #[error("node {0}: only node 0 (the root) may lack a parent, and node 0 must")]
    Root(usize),
    /// Parents must precede children.
    #[error("node {node}: parent {parent} does not precede it")]
    ParentOrder {
        /// The offending node.
        node: usize,
        /// Its declared parent.
        parent: usize,
    },
    /// Coordinates and radii must be finite; radii non-negative.
    #[error("node {0}: position or radius is not finite, or radius is negative")]
    NotFinite(usize),
    /// The anchor origin is not finite.
    #[error("anchor origin is not finite")]
    AnchorNotFinite,
    /// Too many nodes for the 32-bit node index.
    #[error("skeleton has {0} nodes, more than the supported 2^32-1")]
    TooLarge(usize),
}

/// A node's children, inline up to two (a chain node or a fork).
type Children = SmallVec<[NodeId; 2]>;

/// A rooted, georeferenced tree skeleton with radii. See the module docs.
///
/// ```
/// use glam::{DVec3, Vec3};
/// use silva::skeleton::{Anchor, NodeId, Skeleton};
///
/// let mut tree = Skeleton::new(Anchor::at(DVec3::new(155_000.0, 463_000.0, 0.0)), 0.3);
/// let top = tree.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 4.0), 0.2);
/// let lateral = tree.add_child(top, Vec3::new(1.0, 0.0, 5.0), 0.05);
/// let leader = tree.add_child(top, Vec3::new(0.0, 0.0, 8.0), 0.15);
/// tree.order_main_extension_first();
/// assert_eq!(tree.children(top), &[leader, lateral]);
/// assert_eq!(tree.branch_orders(), vec![0, 0, 1, 0]);
/// assert!((tree.absolute_position(leader).x - 155_000.0).abs() < 1e-9);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Skeleton {
    anchor: Anchor,
    nodes: Vec<Node>,
    /// Derived from `nodes[..].parent`; kept in main-extension-first order.
    children: Vec<Children>,
}

impl Skeleton {
    /// A skeleton with only its root, at the anchor's origin.
    pub fn new(anchor: Anchor, root_radius_m: f32) -> Self {
        Self {
            anchor,
            nodes: vec![Node {
                position: Vec3::ZERO,
                radius_m: root_radius_m,
                parent: None,
            }],
            children: vec![Children::new()],
        }
    }

    /// Builds a skeleton from nodes in parent-before-child order.
    ///
    /// Children keep the order in which they appear in `nodes`.
    pub fn from_nodes(anchor: Anchor, nodes: Vec<Node>) -> Result<Self, SkeletonError> {
        if nodes.is_empty() {
            return Err(SkeletonError::Empty);
        }
        if !anchor.origin.is_finite() {
            return Err(SkeletonError::AnchorNotFinite);
        }
        if nodes.len() > u32::MAX as usize {
            return Err(SkeletonError::TooLarge(nodes.len()));
        }
        let mut children = vec![Children::new(); nodes.len()];
        for (i, node) in nodes.iter().enumerate() {
            let finite = node.position.is_finite() && node.radius_m.is_finite();
            if !finite || node.radius_m < 0.0 {
                return Err(SkeletonError::NotFinite(i));
            }
            match (i, node.parent) {
                (0, None) => {}
                (0, Some(_)) | (_, None) => return Err(SkeletonError::Root(i)),
                (_, Some(p)) if p.index() >= i => {
                    return Err(SkeletonError::ParentOrder {
                        node: i,
                        parent: p.index(),
                    });
                }
                (_, Some(p)) => children[p.index()].push(NodeId::from_index(i)),
            }
        }
        Ok(Self {
            anchor,
            nodes,
            children,
        })
    }

    /// Appends a node as the last child of `parent` and returns its id.
    ///
    /// # Panics
    /// If `parent` is not a node of this skeleton.
    pub fn add_child(&mut self, parent: NodeId, position: Vec3, radius_m: f32) -> NodeId {
        assert!(
            parent.index() < self.nodes.len(),
            "unknown parent {parent:?}"
        );
        let id = NodeId::from_index(self.nodes.len());
        self.nodes.push(Node {
            position,
            radius_m,
            parent: Some(parent),
        });
        self.children.push(Children::new());
        self.children[parent.index()].push(id);
        id
    }

    /// The georeference.
    pub fn anchor(&self) -> &Anchor {
        &self.anchor
    }

    /// Replaces the georeference without moving the geometry relative to it.
    pub fn set_anchor(&mut self, anchor: Anchor) {
        self.anchor = anchor;
    }

    /// All nodes, parents before children.
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }

    /// Number of nodes (at least 1).
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// Always false: a skeleton has at least its root. Present for API symmetry.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Number of internodes (edges), `len() - 1`.
    pub fn internode_count(&self) -> usize {
        self.nodes.len() - 1
    }

    /// Node ids in storage order (parents first).
    pub fn ids(&self) -> impl DoubleEndedIterator<Item = NodeId> + ExactSizeIterator + use<> {
        (0..self.nodes.len() as u32).map(NodeId)
    }

    /// One node.
    pub fn node(&self, id: NodeId) -> &Node {
        &self.nodes[id.index()]
    }

    /// Position relative to the anchor, in metres.
    pub fn position(&self, id: NodeId) -> Vec3 {
        self.nodes[id.index()].position
    }

    /// Absolute position in the anchor's CRS, in full `f64` precision.
    pub fn absolute_position(&self, id: NodeId) -> DVec3 {
        self.anchor.origin + self.position(id).as_dvec3()
    }

    /// Radius at a node, in metres.
    pub fn radius(&self, id: NodeId) -> f32 {
        self.nodes[id.index()].radius_m
    }

    /// Moves a node (relative coordinates).
    pub fn set_position(&mut self, id: NodeId, position: Vec3) {
        self.nodes[id.index()].position = position;
    }

    /// Sets a node's radius in metres.
    pub fn set_radius(&mut self, id: NodeId, radius_m: f32) {
        self.nodes[id.index()].radius_m = radius_m;
    }

    /// The parent, `None` for the root.
    pub fn parent(&self, id: NodeId) -> Option<NodeId> {
        self.nodes[id.index()].parent
    }

    /// Children, main extension first.
    pub fn children(&self, id: NodeId) -> &[NodeId] {
        &self.children[id.index()]
    }

    /// True for a node without children.
    pub fn is_tip(&self, id: NodeId) -> bool {
        self.children[id.index()].is_empty()
    }

    /// True for a node with two or more children.
    pub fn is_fork(&self, id: NodeId) -> bool {
        self.children[id.index()].len() >= 2
    }

    /// Internodes as (parent, child) pairs, in storage order of the child.
    pub fn internodes(&self) -> impl Iterator<Item = (NodeId, NodeId)> + '_ {
        self.ids().filter_map(|c| self.parent(c).map(|p| (p, c)))
    }

    /// Length of the internode that ends at `id` (0 for the root).
    pub fn internode_length(&self, id: NodeId) -> f32 {
        self.parent(id)
            .map_or(0.0, |p| self.position(p).distance(self.position(id)))
    }

    /// Radii at the two ends of the internode that ends at `id`, base
    /// first. A main extension tapers from its parent's radius to its own;
    /// a lateral's first internode has its own radius at both ends, since
    /// the stem it leaves holds its base (a 3 cm twig on a 30 cm trunk is
    /// a 3 cm branch from the bark out). The root's internode is its own
    /// radius twice.
    ///
    /// ```
    /// use glam::{DVec3, Vec3};
    /// use silva::{Anchor, NodeId, Skeleton};
    ///
    /// let mut tree = Skeleton::new(Anchor::at(DVec3::ZERO), 0.3);
    /// let top = tree.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 2.0), 0.2);
    /// let twig = tree.add_child(NodeId::ROOT, Vec3::new(0.5, 0.0, 1.0), 0.03);
    /// assert_eq!(tree.internode_radii(top), (0.3, 0.2));
    /// assert_eq!(tree.internode_radii(twig), (0.03, 0.03));
    /// ```
    pub fn internode_radii(&self, id: NodeId) -> (f32, f32) {
        let own = self.radius(id);
        match self.parent(id) {
            Some(p) if self.children(p).first() == Some(&id) => (self.radius(p), own),
            _ => (own, own),
        }
    }

    /// The angle, in degrees, between each internode and the one before it
    /// (its parent's), for every internode whose parent is not the root;
    /// zero-length internodes are left out. A measure of how much the
    /// chains zigzag.
    pub fn turning_angles_deg(&self) -> Vec<f32> {
        self.ids()
            .filter_map(|id| {
                let parent = self.parent(id)?;
                let before = self.position(parent) - self.position(self.parent(parent)?);
                let after = self.position(id) - self.position(parent);
                (before.length() > 0.0 && after.length() > 0.0)
                    .then(|| before.angle_between(after).to_degrees())
            })
            .collect()
    }

    /// Sum of all internode lengths, in metres.
    pub fn total_length(&self) -> f32 {
        self.ids().map(|id| self.internode_length(id)).sum()
    }

    /// For each node, the summed internode length of its subtree (excluding
    /// the internode leading into it).
    pub fn subtree_lengths(&self) -> Vec<f32> {
        let mut acc = vec![0.0f32; self.nodes.len()];
        for id in self.ids().rev() {
            if let Some(p) = self.parent(id) {
                acc[p.index()] += acc[id.index()] + self.internode_length(id);
            }
        }
        acc
    }

    /// Nodes in depth-first pre-order, main extension before laterals.
    pub fn depth_first(&self) -> Vec<NodeId> {
        let mut order = Vec::with_capacity(self.nodes.len());
        let mut stack = vec![NodeId::ROOT];
        while let Some(id) = stack.pop() {
            order.push(id);
            stack.extend(self.children(id).iter().rev());
        }
        order
    }

    /// Branch order per node: 0 on the trunk; a lateral child starts order
    /// `parent + 1`; a main extension keeps its parent's order.
    pub fn branch_orders(&self) -> Vec<u32> {
        let mut order = vec![0u32; self.nodes.len()];
        for id in self.ids() {
            for (k, &c) in self.children(id).iter().enumerate() {
                order[c.index()] = order[id.index()] + u32::from(k > 0);
            }
        }
        order
    }

    /// Reorders every node's children so that the child with the longest
    /// subtree (including its own internode) comes first: the main extension.
    /// Ties keep their previous order.
    pub fn order_main_extension_first(&mut self) {
        let sub = self.subtree_lengths();
        let weight = |c: NodeId| sub[c.index()] + self.internode_length(c);
        let weights: Vec<f32> = self.ids().map(weight).collect();
        for kids in &mut self.children {
            kids.sort_by(|a, b| weights[b.index()].total_cmp(&weights[a.index()]));
        }
    }

    /// Sets the children order of one node; `order` must be a permutation of
    /// its current children.
    ///
    /// # Panics
    /// If `order` is not a permutation of the node's children.
    pub fn set_children_order(&mut self, id: NodeId, order: Vec<NodeId>) {
        let mut a = order.clone();
        let mut b = self.children[id.index()].to_vec();
        a.sort();
        b.sort();
        assert_eq!(
            a, b,
            "set_children_order needs a permutation of the children"
        );
        self.children[id.index()] = Children::from_vec(order);
    }

    /// A copy that keeps only the nodes with `keep[i] == true` (the root is
    /// always kept). A dropped node's kept descendants attach to its nearest
    /// kept ancestor, so this both prunes subtrees (drop every node in them)
    /// and removes intermediate chain nodes (Douglas–Peucker). Children order
    /// and relative positions are preserved; the result is in depth-first
    /// order.
    ///
    /// # Panics
    /// If `keep.len() != self.len()`.
    pub fn retain(&self, keep: &[bool]) -> Skeleton {
        assert_eq!(keep.len(), self.nodes.len());
        let mut out = Skeleton::new(self.anchor.clone(), self.radius(NodeId::ROOT));
        out.nodes[0].position = self.position(NodeId::ROOT);
        let mut stack = vec![(NodeId::ROOT, NodeId::ROOT)];
        while let Some((old, attach_to)) = stack.pop() {
            let here = if old == NodeId::ROOT {
                NodeId::ROOT
            } else if keep[old.index()] {
                out.add_child(attach_to, self.position(old), self.radius(old))
            } else {
                attach_to
            };
            for &c in self.children(old).iter().rev() {
                stack.push((c, here));
            }
        }
        out
    }

    /// A copy stored in depth-first pre-order (main extension first), the
    /// canonical order used for serialisation and encoding.
    pub fn canonical(&self) -> Skeleton {
        self.retain(&vec![true; self.nodes.len()])
    }

    /// Axis-aligned bounds of the node positions (relative), `(min, max)`.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.nodes.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), n| (lo.min(n.position), hi.max(n.position)),
        )
    }
}

mod json;
mod ply;
pub use json::SkeletonJsonError;
pub(crate) use ply::ply_header_start;
pub use ply::{MAX_PLY_NODES, SkeletonPlyError};
