//! The skeleton's PLY form: one vertex per node (`double x y z` in CRS
//! coordinates, `float radius` in metres) and one edge per internode (`int
//! vertex1`, `int vertex2`, parent to child).
//!
//! [`Skeleton::to_ply`] writes it binary, so that `silva reconstruct
//! --skeleton s.ply` gives a file any PLY viewer opens: the paper
//! lsystem-from-adtree-skeletons (§3.4) found that AdTree's own skeleton PLY
//! could not be opened by any viewer it tried.
//!
//! [`Skeleton::from_ply`] reads silva's files back and also the "classical
//! skeleton" PLY of the augmented AdTree (same paper, Fig. 3.11: ascii,
//! `float x y z`, an empty face element, edges between vertex indices and no
//! radius), so an AdTree skeleton can be encoded as LsJSON or chain code
//! directly, the paper's own workflow. As elsewhere the raw layer is kept
//! apart: `cloud`'s PLY reader turns the bytes into columns, and only this
//! module knows what they mean as a tree.
//!
//! # Which vertex is the root
//! - A file silva wrote (its header comment says `silva tree skeleton`)
//!   whose edges all point parent to child away from vertex 0 (no vertex is
//!   the second end of two edges, vertex 0 of none) is taken as it stands,
//!   each node's children in edge order (silva's order: main extension
//!   first). Its root is the trunk base even where a branch hangs lower.
//! - Any other file's edges are taken as undirected: a chain written from
//!   the top down also points away from its vertex 0, so the direction of a
//!   foreign file's edges says nothing. The root is the lowest vertex, the
//!   trunk base of an upright tree (the same upright-axis assumption as
//!   reconstruction), edges are oriented away from it and children are
//!   ordered main extension first ([`Skeleton::order_main_extension_first`]).
//!
//! Either way the edges must form one tree over all vertices: `n` vertices
//! joined by `n − 1` edges with every vertex reachable from the root.
//! Without a `radius` property every radius is 0 (the CLI then estimates
//! them: `silva::reconstruct::radii::estimate_radii`).
//!
//! The anchor is the root's position, with the CRS of a `comment crs NAME`
//! line; a `comment origin X Y Z` line (silva writes `0 0 0`) is added to
//! every vertex.

use std::fmt::Write;

use glam::DVec3;

use super::{Anchor, Node, NodeId, Skeleton, SkeletonError};
use crate::cloud::{CloudError, PlyDocument, read_document};

/// Most vertices a skeleton PLY may hold: the node limit of the chain-code
/// decoder (`encode::chaincode::Limits`), far above any tree silva makes.
pub const MAX_PLY_NODES: usize = 1 << 22;

/// The start of the header comment that marks a file silva wrote.
const WRITER: &str = "silva tree skeleton";

/// Longest CRS name taken from a `comment crs` line.
const MAX_CRS_BYTES: usize = 256;

/// Why a skeleton PLY was rejected.
#[derive(Debug, thiserror::Error)]
pub enum SkeletonPlyError {
    /// Not a readable PLY document.
    #[error("skeleton {0}")]
    Ply(#[from] CloudError),
    /// An element or property a skeleton needs is missing or unusable.
    #[error("skeleton PLY: {0}")]
    Layout(String),
    /// A vertex has a non-finite coordinate or a bad radius.
    #[error("skeleton PLY: vertex {vertex}: {reason}")]
    Vertex {
        /// 0-based vertex index in the file.
        vertex: usize,
        /// What is wrong with it.
        reason: String,
    },
    /// An edge names a vertex that does not exist, or joins one to itself.
    #[error("skeleton PLY: edge {edge}: {reason}")]
    Edge {
        /// 0-based edge index in the file.
        edge: usize,
        /// What is wrong with it.
        reason: String,
    },
    /// The edges do not join the vertices into one tree.
    #[error("skeleton PLY: the edges do not form one tree: {0}")]
    NotATree(String),
    /// The nodes do not form a valid skeleton.
    #[error("skeleton PLY: {0}")]
    Invalid(#[from] SkeletonError),
}

impl Skeleton {
    /// Encodes the skeleton as binary little-endian PLY: one vertex per node
    /// with absolute `double` coordinates and a `float` radius in metres, and
    /// one edge (`int vertex1`, `int vertex2`, parent to child) per internode.
    ///
    /// ```
    /// use glam::{DVec3, Vec3};
    /// use silva::{Anchor, NodeId, Skeleton};
    ///
    /// let mut tree = Skeleton::new(Anchor::at(DVec3::new(85_000.0, 446_000.0, 0.5)), 0.2);
    /// let top = tree.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 3.0), 0.1);
    /// tree.add_child(top, Vec3::new(0.5, 0.0, 3.5), 0.02);
    /// let ply = tree.to_ply();
    /// assert!(ply.starts_with(b"ply\nformat binary_little_endian 1.0\n"));
    /// let back = Skeleton::from_ply(&ply).unwrap();
    /// assert_eq!(back.len(), 3);
    /// assert_eq!(back.absolute_position(NodeId::from_index(2)), DVec3::new(85_000.5, 446_000.0, 4.0));
    /// ```
    pub fn to_ply(&self) -> Vec<u8> {
        let mut header = ply_header_start(
            &format!("{WRITER}, metres, z up"),
            self.anchor(),
            DVec3::ZERO,
        );
        let _ = write!(
            header,
            "element vertex {}\nproperty double x\nproperty double y\nproperty double z\n\
             property float radius\nelement edge {}\nproperty int vertex1\nproperty int vertex2\n\
             end_header\n",
            self.len(),
            self.internode_count()
        );
        let mut out = header.into_bytes();
        out.reserve(self.len() * 28 + self.internode_count() * 8);
        for id in self.ids() {
            for c in self.absolute_position(id).to_array() {
                out.extend_from_slice(&c.to_le_bytes());
            }
            out.extend_from_slice(&self.radius(id).to_le_bytes());
        }
        for (parent, child) in self.internodes() {
            // Node counts fit in i32 for any skeleton this crate reconstructs;
            // PLY readers expect the signed `int` for edges.
            out.extend_from_slice(&(parent.index() as i32).to_le_bytes());
            out.extend_from_slice(&(child.index() as i32).to_le_bytes());
        }
        out
    }

    /// Reads a skeleton PLY: silva's own ([`Skeleton::to_ply`]) or AdTree's
    /// classical skeleton (ascii, no radius, edges in any direction). See
    /// the module docs for how the root is found.
    ///
    /// ```
    /// use silva::{NodeId, Skeleton};
    ///
    /// // AdTree's layout (lsystem-from-adtree-skeletons, Fig. 3.11), edges
    /// // in no particular direction or order.
    /// let adtree = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\n\
    ///     property float y\nproperty float z\nelement face 0\n\
    ///     property list uchar int vertex_index\nelement edge 3\n\
    ///     property int vertex1\nproperty int vertex2\nend_header\n\
    ///     127395.5 401149.75 14.0\n127395.5 401149.75 11.0\n\
    ///     127396.5 401149.75 13.0\n127395.5 401149.75 12.0\n\
    ///     2 3\n3 1\n0 3\n";
    /// let tree = Skeleton::from_ply(adtree.as_bytes()).unwrap();
    /// assert_eq!(tree.len(), 4);
    /// assert_eq!(tree.absolute_position(NodeId::ROOT).z, 11.0); // the lowest vertex
    /// assert_eq!(tree.children(NodeId::from_index(1)).len(), 2); // the fork at 12 m
    /// assert_eq!(tree.radius(NodeId::ROOT), 0.0); // AdTree writes no radius
    /// ```
    pub fn from_ply(bytes: &[u8]) -> Result<Skeleton, SkeletonPlyError> {
        let keep = |element: &str, property: &str| match element {
            "vertex" => matches!(property, "x" | "y" | "z" | "radius"),
            "edge" => matches!(property, "vertex1" | "vertex2"),
            _ => false,
        };
        let doc = read_document(bytes, &keep, MAX_PLY_NODES as u64)?;
        let vertices = Vertices::read(&doc)?;
        let edges = edges(&doc, vertices.len())?;
        let by_silva = doc.comments.iter().any(|c| c.starts_with(WRITER));
        let rooted = Rooted::from_edges(&vertices, &edges, by_silva)?;
        rooted.skeleton(&vertices, crs(&doc)?)
    }
}

/// The start of silva's PLY headers, up to the first element: format, what
/// the file holds, its CRS and the origin to add to every vertex.
pub(crate) fn ply_header_start(what: &str, anchor: &Anchor, local_origin: DVec3) -> String {
    let mut header = String::from("ply\nformat binary_little_endian 1.0\n");
    let _ = writeln!(header, "comment {what}");
    if let Some(crs) = &anchor.crs {
        let _ = writeln!(header, "comment crs {crs}");
    }
    let _ = writeln!(
        header,
        "comment origin {} {} {} (add to every vertex for CRS coordinates)",
        local_origin.x, local_origin.y, local_origin.z
    );
    header
}

fn layout(reason: impl Into<String>) -> SkeletonPlyError {
    SkeletonPlyError::Layout(reason.into())
}

/// The vertex element as absolute positions and radii.
struct Vertices {
    positions: Vec<DVec3>,
    radii: Vec<f32>,
}

impl Vertices {
    fn read(doc: &PlyDocument) -> Result<Self, SkeletonPlyError> {
        let element = doc
            .element("vertex")
            .ok_or_else(|| layout("no vertex element"))?;
        let column = |name: &str| {
            element
                .column(name)
                .ok_or_else(|| layout(format!("the vertex element has no scalar {name} property")))
        };
        let (x, y, z) = (column("x")?, column("y")?, column("z")?);
        if x.is_empty() {
            return Err(layout("no vertices: a skeleton has at least its root"));
        }
        let origin = origin(doc);
        let positions: Vec<DVec3> = (0..x.len())
            .map(|i| origin + DVec3::new(x[i], y[i], z[i]))
            .collect();
        let radii: Vec<f32> = element.column("radius").map_or_else(
            || vec![0.0; x.len()],
            |r| r.iter().map(|&r| r as f32).collect(),
        );
        for (vertex, (p, r)) in positions.iter().zip(&radii).enumerate() {
            let reason = if !p.is_finite() {
                "a coordinate is not finite"
            } else if !(r.is_finite() && *r >= 0.0) {
                "the radius is not a finite number of metres, 0 or more"
            } else {
                continue;
            };
            return Err(SkeletonPlyError::Vertex {
                vertex,
                reason: reason.into(),
            });
        }
        Ok(Vertices { positions, radii })
    }

    fn len(&self) -> usize {
        self.positions.len()
    }

    /// The lowest vertex (the first of equals): the trunk base of an
    /// upright tree.
    fn lowest(&self) -> usize {
        (0..self.len())
            .min_by(|&a, &b| self.positions[a].z.total_cmp(&self.positions[b].z))
            .expect("there is at least one vertex")
    }
}

/// A `comment origin X Y Z` line's offset, or zero.
fn origin(doc: &PlyDocument) -> DVec3 {
    doc.comments
        .iter()
        .filter_map(|c| c.strip_prefix("origin "))
        .find_map(|rest| {
            let xyz: Vec<f64> = rest
                .split_ascii_whitespace()
                .take(3)
                .map_while(|w| w.parse().ok())
                .collect();
            (xyz.len() == 3 && xyz.iter().all(|v| v.is_finite()))
                .then(|| DVec3::new(xyz[0], xyz[1], xyz[2]))
        })
        .unwrap_or(DVec3::ZERO)
}

/// A `comment crs NAME` line's CRS.
fn crs(doc: &PlyDocument) -> Result<Option<String>, SkeletonPlyError> {
    let Some(name) = doc.comments.iter().find_map(|c| c.strip_prefix("crs ")) else {
        return Ok(None);
    };
    let name = name.trim();
    if name.len() > MAX_CRS_BYTES {
        return Err(layout(format!(
            "the CRS comment is longer than {MAX_CRS_BYTES} bytes"
        )));
    }
    Ok(Some(name.to_owned()))
}

/// The edge element as pairs of vertex indices, checked against `n`
/// vertices: one tree needs exactly `n − 1` of them.
fn edges(doc: &PlyDocument, n: usize) -> Result<Vec<(usize, usize)>, SkeletonPlyError> {
    let Some(element) = doc.element("edge") else {
        if n == 1 {
            return Ok(Vec::new());
        }
        return Err(layout(
            "no edge element: a skeleton PLY joins its vertices by edges (vertex1, vertex2); \
             a point cloud is read by `silva reconstruct`",
        ));
    };
    let column = |name: &str| {
        element
            .column(name)
            .ok_or_else(|| layout(format!("the edge element has no scalar {name} property")))
    };
    let (first, second) = (column("vertex1")?, column("vertex2")?);
    if first.len() + 1 != n {
        return Err(SkeletonPlyError::NotATree(format!(
            "{n} vertices need {} edges, the file has {}",
            n - 1,
            first.len()
        )));
    }
    let vertex = |edge: usize, v: f64| {
        if v.fract() == 0.0 && v >= 0.0 && v < n as f64 {
            Ok(v as usize)
        } else {
            Err(SkeletonPlyError::Edge {
                edge,
                reason: format!("{v} is not one of the {n} vertices"),
            })
        }
    };
    (0..first.len())
        .map(|edge| {
            let (a, b) = (vertex(edge, first[edge])?, vertex(edge, second[edge])?);
            if a == b {
                return Err(SkeletonPlyError::Edge {
                    edge,
                    reason: format!("joins vertex {a} to itself"),
                });
            }
            Ok((a, b))
        })
        .collect()
}

/// Neighbour lists in one array (compressed rows), in edge order.
struct Adjacency {
    start: Vec<usize>,
    to: Vec<usize>,
}

impl Adjacency {
    fn new(n: usize, pairs: impl Iterator<Item = (usize, usize)> + Clone) -> Self {
        let mut start = vec![0; n + 1];
        for (a, _) in pairs.clone() {
            start[a + 1] += 1;
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut to = vec![0; start[n]];
        for (a, b) in pairs {
            to[fill[a]] = b;
            fill[a] += 1;
        }
        Adjacency { start, to }
    }

    fn of(&self, v: usize) -> &[usize] {
        &self.to[self.start[v]..self.start[v + 1]]
    }
}

/// The vertices in depth-first pre-order from the root, with each one's
/// parent: the node order of the skeleton.
struct Rooted {
    order: Vec<usize>,
    parent: Vec<Option<usize>>,
    /// Children in the file's edge order, which silva wrote main extension
    /// first; otherwise they are ordered from subtree lengths.
    ordered: bool,
}

impl Rooted {
    fn from_edges(
        vertices: &Vertices,
        edges: &[(usize, usize)],
        by_silva: bool,
    ) -> Result<Self, SkeletonPlyError> {
        let n = vertices.len();
        if by_silva && points_away_from_vertex_0(n, edges) {
            let children = Adjacency::new(n, edges.iter().copied());
            if let Some(rooted) = Self::walk(0, &children, true) {
                return Ok(rooted);
            }
        }
        let both_ways = edges.iter().flat_map(|&(a, b)| [(a, b), (b, a)]);
        let root = vertices.lowest();
        Self::walk(root, &Adjacency::new(n, both_ways), false).ok_or_else(|| {
            SkeletonPlyError::NotATree(format!(
                "some vertices are not joined to the lowest vertex ({root}), the root"
            ))
        })
    }

    /// Depth-first pre-order from `root`; `None` unless every vertex is
    /// reached.
    fn walk(root: usize, neighbours: &Adjacency, ordered: bool) -> Option<Self> {
        let n = neighbours.start.len() - 1;
        let mut parent = vec![None; n];
        let mut seen = vec![false; n];
        let mut order = Vec::with_capacity(n);
        let mut stack = vec![root];
        seen[root] = true;
        while let Some(v) = stack.pop() {
            order.push(v);
            for &w in neighbours.of(v).iter().rev() {
                if !seen[w] {
                    seen[w] = true;
                    parent[w] = Some(v);
                    stack.push(w);
                }
            }
        }
        (order.len() == n).then_some(Rooted {
            order,
            parent,
            ordered,
        })
    }

    fn skeleton(
        self,
        vertices: &Vertices,
        crs: Option<String>,
    ) -> Result<Skeleton, SkeletonPlyError> {
        let root = vertices.positions[self.order[0]];
        let mut index = vec![0; self.order.len()];
        for (i, &v) in self.order.iter().enumerate() {
            index[v] = i;
        }
        let nodes = self
            .order
            .iter()
            .map(|&v| Node {
                position: (vertices.positions[v] - root).as_vec3(),
                radius_m: vertices.radii[v],
                parent: self.parent[v].map(|p| NodeId::from_index(index[p])),
            })
            .collect();
        let mut skeleton = Skeleton::from_nodes(Anchor { origin: root, crs }, nodes)?;
        if !self.ordered {
            skeleton.order_main_extension_first();
            skeleton = skeleton.canonical();
        }
        Ok(skeleton)
    }
}

/// Whether every edge points parent to child away from vertex 0: no vertex
/// is the second end of two edges, and vertex 0 of none.
fn points_away_from_vertex_0(n: usize, edges: &[(usize, usize)]) -> bool {
    let mut has_parent = vec![false; n];
    for &(_, child) in edges {
        if child == 0 || has_parent[child] {
            return false;
        }
        has_parent[child] = true;
    }
    true
}
