//! Generalised cylinders: one closed tube per branch, swept along the
//! smoothed axis with rotation-minimising rings.
//!
//! A *branch* is the trunk, or a lateral child followed through its main
//! extensions to a tip (the chain code's unit branch). A lateral's tube
//! starts at the fork node, on its parent's axis, with its radius clamped to
//! the parent's there, so the joint is buried inside the parent tube and
//! leaves no gap. Every tube is closed: a flat disc at its base and a low
//! cone (a rounded tip when smooth-shaded) at its end, so each tube bounds a
//! volume and its faces all wind counter-clockwise seen from outside.
//!
//! A ring is a regular polygon standing for a circle. Were its vertices on
//! the circle, every face would lie inside it (by up to 29 % of the radius
//! mid-edge for a four-sided twig) and the mesh would miss points on the bark
//! that the cylinders fit; [`ring_radius_scale`] instead places them so that
//! the polygon has the circle's perimeter, hence the tube the cylinder's
//! surface area, with the faces straddling the true surface.

use glam::Vec3;

use super::Mesh;
use super::frame::{AxisSample, rotation_minimising_normals, smooth_axis};
use super::lod::{Lod, RingResolution};
use crate::skeleton::{NodeId, Skeleton};

/// Thinner radii are swept at this radius, so rings never collapse into
/// degenerate triangles (skeletons may record 0 at tips).
pub const MIN_RADIUS_M: f32 = 0.001;
/// Consecutive axis points closer than this are merged: a ring on top of
/// another would only add zero-area faces.
const MIN_STEP_M: f32 = 0.001;
/// Height of a tip's cone cap as a fraction of the tip radius.
const TIP_CAP_HEIGHT: f32 = 0.5;

/// How far out a ring's vertices lie, as a multiple of the branch radius,
/// for a ring of `segments` vertices: `(π/n) / sin(π/n)`, which gives the
/// polygon the perimeter of the circle (1.209 for 3 vertices, 1.111 for 4,
/// 1.012 for 12; 1 in the limit).
///
/// ```
/// use silva::mesh::ring_radius_scale;
/// let n = 12;
/// let side = 2.0 * ring_radius_scale(n) * (std::f32::consts::PI / n as f32).sin();
/// assert!((side * n as f32 - std::f32::consts::TAU).abs() < 1e-5);
/// ```
pub fn ring_radius_scale(segments: u32) -> f32 {
    let half_angle = std::f32::consts::PI / segments.max(3) as f32;
    half_angle / half_angle.sin()
}

/// Sweeps every branch of `skeleton` (already reduced to the level) at the
/// ring resolution of `lod`.
pub(super) fn sweep(skeleton: &Skeleton, lod: Lod) -> Mesh {
    let resolution = lod.resolution();
    let mut sweeper = Sweeper {
        resolution,
        mesh: Mesh::default(),
        points: Vec::new(),
        radii: Vec::new(),
        samples: Vec::new(),
        normals: Vec::new(),
        ring: Vec::new(),
        ring_scale: 1.0,
    };
    let estimate = skeleton.len() * 2 * resolution.max_segments as usize;
    sweeper.mesh.positions.reserve(estimate);
    sweeper.mesh.normals.reserve(estimate);
    sweeper.mesh.indices.reserve(estimate * 6);
    if !skeleton.children(NodeId::ROOT).is_empty() {
        sweeper.branch(skeleton, None, NodeId::ROOT);
    }
    for fork in skeleton.ids() {
        for &lateral in skeleton.children(fork).iter().skip(1) {
            sweeper.branch(skeleton, Some(fork), lateral);
        }
    }
    sweeper.mesh
}

/// Reusable buffers for sweeping branch after branch.
struct Sweeper {
    resolution: RingResolution,
    mesh: Mesh,
    points: Vec<Vec3>,
    radii: Vec<f32>,
    samples: Vec<AxisSample>,
    normals: Vec<Vec3>,
    /// Unit (cos, sin) around the current ring.
    ring: Vec<(f32, f32)>,
    /// [`ring_radius_scale`] of the current ring.
    ring_scale: f32,
}

impl Sweeper {
    /// Sweeps the branch that starts at `first` (hanging from `fork`, or the
    /// trunk when `fork` is `None`) and follows main extensions to a tip.
    fn branch(&mut self, skeleton: &Skeleton, fork: Option<NodeId>, first: NodeId) {
        self.collect_axis(skeleton, fork, first);
        if self.points.len() < 2 {
            return;
        }
        smooth_axis(
            &self.points,
            &self.radii,
            &self.resolution,
            &mut self.samples,
        );
        rotation_minimising_normals(&self.samples, &mut self.normals);
        let segments = self.resolution.segments(self.radii[0]) as usize;
        self.ring_scale = ring_radius_scale(segments as u32);
        self.ring = (0..segments)
            .map(|j| {
                let angle = std::f32::consts::TAU * j as f32 / segments as f32;
                (angle.cos(), angle.sin())
            })
            .collect();
        self.emit_tube();
    }

    /// Fills `points` and `radii` with the branch's polyline, merging points
    /// that are too close and clamping radii.
    fn collect_axis(&mut self, skeleton: &Skeleton, fork: Option<NodeId>, first: NodeId) {
        self.points.clear();
        self.radii.clear();
        let push = |points: &mut Vec<Vec3>, radii: &mut Vec<f32>, p: Vec3, r: f32| {
            if points.last().is_none_or(|q| q.distance(p) >= MIN_STEP_M) {
                points.push(p);
                radii.push(r.max(MIN_RADIUS_M));
            }
        };
        if let Some(fork) = fork {
            // Start on the parent's axis, no wider than the parent there.
            let parent_r = skeleton.radius(fork);
            let r = skeleton.radius(first);
            let base_r = if parent_r > 0.0 { r.min(parent_r) } else { r };
            push(
                &mut self.points,
                &mut self.radii,
                skeleton.position(fork),
                base_r,
            );
        }
        let mut node = first;
        loop {
            push(
                &mut self.points,
                &mut self.radii,
                skeleton.position(node),
                skeleton.radius(node),
            );
            match skeleton.children(node).first() {
                Some(&next) => node = next,
                None => break,
            }
        }
    }

    /// Appends the rings, sides and caps of the sampled branch to the mesh.
    fn emit_tube(&mut self) {
        let mesh = &mut self.mesh;
        let n = self.ring.len() as u32;
        let scale = self.ring_scale;
        let first = &self.samples[0];
        let base = mesh.push_vertex(first.centre, -first.tangent);
        let ring0 = mesh.positions.len() as u32;
        for (s, normal) in self.samples.iter().zip(&self.normals) {
            let binormal = s.tangent.cross(*normal);
            for &(c, sn) in &self.ring {
                let radial = *normal * c + binormal * sn;
                let surface_normal = (radial - s.tangent * s.radius_slope)
                    .try_normalize()
                    .unwrap_or(radial);
                mesh.push_vertex(s.centre + radial * (s.radius_m * scale), surface_normal);
            }
        }
        let last = self.samples[self.samples.len() - 1];
        let apex = mesh.push_vertex(
            last.centre + last.tangent * (last.radius_m * TIP_CAP_HEIGHT),
            last.tangent,
        );
        let rings = self.samples.len() as u32;
        for j in 0..n {
            let k = (j + 1) % n;
            mesh.indices
                .extend_from_slice(&[base, ring0 + k, ring0 + j]);
        }
        for i in 0..rings - 1 {
            let (a, b) = (ring0 + i * n, ring0 + (i + 1) * n);
            for j in 0..n {
                let k = (j + 1) % n;
                mesh.indices
                    .extend_from_slice(&[a + j, a + k, b + j, a + k, b + k, b + j]);
            }
        }
        let tip = ring0 + (rings - 1) * n;
        for j in 0..n {
            let k = (j + 1) % n;
            mesh.indices.extend_from_slice(&[tip + j, tip + k, apex]);
        }
    }
}
