//! The reader: expanded L-string → turtle → [`Skeleton`]
//! (lsystem-from-adtree-skeletons §3.2.6, "Read the L-string").
//!
//! Unlike the paper's LsTurtle, every `F` creates a node — consecutive `F`s
//! are not merged — so the decoded skeleton has exactly the encoded topology.

use glam::DVec3;

use super::expand::expand;
use super::format::LsJson;
use super::turtle::{Effect, TurtleState};
use super::{Limits, LsError};
use crate::skeleton::{Node, NodeId, Skeleton};

/// A node as the turtle drew it.
struct Drawn {
    position: DVec3,
    radius_m: f64,
    parent: usize,
    /// Bracket depth at which the `F` was read.
    depth: usize,
}

/// Decodes LsJSON into a skeleton in canonical order (depth-first, main
/// extension first). The main extension of a node is the child drawn at the
/// node's own bracket depth, i.e. the continuation after the `[...]`
/// laterals; laterals follow in the order they appear.
pub fn decode(ls: &LsJson, limits: &Limits) -> Result<Skeleton, LsError> {
    let symbols = expand(ls, limits)?;
    let mut turtle = TurtleState::start(ls.trunk_radius_m);
    let mut drawn = vec![Drawn {
        position: DVec3::ZERO,
        radius_m: ls.trunk_radius_m,
        parent: 0,
        depth: 0,
    }];
    let mut current = 0usize;
    let mut saved: Vec<(TurtleState, usize)> = Vec::new();
    for s in symbols {
        match turtle.apply(s, &ls.dimensions, ls.degrees) {
            Effect::Turned => {}
            Effect::Push => saved.push((turtle, current)),
            Effect::Pop => {
                // Balance was checked by `expand`.
                (turtle, current) = saved.pop().ok_or(LsError::Unbalanced {
                    symbol: 0,
                    reason: "']' without a matching '['",
                })?;
            }
            Effect::Drew => {
                if drawn.len() > limits.max_nodes {
                    return Err(LsError::TooManyNodes {
                        limit: limits.max_nodes,
                    });
                }
                let distance = turtle.position.length();
                if distance.is_nan() || distance > limits.max_extent_m {
                    return Err(LsError::OutOfRange {
                        node: drawn.len(),
                        limit_m: limits.max_extent_m,
                    });
                }
                drawn.push(Drawn {
                    position: turtle.position,
                    radius_m: turtle.width_m,
                    parent: current,
                    depth: saved.len(),
                });
                current = drawn.len() - 1;
            }
        }
    }
    to_skeleton(ls, &drawn)
}

fn to_skeleton(ls: &LsJson, drawn: &[Drawn]) -> Result<Skeleton, LsError> {
    let nodes = drawn
        .iter()
        .enumerate()
        .map(|(i, d)| Node {
            position: d.position.as_vec3(),
            radius_m: d.radius_m as f32,
            parent: (i > 0).then(|| NodeId::from_index(d.parent)),
        })
        .collect();
    let mut skeleton = Skeleton::from_nodes(ls.anchor.clone(), nodes)?;
    for id in skeleton.ids() {
        let kids = skeleton.children(id);
        let own_depth = drawn[id.index()].depth;
        let main = kids
            .iter()
            .position(|c| drawn[c.index()].depth == own_depth);
        if let Some(m) = main.filter(|&m| m > 0) {
            let mut order = kids.to_vec();
            let main_child = order.remove(m);
            order.insert(0, main_child);
            skeleton.set_children_order(id, order);
        }
    }
    Ok(skeleton.canonical())
}
