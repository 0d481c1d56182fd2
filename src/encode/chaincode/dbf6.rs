//! DBF6 encoding and decoding (chain-code paper §3.1, Pseudocode 1).
//!
//! The grammar (see `docs/chaincode.md` for the full statement):
//! - decoding starts at the root, voxel `(0,0,0)`, at the start of a branch;
//! - moves 0–5 add unit steps to the current internode's *correction*;
//! - 6, 7 or 8 ends the internode: its voxel step is the correction plus the
//!   previous internode's step on the same branch (nothing at a branch start),
//!   and a node is created at the new voxel with the next radius;
//! - 6 also enqueues a lateral at that node; a 6 read where a fork symbol was
//!   just read (or at the very start, at the root) and no move has been read
//!   since is a zero-length internode: it only enqueues one more lateral at
//!   the same node;
//! - 7 ends the branch and resumes at the oldest queued lateral, whose first
//!   internode is coded in full; the code ends with the 7 that finds the
//!   queue empty.
//!
//! The one ambiguity, an internode with a zero correction that itself ends in
//! a fork right where a zero-length internode could stand, is removed by the
//! encoder writing its correction as the cancelling pair `0 3`.

use std::collections::VecDeque;

use glam::DVec3;

use super::plan;
use super::radii::quantise;
use super::split;
use super::{
    ChainCode, ChainError, ChainHeader, ChainOptions, END, FORK, Limits, MOVE_NEG_X, MOVE_POS_X,
    Prediction, Resolution, TIP, Voxelisation,
};
use crate::skeleton::{Node, NodeId, Skeleton};

/// Largest voxel coordinate the encoder produces; steps and corrections stay
/// far inside `i32`.
const MAX_VOXEL: f64 = (1u32 << 28) as f64;

/// Unit step of each move symbol.
const MOVES: [[i32; 3]; 6] = [
    [1, 0, 0],
    [0, 1, 0],
    [0, 0, 1],
    [-1, 0, 0],
    [0, -1, 0],
    [0, 0, -1],
];

/// Encodes a skeleton (Pseudocode 1). Children order is kept as it is: the
/// first child of every node is its main extension (see
/// [`Skeleton::order_main_extension_first`]).
///
/// With `opts.prediction` unset, encodes with every [`Prediction`] weight
/// and keeps the code whose corrections compress shortest (kind 3's
/// correction streams, the only part the prediction changes; the paper's
/// differential prediction on a tie). With [`Voxelisation::Optimised`],
/// the voxels of the best of those are then planned for the whole tree
/// (`plan.rs`), and the planned code is kept where its whole compressed
/// stream is shorter.
///
/// The result holds at most `Limits::default()` symbols and nodes, so that
/// every code this function produces can be read back with default limits.
pub fn encode(skeleton: &Skeleton, opts: &ChainOptions) -> Result<ChainCode, ChainError> {
    let frame = Frame::new(skeleton, opts)?;
    let greedy = match opts.voxelisation {
        Voxelisation::Nearest => Voxelisation::Nearest,
        Voxelisation::Predictive | Voxelisation::Optimised => Voxelisation::Predictive,
    };
    let single = opts.prediction.map(|p| [p]);
    let predictions: &[Prediction] = match &single {
        Some(one) => one,
        None => &Prediction::ALL,
    };
    let mut best = Shortest::default();
    for &prediction in predictions {
        let voxels = greedy_voxels(skeleton, &frame, prediction, greedy);
        best.offer(emit(skeleton, &frame, prediction, &voxels), voxels);
    }
    let plan_it = opts.voxelisation == Voxelisation::Optimised && skeleton.len() <= PLAN_MAX_NODES;
    let Some((greedy_code, start)) = best.code_and_voxels().filter(|_| plan_it) else {
        return best.into_result();
    };
    // One round: a second, from the planned code, saved at most one byte
    // per tree on the four real clouds at r = 3, 5 and 10
    // (`examples/voxel_choice.rs`) and took as long as the first.
    let prediction = greedy_code.header.prediction;
    let voxels = plan::plan(skeleton, &frame.targets, &frame.order, prediction, start);
    match emit(skeleton, &frame, prediction, &voxels) {
        Ok(planned) if shorter(&planned, greedy_code) => Ok(planned),
        _ => best.into_result(),
    }
}

/// Whether `planned` compresses shorter than `greedy`. Small skeletons
/// compare whole compressed streams: there the single-string form (kind 1)
/// can win, and fewer correction bits once made it a byte longer. Larger
/// ones compare the parts of kind 3 the voxels change, which costs no
/// compression (two would add 4–5 ms to a tree of 2,000 internodes).
fn shorter(planned: &ChainCode, greedy: &ChainCode) -> bool {
    if planned.radii_q.len() <= EXACT_MAX_NODES {
        return planned.compress().len() < greedy.compress().len();
    }
    let bits = |code: &ChainCode| code.voxel_dependent_bits().unwrap_or(u64::MAX);
    bits(planned) < bits(greedy)
}

/// Largest skeleton whose planned code is compared with its greedy one by
/// whole compressed length.
const EXACT_MAX_NODES: usize = 1024;

/// Largest skeleton whose voxels are planned; larger ones keep the greedy
/// choice. The plan's tables take at most 8 candidates of 12 bytes, 64
/// costs of 4 bytes and two 4-byte offsets per node: under 400 MB here.
const PLAN_MAX_NODES: usize = 1 << 20;

/// The code whose corrections compress shortest among those offered, and
/// the first error if none could be made.
#[derive(Default)]
struct Shortest {
    best: Option<(u64, ChainCode, Vec<[i32; 3]>)>,
    first_error: Option<ChainError>,
}

impl Shortest {
    /// Keeps `code` if its corrections compress shorter than the best's;
    /// ties keep the earlier one.
    fn offer(&mut self, code: Result<ChainCode, ChainError>, voxels: Vec<[i32; 3]>) {
        match code {
            Ok(code) => {
                let bits = split::correction_bits(&code).unwrap_or(u64::MAX);
                if self.best.as_ref().is_none_or(|(fewest, ..)| bits < *fewest) {
                    self.best = Some((bits, code, voxels));
                }
            }
            Err(e) => {
                self.first_error.get_or_insert(e);
            }
        }
    }

    fn code_and_voxels(&self) -> Option<(&ChainCode, &[[i32; 3]])> {
        self.best
            .as_ref()
            .map(|(_, code, voxels)| (code, voxels.as_slice()))
    }

    fn into_result(self) -> Result<ChainCode, ChainError> {
        match (self.best, self.first_error) {
            (Some((_, code, _)), _) => Ok(code),
            (None, Some(e)) => Err(e),
            (None, None) => unreachable!("at least one prediction is tried"),
        }
    }
}

/// What every encoding of one skeleton shares: the radius step, the voxel
/// size, the node positions in voxel units from the root and the encode
/// order.
struct Frame {
    radius_step_m: f32,
    voxel_size_m: f64,
    resolution: Resolution,
    targets: Vec<DVec3>,
    order: Vec<NodeId>,
}

impl Frame {
    fn new(skeleton: &Skeleton, opts: &ChainOptions) -> Result<Self, ChainError> {
        let radius_step_m = checked_radius_step(skeleton, opts)?;
        let voxel_size_m = voxel_size(skeleton, opts.resolution)?;
        Ok(Self {
            radius_step_m,
            voxel_size_m,
            resolution: opts.resolution,
            targets: scaled_positions(skeleton, voxel_size_m)?,
            order: encode_order(skeleton),
        })
    }
}

/// The voxel that `node`'s correction is taken from
/// ([`plan::Kind::predicted`]).
fn predicted_voxel(
    skeleton: &Skeleton,
    node: NodeId,
    voxels: &[[i32; 3]],
    prediction: Prediction,
) -> [i32; 3] {
    let parent = skeleton.parent(node).expect("only the root lacks a parent");
    let grand = skeleton.parent(parent).unwrap_or(parent);
    plan::Kind::of(skeleton, node).predicted(
        prediction,
        voxels[parent.index()],
        voxels[grand.index()],
    )
}

/// Every node's voxel chosen one at a time, parents first
/// ([`Voxelisation::Nearest`] or [`Voxelisation::Predictive`]).
fn greedy_voxels(
    skeleton: &Skeleton,
    frame: &Frame,
    prediction: Prediction,
    mode: Voxelisation,
) -> Vec<[i32; 3]> {
    let mut voxels = vec![[0i32; 3]; skeleton.len()];
    for &node in &frame.order[1..] {
        let predicted = predicted_voxel(skeleton, node, &voxels, prediction);
        voxels[node.index()] = choose_voxel(frame.targets[node.index()], predicted, mode);
    }
    voxels
}

/// The code of `voxels` (one per node, by index) under `prediction`.
fn emit(
    skeleton: &Skeleton,
    frame: &Frame,
    prediction: Prediction,
    voxels: &[[i32; 3]],
) -> Result<ChainCode, ChainError> {
    let limits = Limits::default();
    let step = frame.radius_step_m;
    let mut symbols = Vec::new();
    let mut radii_q = Vec::with_capacity(frame.order.len());
    radii_q.push(quantise(skeleton.radius(NodeId::ROOT), step)?);
    let root_kids = skeleton.children(NodeId::ROOT).len();
    symbols.extend(std::iter::repeat_n(FORK, root_kids.saturating_sub(1)));
    for &node in &frame.order[1..] {
        let parent = skeleton.parent(node).expect("only the root lacks a parent");
        let is_main = skeleton.children(parent)[0] == node;
        let correction = sub(
            voxels[node.index()],
            predicted_voxel(skeleton, node, voxels, prediction),
        );
        let moves: u32 = correction.iter().map(|c| c.unsigned_abs()).sum();
        let needed = symbols.len() + moves as usize + skeleton.children(node).len() + 2;
        if needed > limits.max_symbols {
            return Err(ChainError::TooManySymbols {
                found: needed,
                limit: limits.max_symbols,
            });
        }
        push_moves(&mut symbols, correction);
        let after_fork = is_main && (parent == NodeId::ROOT || skeleton.is_fork(parent));
        push_terminator(
            &mut symbols,
            moves,
            after_fork,
            skeleton.children(node).len(),
        );
        radii_q.push(quantise(skeleton.radius(node), step)?);
    }
    Ok(ChainCode {
        header: ChainHeader {
            voxel_size_m: frame.voxel_size_m,
            resolution: match frame.resolution {
                Resolution::PerInternode(r) => Some(r),
                Resolution::VoxelSize(_) => None,
            },
            radius_step_m: step,
            anchor: skeleton.anchor().clone(),
            root_position: skeleton.position(NodeId::ROOT),
            prediction,
        },
        symbols,
        radii_q,
    })
}

/// The radius step of `opts`, once it and the skeleton's size are known to
/// be encodable (at most `Limits::default()` nodes).
fn checked_radius_step(skeleton: &Skeleton, opts: &ChainOptions) -> Result<f32, ChainError> {
    let step = opts.radius_step_m;
    if !(step.is_finite() && step > 0.0) {
        return Err(ChainError::InvalidOptions("radius step must be positive"));
    }
    let limits = Limits::default();
    if skeleton.len() > limits.max_nodes {
        return Err(ChainError::TooManyNodes {
            found: skeleton.len(),
            limit: limits.max_nodes,
        });
    }
    Ok(step)
}

/// The end of an internode of `moves` moves whose node has `kids` children
/// (docs/chaincode.md §4): 7 at a tip, 8 on a chain, `kids − 1` times 6 at
/// a fork. A main extension of a fork (or the root's first child) with a
/// zero correction that forks again writes the cancelling pair `0 3` first:
/// its 6s would otherwise read as more children of the fork before it.
fn push_terminator(symbols: &mut Vec<u8>, moves: u32, after_fork: bool, kids: usize) {
    if moves == 0 && after_fork && kids >= 2 {
        symbols.extend([MOVE_POS_X, MOVE_NEG_X]);
    }
    match kids {
        0 => symbols.push(TIP),
        1 => symbols.push(END),
        k => symbols.extend(std::iter::repeat_n(FORK, k - 1)),
    }
}

/// The original node ids in the order [`decode`] creates them: decoded node
/// `i` is `encode_order(s)[i]`. Branch by branch: the trunk from the root
/// along main extensions, then each lateral branch in the order its fork was
/// passed.
pub fn encode_order(skeleton: &Skeleton) -> Vec<NodeId> {
    let mut order = Vec::with_capacity(skeleton.len());
    let mut queue = VecDeque::new();
    let mut cur = NodeId::ROOT;
    order.push(cur);
    loop {
        let kids = skeleton.children(cur);
        if kids.len() > 1 {
            queue.extend(&kids[1..]);
        }
        let next = match kids.first() {
            Some(&main) => main,
            None => match queue.pop_front() {
                Some(lateral) => lateral,
                None => return order,
            },
        };
        order.push(next);
        cur = next;
    }
}

/// Decodes a chain code into a skeleton whose node `i` is the original node
/// `encode_order(s)[i]`, within `√3·d/2` of it.
///
/// Fails only if the coordinates leave the `i32` voxel or `f32` metre range.
/// The loop still checks the grammar itself (the tests feed it raw streams),
/// and its work is linear in the number of symbols.
pub fn decode(code: &ChainCode) -> Result<Skeleton, ChainError> {
    code.header.validate()?;
    let mut turtle = Turtle::new(&code.header, &code.radii_q, code.symbols.len())?;
    // The current internode's net moves and whether it has any. They stay
    // out of `Turtle` so that the loop over the moves, most of the symbols,
    // keeps them in registers (decoding took 5 % longer with them inside).
    let mut correction = [0i32; 3];
    let mut has_moves = false;
    for (pos, &s) in code.symbols.iter().enumerate() {
        if s < FORK {
            for (c, d) in correction.iter_mut().zip(MOVES[usize::from(s)]) {
                *c = c.wrapping_add(d);
            }
            has_moves = true;
            continue;
        }
        turtle.read_terminator(pos, s, correction, has_moves)?;
        correction = [0; 3];
        has_moves = false;
    }
    turtle.finish()
}

/// Decodes a code given as its internodes' terminators (what the
/// split-stream forms store) instead of its symbols: the same turtle as
/// [`decode`] without a pass over the move symbols.
pub(crate) fn decode_terminators(
    header: &ChainHeader,
    radii_q: &[u32],
    n_symbols: usize,
    terminators: &[Terminator],
) -> Result<Skeleton, ChainError> {
    header.validate()?;
    let mut turtle = Turtle::new(header, radii_q, n_symbols)?;
    for t in terminators {
        turtle.read_terminator(t.pos, t.symbol, t.correction, t.has_moves)?;
    }
    turtle.finish()
}

/// One internode as its terminator sees it: the fork, tip or end `symbol`
/// at position `pos` of the code, after moves whose net sum is `correction`
/// (`has_moves`: whether there were any; `0 3` has moves and sums to zero).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Terminator {
    pub(crate) pos: usize,
    pub(crate) symbol: u8,
    pub(crate) correction: [i32; 3],
    pub(crate) has_moves: bool,
}

/// The decoder's state machine (`docs/chaincode.md` §4) between
/// internodes: where it stands, on which branch, and the queued laterals.
struct Turtle<'a> {
    header: &'a ChainHeader,
    /// Length of the code in symbols.
    n_symbols: usize,
    /// One radius per node in decoding order.
    radii: &'a [u32],
    /// Root position relative to the anchor, voxel size and radius step,
    /// in `f64` (each node is placed from them in one rounding).
    root: DVec3,
    voxel_size_m: f64,
    radius_step_m: f64,
    nodes: Vec<Node>,
    /// Laterals still to decode: fork node and its voxel, oldest first.
    queue: VecDeque<(u32, [i32; 3])>,
    /// Current node and its voxel.
    node: u32,
    voxel: [i32; 3],
    /// The previous internode's step on this branch; zero at a branch start.
    history: [i32; 3],
    /// How the next step is predicted from `history`.
    prediction: Prediction,
    /// A 6 read now (without moves) is a zero-length fork internode.
    markers_allowed: bool,
    /// The 7 that found the queue empty was read.
    finished: bool,
}

impl<'a> Turtle<'a> {
    /// At the root, voxel `(0,0,0)`, which takes the first radius.
    fn new(
        header: &'a ChainHeader,
        radii: &'a [u32],
        n_symbols: usize,
    ) -> Result<Self, ChainError> {
        let Some(&root_q) = radii.first() else {
            return Err(ChainError::RadiiCount { nodes: 1, radii: 0 });
        };
        let mut turtle = Turtle {
            header,
            n_symbols,
            radii,
            root: header.root_position.as_dvec3(),
            voxel_size_m: header.voxel_size_m,
            radius_step_m: f64::from(header.radius_step_m),
            nodes: Vec::with_capacity(radii.len().min(n_symbols + 1)),
            queue: VecDeque::new(),
            node: 0,
            voxel: [0; 3],
            history: [0; 3],
            prediction: header.prediction,
            markers_allowed: true,
            finished: n_symbols == 0,
        };
        let radius_m = turtle.radius_m(root_q);
        turtle.nodes.push(Node {
            position: header.root_position,
            radius_m,
            parent: None,
        });
        Ok(turtle)
    }

    /// Reads the fork, tip or end symbol `s` at position `pos`, after the
    /// moves of the current internode (their net `correction`; `has_moves`
    /// whether there were any).
    #[inline(always)]
    fn read_terminator(
        &mut self,
        pos: usize,
        s: u8,
        correction: [i32; 3],
        has_moves: bool,
    ) -> Result<(), ChainError> {
        match s {
            FORK if self.markers_allowed && !has_moves => {
                self.queue.push_back((self.node, self.voxel));
            }
            FORK | TIP | END => {
                self.end_internode(pos, s, correction)?;
                if s == TIP {
                    self.resume(pos)?;
                }
            }
            _ => {
                return Err(ChainError::InvalidSymbol {
                    position: pos,
                    symbol: s,
                });
            }
        }
        Ok(())
    }

    /// Ends the current internode with terminator `s`: a new node at the
    /// predicted voxel plus `correction`, with the next radius.
    #[inline(always)]
    fn end_internode(&mut self, pos: usize, s: u8, correction: [i32; 3]) -> Result<(), ChainError> {
        let overflow = ChainError::CoordinateOverflow { position: pos };
        let predicted = self.prediction.step(self.history);
        let step = add(predicted, correction).ok_or(overflow.clone())?;
        let voxel = add(self.voxel, step).ok_or(overflow)?;
        let idx = self.nodes.len();
        let Some(&q) = self.radii.get(idx) else {
            return Err(ChainError::RadiiCount {
                nodes: idx + 1,
                radii: self.radii.len(),
            });
        };
        self.nodes.push(Node {
            position: self.place(voxel),
            radius_m: self.radius_m(q),
            parent: Some(NodeId::from_index(self.node as usize)),
        });
        self.node = idx as u32;
        self.voxel = voxel;
        self.history = step;
        self.markers_allowed = s == FORK;
        if s == FORK {
            self.queue.push_back((self.node, self.voxel));
        }
        Ok(())
    }

    /// After a tip: resume at the oldest queued lateral, whose first
    /// internode is coded in full, or end the code if none is left.
    fn resume(&mut self, pos: usize) -> Result<(), ChainError> {
        match self.queue.pop_front() {
            Some((fork, fork_voxel)) => {
                self.node = fork;
                self.voxel = fork_voxel;
                self.history = [0; 3];
            }
            None => {
                let left = self.n_symbols - pos - 1;
                if left > 0 {
                    return Err(ChainError::TrailingSymbols { count: left });
                }
                self.finished = true;
            }
        }
        Ok(())
    }

    /// The skeleton, once the whole stream was read.
    fn finish(self) -> Result<Skeleton, ChainError> {
        if !self.finished {
            return Err(ChainError::Unterminated {
                queued: self.queue.len(),
            });
        }
        let radii = self.radii.len();
        if self.nodes.len() != radii {
            return Err(ChainError::RadiiCount {
                nodes: self.nodes.len(),
                radii,
            });
        }
        Ok(Skeleton::from_nodes(
            self.header.anchor.clone(),
            self.nodes,
        )?)
    }

    fn radius_m(&self, q: u32) -> f32 {
        (f64::from(q) * self.radius_step_m) as f32
    }

    /// A voxel's centre relative to the anchor, rounded once to `f32`.
    fn place(&self, v: [i32; 3]) -> glam::Vec3 {
        let v = DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2]));
        (self.root + v * self.voxel_size_m).as_vec3()
    }
}

/// Voxel size in metres for the chosen resolution (Eq. 2 with the mean
/// internode length; 1 m stands in when no internode has positive length).
fn voxel_size(skeleton: &Skeleton, resolution: Resolution) -> Result<f64, ChainError> {
    let d = match resolution {
        Resolution::VoxelSize(d) => d,
        Resolution::PerInternode(r) => {
            if !(r.is_finite() && r > 0.0) {
                return Err(ChainError::InvalidOptions("resolution must be positive"));
            }
            let (sum, count) = skeleton
                .ids()
                .map(|id| f64::from(skeleton.internode_length(id)))
                .filter(|&l| l > 0.0)
                .fold((0.0, 0u64), |(s, c), l| (s + l, c + 1));
            let mean = if count == 0 { 1.0 } else { sum / count as f64 };
            mean / f64::from(r)
        }
    };
    if d.is_finite() && d > 0.0 {
        Ok(d)
    } else {
        Err(ChainError::InvalidOptions("voxel size must be positive"))
    }
}

/// Node positions relative to the root in voxel units, checked to stay
/// within ±2^28 voxels.
fn scaled_positions(skeleton: &Skeleton, d: f64) -> Result<Vec<DVec3>, ChainError> {
    let root = skeleton.position(NodeId::ROOT).as_dvec3();
    skeleton
        .nodes()
        .iter()
        .map(|n| {
            let x = (n.position.as_dvec3() - root) / d;
            if x.abs().max_element() > MAX_VOXEL {
                return Err(ChainError::TooFine { voxel_size_m: d });
            }
            Ok(x)
        })
        .collect()
}

/// The voxel for a node at `x` (voxel units from the root), given the voxel
/// the differential prediction points at.
fn choose_voxel(x: DVec3, predicted: [i32; 3], mode: Voxelisation) -> [i32; 3] {
    // Eq. 1, rtz(x + sgn(x)/2): rounding half away from zero, so voxel
    // (0,0,0) is centred on the root. Its centre is within √3/2 of x.
    let r = x.round();
    let nearest = [r.x as i32, r.y as i32, r.z as i32];
    if mode == Voxelisation::Nearest {
        return nearest;
    }
    let cost = |v: [i32; 3]| {
        let moves: u32 = sub(v, predicted).iter().map(|c| c.unsigned_abs()).sum();
        let c = DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2]));
        (moves, c.distance_squared(x))
    };
    // Every voxel whose centre is within √3/2 of x: at most two per axis.
    let reach = 3f64.sqrt() / 2.0;
    let lo = (x - reach).ceil();
    let hi = (x + reach).floor();
    let mut best = (nearest, cost(nearest));
    for i in lo.x as i32..=hi.x as i32 {
        for j in lo.y as i32..=hi.y as i32 {
            for k in lo.z as i32..=hi.z as i32 {
                let v = [i, j, k];
                let c = cost(v);
                if c.1 <= plan::REACH_SQ && c < best.1 {
                    best = (v, c);
                }
            }
        }
    }
    best.0
}

/// Appends the moves of a correction, clustered by axis (x, then y, then z)
/// as the paper suggests for compressibility.
fn push_moves(symbols: &mut Vec<u8>, c: [i32; 3]) {
    for (axis, &v) in c.iter().enumerate() {
        let sym = if v >= 0 { axis as u8 } else { axis as u8 + 3 };
        symbols.extend(std::iter::repeat_n(sym, v.unsigned_abs() as usize));
    }
}

fn sub(a: [i32; 3], b: [i32; 3]) -> [i32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline]
fn add(a: [i32; 3], b: [i32; 3]) -> Option<[i32; 3]> {
    Some([
        a[0].checked_add(b[0])?,
        a[1].checked_add(b[1])?,
        a[2].checked_add(b[2])?,
    ])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::Anchor;
    use glam::Vec3;

    fn decoded_position(code: &ChainCode, v: [i32; 3]) -> Vec3 {
        let d = code.header.voxel_size_m;
        (code.header.root_position.as_dvec3()
            + DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2])) * d)
            .as_vec3()
    }

    /// The planar tree of the paper's Figs. 4 and 6 (unit voxels, x right,
    /// y up).
    fn paper_tree() -> Skeleton {
        let p = |x: f32, y: f32| Vec3::new(x, y, 0.0);
        let mut s = Skeleton::new(Anchor::default(), 0.010);
        let n1 = s.add_child(NodeId::ROOT, p(0.0, 3.0), 0.009);
        let n2 = s.add_child(n1, p(0.0, 6.0), 0.008);
        let n3 = s.add_child(n2, p(-1.0, 8.0), 0.006);
        s.add_child(n3, p(-2.0, 11.0), 0.004);
        let l1 = s.add_child(n2, p(2.0, 8.0), 0.004);
        s.add_child(n3, p(-4.0, 8.0), 0.002);
        s.add_child(l1, p(3.0, 10.0), 0.003);
        s.add_child(l1, p(5.0, 7.0), 0.001);
        s
    }

    fn as_text(symbols: &[u8]) -> String {
        symbols.iter().map(|s| char::from(b'0' + s)).collect()
    }

    #[test]
    fn reproduces_the_papers_differential_code() {
        let opts = ChainOptions {
            resolution: Resolution::VoxelSize(1.0),
            prediction: Some(Prediction::DIFFERENTIAL),
            ..ChainOptions::default()
        };
        let code = encode(&paper_tree(), &opts).unwrap();
        // Fig. 6 of the paper.
        assert_eq!(as_text(&code.symbols), "11186346170011637333700047");
        assert_eq!(code.radii_q, vec![10, 9, 8, 6, 4, 4, 3, 2, 1]);
        let back = decode(&code).unwrap();
        assert_eq!(back.len(), 9);
        let order = encode_order(&paper_tree());
        for (i, &orig) in order.iter().enumerate() {
            let id = NodeId::from_index(i);
            assert_eq!(back.position(id), paper_tree().position(orig));
        }
    }

    #[test]
    fn multi_way_fork_with_zero_correction_main_extension() {
        // Root trifurcates; the main extension continues straight and then
        // forks again, so it needs the cancelling pair.
        let mut s = Skeleton::new(Anchor::default(), 0.1);
        let a = s.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 1.0), 0.1);
        let b = s.add_child(a, Vec3::new(0.0, 0.0, 2.0), 0.1);
        s.add_child(a, Vec3::new(1.0, 0.0, 1.0), 0.1);
        s.add_child(a, Vec3::new(-1.0, 0.0, 1.0), 0.1);
        let c = s.add_child(b, Vec3::new(0.0, 0.0, 3.0), 0.1);
        s.add_child(b, Vec3::new(0.0, 1.0, 2.0), 0.1);
        s.add_child(c, Vec3::new(0.0, 0.0, 3.0), 0.1);
        let opts = ChainOptions {
            resolution: Resolution::VoxelSize(1.0),
            ..ChainOptions::default()
        };
        let code = encode(&s, &opts).unwrap();
        assert_eq!(as_text(&code.symbols), "266036857073717");
        let back = decode(&code).unwrap();
        assert_eq!(back.len(), s.len());
        for (i, &orig) in encode_order(&s).iter().enumerate() {
            let id = NodeId::from_index(i);
            assert_eq!(back.position(id), s.position(orig));
            assert_eq!(
                back.parent(id).map(|p| encode_order(&s)[p.index()]),
                s.parent(orig)
            );
        }
    }

    #[test]
    fn single_node_and_bad_streams() {
        let s = Skeleton::new(Anchor::default(), 0.2);
        let code = encode(&s, &ChainOptions::default()).unwrap();
        assert!(code.symbols.is_empty());
        assert_eq!(decode(&code).unwrap().len(), 1);

        let mut bad = code.clone();
        bad.symbols = vec![2, 8];
        bad.radii_q = vec![1, 1];
        assert!(matches!(decode(&bad), Err(ChainError::Unterminated { .. })));
        bad.symbols = vec![2, 7, 2];
        assert!(matches!(
            decode(&bad),
            Err(ChainError::TrailingSymbols { count: 1 })
        ));
        bad.symbols = vec![9, 7];
        assert!(matches!(
            decode(&bad),
            Err(ChainError::InvalidSymbol { .. })
        ));
        bad.symbols = vec![2, 7];
        bad.radii_q = vec![1];
        assert!(matches!(decode(&bad), Err(ChainError::RadiiCount { .. })));
    }

    #[test]
    fn a_stream_that_leaves_the_voxel_range_is_refused_where_it_does() {
        // One +z move per internode: each step is one voxel longer than the
        // one it repeats, so the height after n internodes is n(n+1)/2 and
        // leaves i32 at internode 65,536.
        let n = 70_000;
        let mut code = encode(
            &Skeleton::new(Anchor::default(), 0.2),
            &ChainOptions::default(),
        )
        .unwrap();
        code.symbols = [2, END].repeat(n);
        code.symbols.push(TIP);
        code.radii_q = vec![1; n + 2];
        assert_eq!(
            decode(&code).unwrap_err(),
            ChainError::CoordinateOverflow {
                position: 2 * 65_535 + 1
            }
        );
    }

    #[test]
    fn voxel_rounding_is_half_away_from_zero() {
        let mut s = Skeleton::new(Anchor::default(), 0.1);
        s.add_child(NodeId::ROOT, Vec3::new(0.5, -0.5, 1.49), 0.1);
        let x = scaled_positions(&s, 1.0).unwrap();
        let v = choose_voxel(x[1], [0; 3], Voxelisation::Nearest);
        assert_eq!(v, [1, -1, 1]);
        let code = encode(
            &s,
            &ChainOptions {
                resolution: Resolution::VoxelSize(1.0),
                voxelisation: Voxelisation::Nearest,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(decoded_position(&code, v), Vec3::new(1.0, -1.0, 1.0));
        assert_eq!(
            decode(&code).unwrap().position(NodeId::from_index(1)),
            Vec3::new(1.0, -1.0, 1.0)
        );

        // The predictive choice may take another voxel within the bound.
        let v = choose_voxel(x[1], [0; 3], Voxelisation::Predictive);
        assert_eq!(v, [0, 0, 1]);
        let c = DVec3::new(0.0, 0.0, 1.0);
        assert!(c.distance(x[1]) <= 3f64.sqrt() / 2.0);
    }
}
