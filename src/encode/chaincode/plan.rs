//! Rate-optimised voxel choice ([`Voxelisation::Optimised`]): the voxels of
//! the whole tree chosen at once, by dynamic programming over the tree, so
//! that the corrections compress shortest.
//!
//! Why: each node may take any voxel whose centre lies within `√3·d/2` of
//! it (about 2.7 on average), and each such choice keeps the error bound
//! (`docs/chaincode.md` §2). The greedy choice ([`Voxelisation::Predictive`])
//! takes the one nearest the prediction, node by node. But a node's voxel
//! also sets the prediction of its main extension and the origin of its
//! laterals, so a choice that is cheap for one internode can make the next
//! dear. This is the chain-code paper's "optimizing chain code generation
//! for increased compressibility while maintaining control over the
//! reconstruction error" (§1, §3.1), done over the whole tree.
//!
//! **Cost.** The split-stream coder (`split.rs`) writes each correction as
//! three zigzagged values, one stream per kind of internode (a branch's
//! first, coded in full and centred, or a continuation) and per axis, each
//! by interpolative coding of the cumulative sums. That coding spends about
//! `n·log2(S/n)` bits on `n` values summing to `S`, so one more unit of value
//! costs about `λ = n / (S·ln 2)` bits. The [`CostModel`] charges each value
//! `λ·zigzag(v − centre)`, with `λ` and the centre of its stream taken from
//! an earlier encoding. (Order-0 code lengths, tried first, lowered the
//! corrections' entropy but not the interpolative code: that coder follows
//! the values' sizes, not their frequencies.)
//!
//! **Program.** A continuation's prediction depends on its parent's and its
//! grandparent's voxels, so a node's state is the pair (parent's candidate,
//! own candidate). `best[n][(p, c)]` is the least cost of everything below
//! node `n` given that pair. It is filled from the tips to the root, and the
//! voxels are then read from the root down. The work is linear in the
//! number of nodes, times at most 8³ candidate triples per internode.
//!
//! [`Voxelisation::Optimised`]: super::Voxelisation::Optimised
//! [`Voxelisation::Predictive`]: super::Voxelisation::Predictive

use glam::DVec3;

use super::Prediction;
use super::container::zigzag;
use crate::skeleton::{NodeId, Skeleton};

/// Squared distance, in voxel units, within which a voxel centre may stand
/// for a node: `(√3/2)²`, the test of the greedy choice too.
pub(super) const REACH_SQ: f64 = 0.75;

/// Largest centre of a branch-first correction stream, as `split.rs`
/// stores it.
const MAX_CENTRE: i64 = 3;

/// Which correction streams an internode writes to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Kind {
    /// The first internode of a branch (the root's children included),
    /// coded in full from its fork.
    BranchFirst = 0,
    /// A main extension, coded as a correction of its prediction.
    Continuation = 1,
}

impl Kind {
    /// The kind of `node`'s internode (`node` is not the root).
    pub(super) fn of(skeleton: &Skeleton, node: NodeId) -> Self {
        match skeleton.parent(node) {
            Some(parent)
                if skeleton.parent(parent).is_some() && skeleton.children(parent)[0] == node =>
            {
                Kind::Continuation
            }
            _ => Kind::BranchFirst,
        }
    }

    /// The voxel an internode of this kind is coded from, given its
    /// parent's and its grandparent's voxels. Differential prediction: a
    /// main extension repeats (a share of) the previous internode's step;
    /// a branch's first internode is coded in full, from its fork's voxel.
    /// Voxels stay within ±2^28 and a predicted step within its previous
    /// step, so the sum stays within `i32`.
    #[inline]
    pub(super) fn predicted(
        self,
        prediction: Prediction,
        parent: [i32; 3],
        grand: [i32; 3],
    ) -> [i32; 3] {
        match self {
            Kind::BranchFirst => parent,
            Kind::Continuation => {
                let step = prediction.step(sub(parent, grand));
                [
                    parent[0] + step[0],
                    parent[1] + step[1],
                    parent[2] + step[2],
                ]
            }
        }
    }
}

/// Estimated bits of a correction: per kind and axis, `λ` bits per unit of
/// zigzagged distance from the stream's centre.
#[derive(Debug, Clone, PartialEq)]
struct CostModel {
    centre: [[i64; 3]; 2],
    lambda: [[f64; 3]; 2],
}

impl CostModel {
    /// The model of the corrections that `voxels` give.
    fn of(tree: &TreeView<'_>, voxels: &[[i32; 3]]) -> Self {
        let mut values: [[Vec<i64>; 3]; 2] = Default::default();
        for node in tree.skeleton.ids().skip(1) {
            let (kind, c) = tree.correction(node, voxels);
            for (axis, &v) in c.iter().enumerate() {
                values[kind as usize][axis].push(i64::from(v));
            }
        }
        let mut model = Self {
            centre: [[0; 3]; 2],
            lambda: [[0.0; 3]; 2],
        };
        for (kind, per_axis) in values.iter().enumerate() {
            for (axis, vs) in per_axis.iter().enumerate() {
                let sum = |c: i64| vs.iter().map(|&v| zigzag(v - c) as f64).sum::<f64>();
                let centre = if kind == Kind::BranchFirst as usize {
                    (-MAX_CENTRE..=MAX_CENTRE)
                        .min_by(|&a, &b| sum(a).total_cmp(&sum(b)))
                        .unwrap_or(0)
                } else {
                    0
                };
                let n = vs.len().max(1) as f64;
                model.centre[kind][axis] = centre;
                model.lambda[kind][axis] = n / (sum(centre).max(1.0) * std::f64::consts::LN_2);
            }
        }
        model
    }

    /// Estimated bits of correction `c` of kind `kind`.
    #[inline]
    fn cost(&self, kind: Kind, c: [i32; 3]) -> f64 {
        let k = kind as usize;
        (0..3)
            .map(|axis| {
                self.lambda[k][axis] * zigzag(i64::from(c[axis]) - self.centre[k][axis]) as f64
            })
            .sum()
    }
}

/// The skeleton with what the program needs of each node: its kind and
/// its candidate voxels.
struct TreeView<'a> {
    skeleton: &'a Skeleton,
    prediction: Prediction,
    kinds: Vec<Kind>,
}

impl<'a> TreeView<'a> {
    fn new(skeleton: &'a Skeleton, prediction: Prediction) -> Self {
        let kinds = skeleton
            .ids()
            .map(|node| Kind::of(skeleton, node))
            .collect();
        Self {
            skeleton,
            prediction,
            kinds,
        }
    }

    /// The voxel `node`'s correction is taken from ([`Kind::predicted`]).
    #[inline]
    fn predicted(&self, node: NodeId, parent: [i32; 3], grand: [i32; 3]) -> [i32; 3] {
        self.kinds[node.index()].predicted(self.prediction, parent, grand)
    }

    /// `node`'s kind and correction under `voxels` (`node` is not the root).
    fn correction(&self, node: NodeId, voxels: &[[i32; 3]]) -> (Kind, [i32; 3]) {
        let parent = self
            .skeleton
            .parent(node)
            .expect("only the root lacks a parent");
        let grand = self.skeleton.parent(parent).unwrap_or(parent);
        let from = self.predicted(node, voxels[parent.index()], voxels[grand.index()]);
        (self.kinds[node.index()], sub(voxels[node.index()], from))
    }

    /// Cost of `node` taking candidate `ic` when its correction is taken
    /// from voxel `from`, plus the least cost below it given that its
    /// parent took candidate `ip`.
    #[inline]
    fn step_cost(
        &self,
        program: &Program<'_>,
        node: NodeId,
        ip: usize,
        ic: usize,
        from: [i32; 3],
    ) -> f32 {
        let cands = program.cands(node);
        program
            .model
            .cost(self.kinds[node.index()], sub(cands[ic], from)) as f32
            + program.best(node)[ip * cands.len() + ic]
    }
}

/// The dynamic program's tables, each node's a slice of one array.
struct Program<'m> {
    model: &'m CostModel,
    /// Node `i`'s candidate voxels are `cands[cand_at[i]..cand_at[i + 1]]`
    /// (the root's: the origin only).
    cand_at: Vec<u32>,
    cands: Vec<[i32; 3]>,
    /// Node `n`'s table is `best[best_at[i]..best_at[i + 1]]`; its entry
    /// `ip·|C(n)| + in` is the least cost below `n` given its parent's
    /// candidate `ip` and its own `in`. Costs are in bits; `f32` keeps
    /// a fraction of a bit, as each table is stored less its minimum.
    best_at: Vec<u32>,
    best: Vec<f32>,
}

impl<'m> Program<'m> {
    fn new(skeleton: &Skeleton, targets: &[DVec3], model: &'m CostModel) -> Self {
        let mut cand_at = Vec::with_capacity(skeleton.len() + 1);
        let mut cands = Vec::with_capacity(skeleton.len() * 3);
        // At most 8 candidates and 64 table entries per node: within `u32`
        // for the encoder's 2^22 nodes.
        for n in skeleton.ids() {
            cand_at.push(cands.len() as u32);
            match n {
                NodeId::ROOT => cands.push([0; 3]),
                _ => push_candidates(&mut cands, targets[n.index()]),
            }
        }
        cand_at.push(cands.len() as u32);
        let count = |i: usize| (cand_at[i + 1] - cand_at[i]) as usize;
        let mut best_at = Vec::with_capacity(skeleton.len() + 1);
        let mut len = 0;
        for n in skeleton.ids() {
            best_at.push(len as u32);
            len += skeleton.parent(n).map_or(1, |p| count(p.index())) * count(n.index());
        }
        best_at.push(len as u32);
        Self {
            model,
            cand_at,
            cands,
            best_at,
            best: vec![0.0; len],
        }
    }

    fn cands(&self, n: NodeId) -> &[[i32; 3]] {
        &self.cands[self.cand_at[n.index()] as usize..self.cand_at[n.index() + 1] as usize]
    }

    fn best(&self, n: NodeId) -> &[f32] {
        &self.best[self.best_at[n.index()] as usize..self.best_at[n.index() + 1] as usize]
    }
}

/// Appends every voxel whose centre is within `√3/2` of `x` (voxel units),
/// nearest first: at least one, as the nearest voxel always qualifies.
fn push_candidates(out: &mut Vec<[i32; 3]>, x: DVec3) {
    let r = x.round();
    let nearest = [r.x as i32, r.y as i32, r.z as i32];
    let reach = REACH_SQ.sqrt();
    let (lo, hi) = ((x - reach).ceil(), (x + reach).floor());
    out.push(nearest);
    for i in lo.x as i32..=hi.x as i32 {
        for j in lo.y as i32..=hi.y as i32 {
            for k in lo.z as i32..=hi.z as i32 {
                let c = DVec3::new(f64::from(i), f64::from(j), f64::from(k));
                if [i, j, k] != nearest && c.distance_squared(x) <= REACH_SQ {
                    out.push([i, j, k]);
                }
            }
        }
    }
}

/// Voxels for every node (by index) that code the corrections in fewer
/// bits than `start` does, as the interpolative coder's cost of `start`'s
/// streams estimates them. Each voxel lies within `√3/2` of its target
/// `targets[i]` (voxel units from the root; the root stays at the origin).
/// `order` lists parents before children (the encode order).
pub(super) fn plan(
    skeleton: &Skeleton,
    targets: &[DVec3],
    order: &[NodeId],
    prediction: Prediction,
    start: &[[i32; 3]],
) -> Vec<[i32; 3]> {
    let tree = TreeView::new(skeleton, prediction);
    let model = CostModel::of(&tree, start);
    let mut program = Program::new(skeleton, targets, &model);
    let mut table = Vec::new();
    for &n in order.iter().rev() {
        least_below(&tree, &program, n, &mut table);
        // Less its minimum: the same choices, and small values in `f32`.
        let least = table.iter().copied().fold(f32::INFINITY, f32::min);
        table.iter_mut().for_each(|cost| *cost -= least);
        let at = program.best_at[n.index()] as usize;
        program.best[at..at + table.len()].copy_from_slice(&table);
    }
    read_back(&tree, &program, order)
}

/// Node `n`'s table from its children's, into `table`.
fn least_below(tree: &TreeView<'_>, program: &Program<'_>, n: NodeId, table: &mut Vec<f32>) {
    let skeleton = tree.skeleton;
    let parent_cands: &[[i32; 3]] = match skeleton.parent(n) {
        Some(p) => program.cands(p),
        None => &[[0; 3]],
    };
    let own = program.cands(n);
    table.clear();
    table.resize(parent_cands.len() * own.len(), 0.0);
    for &c in skeleton.children(n) {
        let n_c = program.cands(c).len();
        for (in_, &v_n) in own.iter().enumerate() {
            let least = |v_p: [i32; 3]| {
                let from = tree.predicted(c, v_n, v_p);
                (0..n_c)
                    .map(|ic| tree.step_cost(program, c, in_, ic, from))
                    .fold(f32::INFINITY, f32::min)
            };
            match tree.kinds[c.index()] {
                // A lateral's cost does not depend on the grandparent's voxel.
                Kind::BranchFirst => {
                    let cost = least(v_n);
                    for ip in 0..parent_cands.len() {
                        table[ip * own.len() + in_] += cost;
                    }
                }
                Kind::Continuation => {
                    for (ip, &v_p) in parent_cands.iter().enumerate() {
                        table[ip * own.len() + in_] += least(v_p);
                    }
                }
            }
        }
    }
}

/// The chosen voxels, read from the root down.
fn read_back(tree: &TreeView<'_>, program: &Program<'_>, order: &[NodeId]) -> Vec<[i32; 3]> {
    let skeleton = tree.skeleton;
    let mut chosen = vec![0u8; skeleton.len()];
    let mut voxels = vec![[0i32; 3]; skeleton.len()];
    for &c in &order[1..] {
        let n = skeleton.parent(c).expect("only the root lacks a parent");
        let grand = skeleton.parent(n).unwrap_or(n);
        let (in_, v_n, v_p) = (
            usize::from(chosen[n.index()]),
            voxels[n.index()],
            voxels[grand.index()],
        );
        let cands = program.cands(c);
        let from = tree.predicted(c, v_n, v_p);
        let ic = (0..cands.len())
            .map(|ic| (tree.step_cost(program, c, in_, ic, from), ic))
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
            .map_or(0, |(_, ic)| ic);
        // At most 8 candidates (two per axis).
        chosen[c.index()] = ic as u8;
        voxels[c.index()] = cands[ic];
    }
    voxels
}

#[inline]
fn sub(a: [i32; 3], b: [i32; 3]) -> [i32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
