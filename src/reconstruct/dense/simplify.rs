//! Skeleton simplification after AdTree (lsystem-from-adtree-skeletons
//! §2.1.1, "Skeleton simplification"): merge near-duplicate children, drop
//! noisy short branches weighted by their subtree length, and thin chains
//! with Douglas–Peucker.

use glam::Vec3;

use crate::skeleton::{Node, NodeId, Skeleton};

/// Merges children of one node that lie within `merge_m` of each other, or
/// within the spread of their parent's cross-section: arcs of one thick
/// stem's cross-section that the binning split apart. The
/// merged node sits at the point-weighted mean, and the grandchildren become
/// siblings, so parallel duplicate chains zip together from the fork up.
pub(super) fn merge_close_siblings(
    mut nodes: Vec<Node>,
    mut counts: Vec<u32>,
    spread_m: &[f32],
    merge_m: f32,
) -> Vec<Node> {
    let n = nodes.len();
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (i, node) in nodes.iter().enumerate() {
        if let Some(p) = node.parent {
            children[p.index()].push(i);
        }
    }
    let mut alive = vec![true; n];
    for v in 0..n {
        let merge_m = merge_m.max(spread_m[v]);
        'again: loop {
            let kids = &children[v];
            for (x, &a) in kids.iter().enumerate() {
                for &b in &kids[x + 1..] {
                    if nodes[a].position.distance(nodes[b].position) < merge_m {
                        let (keep, gone) = (a.min(b), a.max(b));
                        let (wk, wg) = (counts[keep] as f32, counts[gone] as f32);
                        nodes[keep].position = (nodes[keep].position * wk
                            + nodes[gone].position * wg)
                            / (wk + wg).max(1.0);
                        counts[keep] += counts[gone];
                        alive[gone] = false;
                        let moved = std::mem::take(&mut children[gone]);
                        for &g in &moved {
                            nodes[g].parent = Some(NodeId::from_index(keep));
                        }
                        children[keep].extend(moved);
                        children[v].retain(|&c| c != gone);
                        continue 'again;
                    }
                }
            }
            break;
        }
    }
    compact(nodes, &alive)
}

/// Drops dead nodes and renumbers parents (order is preserved, so parents
/// still precede children).
fn compact(nodes: Vec<Node>, alive: &[bool]) -> Vec<Node> {
    let mut new_id = vec![0usize; nodes.len()];
    let mut next = 0;
    for (i, &a) in alive.iter().enumerate() {
        new_id[i] = next;
        next += usize::from(a);
    }
    nodes
        .into_iter()
        .zip(alive)
        .filter(|(_, a)| **a)
        .map(|(mut node, _)| {
            node.parent = node.parent.map(|p| NodeId::from_index(new_id[p.index()]));
            node
        })
        .collect()
}

/// Removes lateral subtrees whose total length (including the internode
/// into them) is below `min_branch_m` or below the parent's diameter (its
/// `radius_m` holds the cross-section's spread here): the noisy stubs that the binning
/// produces where a cross-section splits for one bin. The heaviest child of
/// each fork always stays, so branches keep their full length.
pub(super) fn prune_short_branches(skeleton: &Skeleton, min_branch_m: f32) -> Skeleton {
    let sub = skeleton.subtree_lengths();
    let weight = |c: NodeId| sub[c.index()] + skeleton.internode_length(c);
    let mut keep = vec![true; skeleton.len()];
    for v in skeleton.ids() {
        if !keep[v.index()] {
            for &c in skeleton.children(v) {
                keep[c.index()] = false;
            }
            continue;
        }
        let kids = skeleton.children(v);
        if kids.len() < 2 {
            continue;
        }
        let heaviest = kids
            .iter()
            .copied()
            .max_by(|&a, &b| weight(a).total_cmp(&weight(b)));
        // Stubs no longer than the parent stem is thick are bark noise.
        let min_m = min_branch_m.max(2.0 * skeleton.radius(v));
        for &c in kids {
            if Some(c) != heaviest && weight(c) < min_m {
                keep[c.index()] = false;
            }
        }
    }
    skeleton.retain(&keep)
}

/// Douglas–Peucker along every chain (the run of single-child nodes between
/// forks and tips): interior nodes closer than `tolerance_m` to the
/// simplified line are removed.
pub(super) fn douglas_peucker(skeleton: &Skeleton, tolerance_m: f32) -> Skeleton {
    let mut keep = vec![true; skeleton.len()];
    for v in skeleton.ids() {
        if v != NodeId::ROOT && skeleton.children(v).len() == 1 {
            continue; // not a chain start
        }
        for &c in skeleton.children(v) {
            let mut chain = vec![v, c];
            let mut end = c;
            while skeleton.children(end).len() == 1 {
                end = skeleton.children(end)[0];
                chain.push(end);
            }
            let pts: Vec<Vec3> = chain.iter().map(|&id| skeleton.position(id)).collect();
            let mut chain_keep = vec![false; pts.len()];
            mark_douglas_peucker(&pts, 0, pts.len() - 1, tolerance_m, &mut chain_keep);
            for (&id, &k) in chain.iter().zip(&chain_keep).skip(1) {
                keep[id.index()] = k || skeleton.children(id).len() != 1;
            }
        }
    }
    skeleton.retain(&keep)
}

/// Marks the endpoints and, recursively, the farthest interior point while
/// it deviates more than `tolerance_m` from the segment.
fn mark_douglas_peucker(
    pts: &[Vec3],
    first: usize,
    last: usize,
    tolerance_m: f32,
    keep: &mut [bool],
) {
    keep[first] = true;
    keep[last] = true;
    if last <= first + 1 {
        return;
    }
    let (a, b) = (pts[first], pts[last]);
    let (far, dev) = (first + 1..last)
        .map(|i| (i, point_segment_distance(pts[i], a, b)))
        .max_by(|x, y| x.1.total_cmp(&y.1))
        .unwrap_or((first, 0.0));
    if dev > tolerance_m {
        mark_douglas_peucker(pts, first, far, tolerance_m, keep);
        mark_douglas_peucker(pts, far, last, tolerance_m, keep);
    }
}

/// Distance from `p` to the segment `a`–`b`.
pub(crate) fn point_segment_distance(p: Vec3, a: Vec3, b: Vec3) -> f32 {
    let ab = b - a;
    let len2 = ab.length_squared();
    let t = if len2 > 0.0 {
        ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    p.distance(a + ab * t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::Anchor;

    fn node(p: [f32; 3], parent: Option<usize>) -> Node {
        Node {
            position: Vec3::from(p),
            radius_m: 0.0,
            parent: parent.map(NodeId::from_index),
        }
    }

    #[test]
    fn close_siblings_merge_and_adopt_grandchildren() {
        let nodes = vec![
            node([0.0, 0.0, 0.0], None),
            node([0.0, 0.0, 1.0], Some(0)),
            node([0.02, 0.0, 1.0], Some(0)),
            node([0.0, 0.0, 2.0], Some(1)),
            node([0.02, 0.0, 2.0], Some(2)),
        ];
        let merged = merge_close_siblings(nodes, vec![1; 5], &[0.0; 5], 0.05);
        assert_eq!(merged.len(), 3);
        assert!((merged[1].position.x - 0.01).abs() < 1e-6);
        assert_eq!(merged[2].parent, Some(NodeId::from_index(1)));
    }

    #[test]
    fn short_stubs_go_and_douglas_peucker_straightens_chains() {
        let nodes = vec![
            node([0.0, 0.0, 0.0], None),
            node([0.0, 0.0, 1.0], Some(0)),
            node([0.001, 0.0, 2.0], Some(1)),
            node([0.0, 0.0, 3.0], Some(2)),
            node([0.05, 0.0, 1.05], Some(1)), // a 7 cm stub
        ];
        let s = Skeleton::from_nodes(Anchor::default(), nodes).unwrap();
        let pruned = prune_short_branches(&s, 0.2);
        assert_eq!(pruned.len(), 4);
        let straight = douglas_peucker(&pruned, 0.01);
        assert_eq!(straight.len(), 2);
        assert_eq!(
            straight.position(NodeId::from_index(1)),
            Vec3::new(0.0, 0.0, 3.0)
        );
    }
}
