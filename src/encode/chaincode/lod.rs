//! Level of detail on the code itself (chain-code paper §3.2, Pseudocode 2).
//!
//! A *branch* is a lateral child of a fork together with its chain of main
//! extensions down to a tip; the trunk is the branch that starts at the root.
//! [`reduce_lod`] drops every lateral branch whose first node has a stored
//! radius below the threshold `T`, together with everything attached to it
//! (its sub-branches go with it whatever their radii). The trunk is never
//! dropped and no main extension is shortened: as in the paper, a branch is
//! pruned as a unit (Weibull ordering).
//!
//! The code is edited without decoding geometry: the symbols of dropped
//! branches and their radii are cut out, and each fork symbol that spawned a
//! dropped branch is removed. A fork that loses all its laterals ends its
//! internode with 8 instead. Kept branches keep their symbols unchanged, so
//! the decoded reduced skeleton has exactly the positions of the full one.
//! [`prune_like_lod`] applies the same rule to a [`Skeleton`].

use super::dbf6::Terminator;
use super::{ChainCode, ChainError, END, FORK, TIP};
use crate::skeleton::{NodeId, Skeleton};

/// A run of fork symbols at one node: the internode's terminating 6 (absent
/// at the root) and one zero-length 6 per further lateral.
#[derive(Debug, Clone, Copy)]
struct ForkGroup {
    start: usize,
    len: usize,
    ends_internode: bool,
    /// Branch the fork node lies on.
    branch: usize,
    /// The fork node, in decoding order.
    node: usize,
}

#[derive(Debug, Clone, Copy)]
struct Branch {
    /// Symbol range, ending with its 7.
    symbols: (usize, usize),
    /// Node range in decoding order.
    nodes: (usize, usize),
    /// The group whose fork symbol spawned it (`None` for the trunk).
    group: Option<usize>,
}

/// The branch structure of a code, checked against its grammar.
#[derive(Debug)]
pub(crate) struct Scan {
    branches: Vec<Branch>,
    groups: Vec<ForkGroup>,
}

impl Scan {
    /// Number of nodes on each branch, in decoding order (the trunk counts
    /// the root). Branches are contiguous in decoding order.
    pub(crate) fn branch_lengths(&self) -> Vec<usize> {
        self.branches
            .iter()
            .map(|b| b.nodes.1 - b.nodes.0)
            .collect()
    }

    /// The fork node (in decoding order) each branch grows from, `None` for
    /// the trunk; always a node of an earlier branch.
    pub(crate) fn branch_parents(&self) -> Vec<Option<usize>> {
        self.branches
            .iter()
            .map(|b| b.group.map(|g| self.groups[g].node))
            .collect()
    }
}

/// Checks `symbols` against the grammar and finds its branches and fork
/// groups; `n_radii` must equal the number of nodes the symbols describe.
pub(crate) fn scan(symbols: &[u8], n_radii: usize) -> Result<Scan, ChainError> {
    let mut scanner = Scanner::new(symbols.is_empty());
    // Whether the current internode has a move: as in `dbf6::decode`, kept
    // out of `Scanner` for the loop over the moves.
    let mut has_moves = false;
    for (pos, &s) in symbols.iter().enumerate() {
        if scanner.finished {
            return Err(ChainError::TrailingSymbols {
                count: symbols.len() - pos,
            });
        }
        match s {
            0..=5 => has_moves = true,
            FORK | TIP | END => {
                scanner.terminator(pos, s, has_moves);
                has_moves = false;
            }
            _ => {
                return Err(ChainError::InvalidSymbol {
                    position: pos,
                    symbol: s,
                });
            }
        }
    }
    scanner.finish(n_radii)
}

/// [`scan`] of a code given as its internodes' terminators, all of them
/// fork, tip or end symbols, in a code of `n_symbols` symbols.
pub(crate) fn scan_terminators(
    terminators: &[Terminator],
    n_symbols: usize,
    n_radii: usize,
) -> Result<Scan, ChainError> {
    let mut scanner = Scanner::new(n_symbols == 0);
    let mut end = 0;
    for t in terminators {
        if scanner.finished {
            break;
        }
        scanner.terminator(t.pos, t.symbol, t.has_moves);
        end = t.pos + 1;
    }
    if scanner.finished && end < n_symbols {
        return Err(ChainError::TrailingSymbols {
            count: n_symbols - end,
        });
    }
    scanner.finish(n_radii)
}

/// [`scan`]'s state: the branches and fork groups found so far, the one
/// being read and the laterals queued.
struct Scanner {
    branches: Vec<Branch>,
    groups: Vec<ForkGroup>,
    /// Fork groups whose laterals are still to come, oldest first.
    queue: std::collections::VecDeque<usize>,
    /// The fork group a zero-length internode (a further 6) would join.
    open_group: Option<usize>,
    /// Nodes so far, the root included.
    nodes: usize,
    current: Branch,
    /// The 7 that found the queue empty was read (or the code is empty).
    finished: bool,
}

impl Scanner {
    fn new(empty: bool) -> Self {
        Scanner {
            branches: Vec::new(),
            groups: Vec::new(),
            queue: std::collections::VecDeque::new(),
            open_group: None,
            nodes: 1,
            current: Branch {
                symbols: (0, 0),
                nodes: (0, 1),
                group: None,
            },
            finished: empty,
        }
    }

    /// The fork, tip or end symbol `s` at `pos`, after moves or none.
    fn terminator(&mut self, pos: usize, s: u8, has_moves: bool) {
        if s == FORK && !has_moves && (self.open_group.is_some() || pos == 0) {
            self.fork_marker(pos);
        } else {
            self.end_internode(pos, s);
        }
    }

    /// A zero-length fork internode at `pos`: one more lateral of the open
    /// group (a new group at the root).
    fn fork_marker(&mut self, pos: usize) {
        let g = match self.open_group {
            Some(g) => g,
            None => self.open(pos, false),
        };
        self.groups[g].len += 1;
        self.queue.push_back(g);
    }

    /// Starts a fork group at `pos` on the current node and returns it.
    fn open(&mut self, pos: usize, ends_internode: bool) -> usize {
        self.groups.push(ForkGroup {
            start: pos,
            len: 0,
            ends_internode,
            branch: self.branches.len(),
            node: self.nodes - 1,
        });
        let g = self.groups.len() - 1;
        self.open_group = Some(g);
        g
    }

    /// An internode ending in `s` (6, 7 or 8) at `pos`.
    fn end_internode(&mut self, pos: usize, s: u8) {
        self.nodes += 1;
        self.open_group = None;
        if s == FORK {
            let g = self.open(pos, true);
            self.groups[g].len = 1;
            self.queue.push_back(g);
        } else if s == TIP {
            self.current.symbols.1 = pos + 1;
            self.current.nodes.1 = self.nodes;
            self.branches.push(self.current);
            match self.queue.pop_front() {
                Some(g) => {
                    self.current = Branch {
                        symbols: (pos + 1, pos + 1),
                        nodes: (self.nodes, self.nodes),
                        group: Some(g),
                    };
                }
                None => self.finished = true,
            }
        }
    }

    /// The scan, once every symbol was read; `n_radii` must equal the
    /// number of nodes.
    fn finish(mut self, n_radii: usize) -> Result<Scan, ChainError> {
        if !self.finished {
            return Err(ChainError::Unterminated {
                queued: self.queue.len(),
            });
        }
        if self.branches.is_empty() {
            // The empty code: the trunk is the root alone.
            self.branches.push(self.current);
        }
        if self.nodes != n_radii {
            return Err(ChainError::RadiiCount {
                nodes: self.nodes,
                radii: n_radii,
            });
        }
        Ok(Scan {
            branches: self.branches,
            groups: self.groups,
        })
    }
}

/// Pseudocode 2: the code of the skeleton without the lateral branches whose
/// first node's stored radius is below `radius_threshold_m` (see the module
/// docs for the exact rule).
pub fn reduce_lod(code: &ChainCode, radius_threshold_m: f32) -> ChainCode {
    let Scan { branches, groups } = scan_valid(code);
    // Branches are in queue order, so a parent branch precedes its laterals.
    let mut kept = vec![true; branches.len()];
    let mut group_kept: Vec<usize> = groups.iter().map(|g| g.len).collect();
    for (b, branch) in branches.iter().enumerate() {
        let Some(g) = branch.group else { continue };
        let parent_kept = kept[groups[g].branch];
        let base = code.radius_m(code.radii_q[branch.nodes.0]);
        kept[b] = parent_kept && keeps_lateral(base, radius_threshold_m);
        if parent_kept && !kept[b] {
            group_kept[g] -= 1;
        }
    }
    let mut symbols = Vec::with_capacity(code.symbols.len());
    let mut radii_q = Vec::with_capacity(code.radii_q.len());
    let mut next_group = 0;
    for (b, branch) in branches.iter().enumerate() {
        if !kept[b] {
            continue;
        }
        radii_q.extend_from_slice(&code.radii_q[branch.nodes.0..branch.nodes.1]);
        let (start, end) = branch.symbols;
        let mut pos = start;
        while pos < end {
            while next_group < groups.len() && groups[next_group].start < pos {
                next_group += 1;
            }
            match groups.get(next_group) {
                Some(g) if g.start == pos => {
                    let k = group_kept[next_group];
                    if k > 0 {
                        symbols.extend(std::iter::repeat_n(FORK, k));
                    } else if g.ends_internode {
                        symbols.push(END);
                    }
                    pos += g.len;
                }
                _ => {
                    symbols.push(code.symbols[pos]);
                    pos += 1;
                }
            }
        }
    }
    ChainCode {
        header: code.header.clone(),
        symbols,
        radii_q,
    }
}

/// The one LOD rule: a lateral stays if its base radius reaches the
/// threshold (so a NaN threshold drops every lateral).
fn keeps_lateral(base_radius_m: f32, radius_threshold_m: f32) -> bool {
    base_radius_m >= radius_threshold_m
}

/// Scans a code that was checked when it was made.
fn scan_valid(code: &ChainCode) -> Scan {
    scan(&code.symbols, code.radii_q.len()).expect("ChainCode is validated on construction")
}

/// Thresholds for `levels` levels of detail (the full model being level 0):
/// the stored base radii of all lateral branches, deduplicated and sorted,
/// sampled at `⌈k·m/levels⌉` of `m` for `k = 1..levels`, as in the paper's
/// Experiment 1; each threshold prunes at least the thinnest laterals.
/// Increasing; fewer than `levels - 1` when there are few distinct radii.
pub fn lod_thresholds(code: &ChainCode, levels: usize) -> Vec<f32> {
    let Scan { branches, .. } = scan_valid(code);
    let mut base: Vec<u32> = branches[1..]
        .iter()
        .map(|b| code.radii_q[b.nodes.0])
        .collect();
    base.sort_unstable();
    base.dedup();
    let mut out: Vec<f32> = (1..levels)
        .filter_map(|k| base.get((k * base.len()).div_ceil(levels)))
        .map(|&q| code.radius_m(q))
        .collect();
    out.dedup();
    out
}

/// The LOD rule of [`reduce_lod`] applied to a skeleton: drops every lateral
/// branch (with all it carries) whose first node's radius is below
/// `radius_threshold_m`. On a decoded skeleton it gives exactly what decoding
/// the reduced code gives; on an original skeleton it differs only for radii
/// within half a quantisation step of the threshold.
pub fn prune_like_lod(skeleton: &Skeleton, radius_threshold_m: f32) -> Skeleton {
    let mut keep = vec![true; skeleton.len()];
    for id in skeleton.ids() {
        for (k, &c) in skeleton.children(id).iter().enumerate() {
            let kept = k == 0 || keeps_lateral(skeleton.radius(c), radius_threshold_m);
            keep[c.index()] = keep[id.index()] && kept;
        }
    }
    keep[NodeId::ROOT.index()] = true;
    skeleton.retain(&keep)
}

#[cfg(test)]
mod tests {
    use super::super::{ChainOptions, Resolution, decode, encode};
    use super::*;
    use crate::skeleton::Anchor;
    use glam::Vec3;

    fn as_text(symbols: &[u8]) -> String {
        symbols.iter().map(|s| char::from(b'0' + s)).collect()
    }

    /// Trunk with a trifurcation: a thick and a thin lateral, the thin one
    /// carrying a thick sub-branch.
    fn tree() -> Skeleton {
        let mut s = Skeleton::new(Anchor::default(), 0.010);
        let a = s.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 2.0), 0.009);
        let top = s.add_child(a, Vec3::new(0.0, 0.0, 4.0), 0.008);
        let thin = s.add_child(a, Vec3::new(2.0, 0.0, 2.0), 0.002);
        s.add_child(a, Vec3::new(-2.0, 0.0, 2.0), 0.005);
        s.add_child(top, Vec3::new(0.0, 0.0, 5.0), 0.007);
        let t2 = s.add_child(thin, Vec3::new(3.0, 0.0, 2.0), 0.002);
        s.add_child(thin, Vec3::new(2.0, 1.0, 2.0), 0.006);
        s.add_child(t2, Vec3::new(4.0, 0.0, 2.0), 0.001);
        s
    }

    #[test]
    fn prunes_thin_laterals_and_what_they_carry() {
        let opts = ChainOptions {
            resolution: Resolution::VoxelSize(1.0),
            ..ChainOptions::default()
        };
        let code = encode(&tree(), &opts).unwrap();
        assert_eq!(as_text(&code.symbols), "226685700638733717");
        let lod = reduce_lod(&code, 0.0035);
        // The thin lateral goes, and with it its thick sub-branch; the fork
        // keeps one fork symbol for the remaining lateral.
        assert_eq!(as_text(&lod.symbols), "226857337");
        assert_eq!(lod.radii_q, vec![10, 9, 8, 7, 5]);
        let full = decode(&code).unwrap();
        assert_eq!(decode(&lod).unwrap(), prune_like_lod(&full, 0.0035));

        // Dropping every lateral turns the fork into an internode end.
        let trunk = reduce_lod(&code, 0.0095);
        assert_eq!(as_text(&trunk.symbols), "228857");
        assert_eq!(decode(&trunk).unwrap().len(), 4);
    }

    #[test]
    fn thresholds_sample_lateral_base_radii() {
        let code = encode(&tree(), &ChainOptions::default()).unwrap();
        // Lateral base radii: 2, 5, 6 mm.
        let t = lod_thresholds(&code, 4);
        assert_eq!(t.len(), 2);
        assert!((t[0] - 0.005).abs() < 1e-6 && (t[1] - 0.006).abs() < 1e-6);
    }
}
