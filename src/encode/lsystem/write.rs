//! The closed-loop writer (lsystem-from-adtree-skeletons §3.2.3–3.2.5,
//! Algorithms 3.1–3.3, redone so that errors cannot build up).
//!
//! The paper computes each step from the *original* skeleton and rounds it,
//! so rounding errors add up along a branch (§4.4, Table 4.1). Here each step
//! is computed from the state the reader will have after decoding the
//! already-written, rounded steps: the writer runs the reader's own turtle
//! ([`TurtleState::apply`]) on the parsed values it prints. The step to a
//! node aims from the *decoded* parent position at the *original* node, so
//! the error of every node is only the rounding error of its own step, which
//! the writer checks before accepting it: `|decoded − original| ≤ tolerance`
//! for every node, whatever its depth.
//!
//! Each step is a turn, then a pitch `&`/`^` about the (turned) left axis,
//! then `F(l)`: both angles are taken in the turtle's own frame, which has
//! no pole. The turn is a roll `\`/`/` about the heading (on either side,
//! the pitch changing sign) or a yaw `+`/`-` about the up axis, whichever
//! prints shortest. Numbers are printed with the fewest decimals that keep
//! the node within tolerance, lengths in the document's unit (1 mm for a
//! 1 mm tolerance, so they print as integers): the writer tries the
//! combinations of coarser and finer roundings of turn, pitch and length,
//! cheapest first in JSON bytes, and keeps the first whose decoded position
//! is close enough. Zero angles are omitted and `!(w)` is written only when
//! the decoded width would otherwise leave the radius tolerance.

use std::ops::Range;

use glam::DVec3;

use super::decimal::{number_chars, rounding};
use super::format::{Dimensions, Symbol};
use super::generalise::TipPlan;
use super::turtle::{Effect, Turn, TurtleState, step_m};
use crate::skeleton::{NodeId, Skeleton};

/// Finest rounding tried before printing a number exactly.
const MAX_DECIMALS: usize = 12;
/// Dimensions the writer assumes while writing, with lengths in units of
/// `unit_m`; defaults are only filled in afterwards, for parameters that
/// already equal them.
pub(crate) fn write_dimensions(unit_m: f64) -> Dimensions {
    Dimensions {
        unit_m,
        forward: 1.0,
        rotation: 0.0,
        roll: 0.0,
    }
}

/// The length unit for a position tolerance: the largest power of ten not
/// above it (1 mm for 1 mm), so that lengths print as short integers;
/// between 1 µm and 1 m.
pub(crate) fn length_unit(tolerance_m: f64) -> f64 {
    let exponent = if tolerance_m > 0.0 {
        tolerance_m.log10().floor().clamp(-6.0, 0.0)
    } else {
        -6.0
    };
    format!("1e{exponent}")
        .parse()
        .expect("a power of ten parses")
}

/// Relative slack for the `f32` rounding of a decoded value of magnitude 1.
const F32_SLACK: f64 = 1.0 / (1u64 << 23) as f64;

/// The number with the fewest decimals within `half_width` of `value`, as
/// the reader will parse it; `value` itself when the interval is too narrow.
pub(crate) fn shortest_within(value: f64, half_width: f64) -> f64 {
    (0..=MAX_DECIMALS)
        .map(|k| rounding(value, k).value)
        .find(|v| (v - value).abs() <= half_width)
        .unwrap_or(value)
}

/// Bytes a symbol with a parameter of `chars` printed characters takes in
/// the JSON document: `c(value)`, and a backslash is escaped as `\\`.
fn json_cost(ch: u8, chars: usize) -> usize {
    chars + 3 + usize::from(ch == b'\\')
}

/// One way to print a quantity: the symbol (if any) and its cost in bytes.
#[derive(Clone, Copy)]
struct Choice {
    symbol: Option<Symbol>,
    cost: usize,
}

/// Roundings of a signed angle in degrees, coarse to fine, plus "omit",
/// into `out` (cleared first). Rounding stops once the error it would add
/// is below `fine_deg`.
fn angle_choices(
    angle_deg: f64,
    (positive, negative): (u8, u8),
    fine_deg: f64,
    out: &mut Vec<Choice>,
) {
    out.clear();
    out.push(Choice {
        symbol: None,
        cost: 0,
    });
    let mut last = 0.0;
    for k in 0..=MAX_DECIMALS {
        let rounded = rounding(angle_deg, k);
        let v = rounded.value;
        if v != 0.0 && v != last {
            let ch = if v > 0.0 { positive } else { negative };
            out.push(Choice {
                symbol: Some(Symbol::with(ch, v.abs())),
                cost: json_cost(ch, rounded.magnitude_chars),
            });
            last = v;
        }
        if (v - angle_deg).abs() <= fine_deg {
            return;
        }
    }
    let ch = if angle_deg > 0.0 { positive } else { negative };
    out.push(Choice {
        symbol: Some(Symbol::with(ch, angle_deg.abs())),
        cost: json_cost(ch, number_chars(angle_deg.abs())),
    });
}

/// Roundings of an internode length in length units, coarse to fine, into
/// `out` (cleared first).
fn length_choices(length: f64, fine: f64, out: &mut Vec<Choice>) {
    out.clear();
    let mut last = f64::NAN;
    for k in 0..=MAX_DECIMALS {
        let rounded = rounding(length, k);
        let v = rounded.value;
        if v != last {
            out.push(Choice {
                symbol: Some(Symbol::with(b'F', v)),
                cost: json_cost(b'F', rounded.chars),
            });
            last = v;
        }
        if (v - length).abs() <= fine {
            return;
        }
    }
    out.push(Choice {
        symbol: Some(Symbol::with(b'F', length)),
        cost: json_cost(b'F', number_chars(length)),
    });
}

/// Yaw (about `U`, positive left) and then pitch (about the yawed `L`,
/// positive down) in degrees that turn `turtle`'s heading onto `direction`
/// (unit). Unlike [`roll_pitch`] it leaves the frame unrolled, and a small
/// turn is two small angles.
fn yaw_pitch(turtle: &TurtleState, direction: DVec3) -> (f64, f64) {
    let h = direction.dot(turtle.heading);
    let l = direction.dot(turtle.left);
    let u = direction.dot(turtle.up);
    (l.atan2(h).to_degrees(), (-u).atan2(h.hypot(l)).to_degrees())
}

/// The choices of a first turn and of a pitch for each way to turn, in
/// buffers kept from one internode to the next.
#[derive(Default)]
struct Ways {
    /// Turn and pitch choices of each way; only the first `count` are in use.
    lists: [[Vec<Choice>; 2]; 3],
    count: usize,
}

impl Ways {
    /// The ways in use.
    fn as_slice(&self) -> &[[Vec<Choice>; 2]] {
        &self.lists[..self.count]
    }

    /// Starts a new way and returns its (empty) turn and pitch choices.
    fn push(&mut self) -> &mut [Vec<Choice>; 2] {
        let way = &mut self.lists[self.count];
        self.count += 1;
        way
    }

    /// One way that writes no turn and no pitch: the step of a
    /// zero-length internode needs none.
    fn set_straight(&mut self) {
        let none = Choice {
            symbol: None,
            cost: 0,
        };
        self.count = 0;
        for list in self.push() {
            list.clear();
            list.push(none);
        }
    }
}

/// The equivalent ways to turn the heading onto `direction` (unit) before a
/// step of `length_m`, each as roundings of a first turn and of a pitch:
/// roll then pitch with the roll within ±90°, the same with the roll on the
/// other side (a `/` instead of an escaped `\\`, or a shorter number), and
/// yaw then pitch. Roundings stop at an angle error that moves the node by
/// `fine_m`; favoured angles are tried up to an error that moves it by
/// `budget_m`.
fn turn_choices(
    turtle: &TurtleState,
    direction: DVec3,
    length_m: f64,
    (fine_m, budget_m): (f64, f64),
    favoured: &Favoured,
    ways: &mut Ways,
) {
    let to_deg = |distance_m: f64, lever_m: f64| (distance_m / lever_m.max(1e-300)).to_degrees();
    let angle = |value: f64, signs: (u8, u8), lever_m: f64, out: &mut Vec<Choice>| {
        angle_choices(value, signs, to_deg(fine_m, lever_m), out);
        favoured.add_near(value, signs, to_deg(budget_m, lever_m), out);
    };
    ways.count = 0;
    let (roll, pitch) = roll_pitch(turtle, direction, true);
    let roll_lever = length_m * pitch.to_radians().sin().abs();
    let mut roll_then_pitch = |roll: f64, pitch: f64| {
        let [turns, pitches] = ways.push();
        angle(roll, (b'\\', b'/'), roll_lever, turns);
        angle(pitch, (b'&', b'^'), length_m, pitches);
    };
    roll_then_pitch(roll, pitch);
    if roll != 0.0 {
        roll_then_pitch(roll - 180.0f64.copysign(roll), -pitch);
    }
    let (yaw, yaw_pitch) = yaw_pitch(turtle, direction);
    let [yaws, pitches] = ways.push();
    angle(yaw, (b'+', b'-'), length_m, yaws);
    angle(yaw_pitch, (b'&', b'^'), length_m, pitches);
}

/// Parameters that an earlier pass printed as one rule letter or omitted
/// as a default: the writer prefers them, at a cost of one byte, wherever
/// one keeps the node within its budget, so that they get more frequent
/// and the rules built afterwards pay more.
#[derive(Debug, Default)]
pub(crate) struct Favoured {
    /// For each pair of symbols a quantity is written with ([`SIGNS`]),
    /// the favoured symbols of either and their signed values, in the order
    /// of the rules and defaults they come from. Kept apart so that each
    /// quantity scans only its own symbols, not every rule's.
    by_signs: [Vec<(f64, Symbol)>; SIGNS.len()],
}

/// The symbols for positive and negative values of each quantity: roll,
/// pitch, yaw and length.
const SIGNS: [(u8, u8); 4] = [(b'\\', b'/'), (b'&', b'^'), (b'+', b'-'), (b'F', b'F')];

impl Favoured {
    /// The parametrised symbols of single-symbol rules, and the defaults of
    /// `dims`, from an encoding written with these rules and dimensions.
    pub(crate) fn from<'a>(
        rules: impl Iterator<Item = &'a Vec<Symbol>>,
        dims: &Dimensions,
    ) -> Self {
        let mut symbols: Vec<Symbol> = rules
            .filter_map(|body| match body.as_slice() {
                [s] if s.param.is_some() => Some(*s),
                _ => None,
            })
            .collect();
        symbols.push(Symbol::with(b'F', dims.forward));
        for ch in *b"&^+-" {
            symbols.push(Symbol::with(ch, dims.rotation));
        }
        symbols.extend([
            Symbol::with(b'\\', dims.roll),
            Symbol::with(b'/', dims.roll),
        ]);
        let by_signs = SIGNS.map(|(positive, negative)| {
            symbols
                .iter()
                .filter_map(|s| {
                    let p = s.param?;
                    match s.ch {
                        c if c == positive => Some((p, *s)),
                        c if c == negative => Some((-p, *s)),
                        _ => None,
                    }
                })
                .collect()
        });
        Favoured { by_signs }
    }

    /// Adds to `out` the favoured symbols for a quantity `value` written
    /// with `signs` (one of [`SIGNS`]: for positive, negative values),
    /// within `reach` of it.
    fn add_near(&self, value: f64, signs: (u8, u8), reach: f64, out: &mut Vec<Choice>) {
        let Some(i) = SIGNS.iter().position(|&s| s == signs) else {
            return;
        };
        for &(signed, symbol) in &self.by_signs[i] {
            if (signed - value).abs() <= reach {
                out.push(Choice {
                    symbol: Some(symbol),
                    cost: 1,
                });
            }
        }
    }
}

/// Roll (about `H`) and pitch (about the rolled `L`, positive down) in
/// degrees that turn `turtle`'s heading onto `direction` (unit). When
/// `signed_pitch`, the roll is kept within ±90° and the pitch takes a sign,
/// which keeps rolls small; otherwise the pitch is in [0°, 180°].
pub(crate) fn roll_pitch(turtle: &TurtleState, direction: DVec3, signed_pitch: bool) -> (f64, f64) {
    let h = direction.dot(turtle.heading);
    let l = direction.dot(turtle.left);
    let u = direction.dot(turtle.up);
    let side = l.hypot(u);
    if side < 1e-15 {
        return (0.0, if h < 0.0 { 180.0 } else { 0.0 });
    }
    let mut roll = l.atan2(-u).to_degrees();
    let mut pitch = side.atan2(h).to_degrees();
    if signed_pitch && roll.abs() > 90.0 {
        roll -= 180.0f64.copysign(roll);
        pitch = -pitch;
    }
    (roll, pitch)
}

/// Buffers the writer keeps from one internode to the next, so that
/// writing a node allocates nothing: with two passes over every node, the
/// allocator was a sixth of the writer's time.
#[derive(Default)]
pub(crate) struct Scratch {
    ways: Ways,
    lengths: Vec<Choice>,
    search: Search,
    trials: TrialCache,
}

/// Appends the cheapest symbols that move `turtle` from its state to within
/// `budget_m` of `target`, drawing a node, and applies them to `turtle`.
/// Returns the decoded position error of the new node.
pub(crate) fn write_internode(
    turtle: &mut TurtleState,
    target: DVec3,
    budget_m: f64,
    (dims, favoured): (&Dimensions, &Favoured),
    scratch: &mut Scratch,
    out: &mut Vec<Symbol>,
) -> f64 {
    let Scratch {
        ways,
        lengths,
        search,
        trials: cache,
    } = scratch;
    let offset = target - turtle.position;
    let length = offset.length();
    let budget = budget_m.max(0.0);
    // A rounding whose own error is this small counts as exact.
    let fine_m = budget * 1e-2;
    if length > 0.0 {
        turn_choices(
            turtle,
            offset / length,
            length,
            (fine_m, budget),
            favoured,
            ways,
        );
    } else {
        ways.set_straight();
    }
    length_choices(length / dims.unit_m, fine_m / dims.unit_m, lengths);
    favoured.add_near(
        length / dims.unit_m,
        (b'F', b'F'),
        budget / dims.unit_m,
        lengths,
    );
    let turns = ways.as_slice();
    search.fill(turns, lengths);
    let mut trials = Trials::new(turtle, turns, lengths, search.triples.len(), dims, cache);
    let chosen = search
        .find(|c| trials.error(c, target) <= budget)
        // The finest roundings are nearly exact; should even they miss
        // (a tolerance of 0), the last, finest combination is the best.
        .unwrap_or_else(|| search.last());
    let error = trials.error(&chosen, target);
    let state = trials.state(&chosen);
    out.extend(chosen.symbols(turns, lengths));
    *turtle = state;
    error
}

/// The decoded states of the combinations the search tries. Many share a
/// turn, or a turn and a pitch: each rotation and each turned state is
/// computed once, by the reader's own operations ([`Turn`],
/// [`TurtleState::turn`]), so every state is bit for bit the one the
/// reader will have.
struct Trials<'a> {
    start: &'a TurtleState,
    turns: &'a [[Vec<Choice>; 2]],
    dims: &'a Dimensions,
    cache: &'a mut TrialCache,
}

/// What [`Trials`] has computed so far for one internode, in buffers kept
/// for the next.
#[derive(Default)]
struct TrialCache {
    /// Step of each length choice, metres (`None` for no `F`).
    steps: Vec<Option<f64>>,
    /// First index of each way's turns, and of its pitches, in the caches.
    first: Vec<[usize; 2]>,
    /// State after each way's turn choices.
    turned: Vec<Option<TurtleState>>,
    /// Rotation of each way's pitch choices.
    pitches: Vec<Option<Option<Turn>>>,
    /// Heading after each (way, turn, pitch) triple. Turns do not move the
    /// turtle, so the heading is all a trial needs of the turned state.
    headings: Vec<Option<DVec3>>,
}

impl<'a> Trials<'a> {
    fn new(
        start: &'a TurtleState,
        turns: &'a [[Vec<Choice>; 2]],
        lengths: &[Choice],
        triples: usize,
        dims: &'a Dimensions,
        cache: &'a mut TrialCache,
    ) -> Self {
        cache.first.clear();
        let (mut turn_count, mut pitch_count) = (0, 0);
        for [turn, pitches] in turns {
            cache.first.push([turn_count, pitch_count]);
            turn_count += turn.len();
            pitch_count += pitches.len();
        }
        cache.steps.clear();
        cache
            .steps
            .extend(lengths.iter().map(|f| f.symbol.map(|s| step_m(s, dims))));
        reset(&mut cache.turned, turn_count);
        reset(&mut cache.pitches, pitch_count);
        reset(&mut cache.headings, triples);
        Self {
            start,
            turns,
            dims,
            cache,
        }
    }

    /// The state after the turn of `c`, and the rotation of its pitch.
    fn turned(&mut self, c: &Combo) -> (TurtleState, Option<Turn>) {
        let [turn, pitches] = &self.turns[c.way];
        let [turn_base, pitch_base] = self.cache.first[c.way];
        let (start, dims) = (self.start, self.dims);
        let state = *self.cache.turned[turn_base + c.turn].get_or_insert_with(|| {
            let mut t = *start;
            if let Some(s) = turn[c.turn].symbol {
                t.apply(s, dims, true);
            }
            t
        });
        let pitch = *self.cache.pitches[pitch_base + c.pitch].get_or_insert_with(|| {
            pitches[c.pitch]
                .symbol
                .and_then(|s| Turn::of(s, dims, true))
        });
        (state, pitch)
    }

    /// The state after the turn and pitch of `c`, before its step.
    fn pitched(&mut self, c: &Combo) -> TurtleState {
        let (mut state, pitch) = self.turned(c);
        if let Some(p) = pitch {
            state.turn(p);
        }
        state
    }

    /// Distance from the node `c` draws to `target`.
    fn error(&mut self, c: &Combo, target: DVec3) -> f64 {
        let heading = match self.cache.headings[c.pair] {
            Some(h) => h,
            None => {
                let h = self.pitched(c).heading;
                self.cache.headings[c.pair] = Some(h);
                h
            }
        };
        // `TurtleState::ahead` of the pitched state, whose position is the
        // start's.
        let position = self.start.position;
        let node = self.cache.steps[c.length].map_or(position, |l| position + heading * l);
        node.distance(target)
    }

    /// The state after all of `c`.
    fn state(&mut self, c: &Combo) -> TurtleState {
        let mut state = self.pitched(c);
        if let Some(l) = self.cache.steps[c.length] {
            state.forward(l);
        }
        state
    }
}

/// Empties `cache` and fills it with `len` unknowns, keeping its buffer.
fn reset<T: Clone>(cache: &mut Vec<Option<T>>, len: usize) {
    cache.clear();
    cache.resize(len, None);
}

/// One combination of a way to turn, its turn and pitch roundings and a
/// length rounding, by indices into the choices.
#[derive(Clone, Copy)]
struct Combo {
    way: usize,
    turn: usize,
    pitch: usize,
    length: usize,
    /// Index of the (way, turn, pitch) triple among all of them.
    pair: usize,
}

impl Combo {
    /// The symbols this combination writes: its turn, pitch and step (each
    /// may be none).
    fn symbols<'c>(
        &self,
        turns: &'c [[Vec<Choice>; 2]],
        lengths: &'c [Choice],
    ) -> impl Iterator<Item = Symbol> + 'c {
        let [turn, pitches] = &turns[self.way];
        [
            turn[self.turn].symbol,
            pitches[self.pitch].symbol,
            lengths[self.length].symbol,
        ]
        .into_iter()
        .flatten()
    }
}

/// The combinations of turns and lengths, cheapest in bytes first and, at
/// equal cost, in the order of the nested loops (way, turn, pitch,
/// length). Costs are a few dozen bytes, so the search goes through them
/// cost by cost, without building and sorting every combination: the
/// triples are grouped by cost once, and those of one total cost are the
/// groups that complete a length's cost, merged back into loop order. The
/// cheapest combination that fits is often some ten costs up. The buffers
/// are kept from one internode to the next.
#[derive(Default)]
struct Search {
    /// The (way, turn, pitch) triples, in loop order.
    triples: Vec<[usize; 3]>,
    /// Cost of each triple.
    costs: Vec<usize>,
    /// Indices of the triples ordered by cost, then index.
    by_cost: Vec<u32>,
    /// Where the triples of each cost start in `by_cost`, one past the
    /// dearest.
    cost_start: Vec<usize>,
    /// Costs and indices of the length choices, ordered.
    lengths: Vec<(usize, usize)>,
    /// Runs of equal cost in `lengths`: the cost and the index range.
    length_runs: Vec<(usize, Range<usize>)>,
    /// For each length run at the cost being searched: the range of
    /// `by_cost` not yet merged, and the run.
    groups: Vec<(Range<usize>, Range<usize>)>,
}

impl Search {
    /// Prepares the search over `turns` and `lengths`.
    fn fill(&mut self, turns: &[[Vec<Choice>; 2]], lengths: &[Choice]) {
        self.triples.clear();
        self.costs.clear();
        for (way, [turn, pitches]) in turns.iter().enumerate() {
            for (ti, r) in turn.iter().enumerate() {
                for (pi, p) in pitches.iter().enumerate() {
                    self.triples.push([way, ti, pi]);
                    self.costs.push(r.cost + p.cost);
                }
            }
        }
        counting_sort(&self.costs, &mut self.by_cost, &mut self.cost_start);
        self.lengths.clear();
        self.lengths
            .extend(lengths.iter().enumerate().map(|(i, f)| (f.cost, i)));
        self.lengths.sort_unstable();
        self.length_runs.clear();
        let mut from = 0;
        for run in self.lengths.chunk_by(|a, b| a.0 == b.0) {
            self.length_runs.push((run[0].0, from..from + run.len()));
            from += run.len();
        }
    }

    /// Range in `by_cost` of the triples of cost `cost`, in loop order.
    fn triples_at(&self, cost: usize) -> Range<usize> {
        match (self.cost_start.get(cost), self.cost_start.get(cost + 1)) {
            (Some(&from), Some(&to)) => from..to,
            _ => 0..0,
        }
    }

    fn combo(&self, pair: u32, length: usize) -> Combo {
        let [way, turn, pitch] = self.triples[pair as usize];
        Combo {
            way,
            turn,
            pitch,
            length,
            pair: pair as usize,
        }
    }

    /// The cheapest combination (first in loop order) that `fits`.
    fn find(&mut self, mut fits: impl FnMut(&Combo) -> bool) -> Option<Combo> {
        let (cheapest, dearest) = self.cost_range();
        let mut groups = std::mem::take(&mut self.groups);
        let mut found = None;
        'costs: for cost in cheapest..=dearest {
            groups.clear();
            for (length_cost, run) in &self.length_runs {
                let Some(turn_cost) = cost.checked_sub(*length_cost) else {
                    break;
                };
                let triples = self.triples_at(turn_cost);
                if !triples.is_empty() {
                    groups.push((triples, run.clone()));
                }
            }
            // A triple has one cost, so it is in at most one group.
            while let Some((triples, run)) = groups
                .iter_mut()
                .filter(|(t, _)| !t.is_empty())
                .min_by_key(|(t, _)| self.by_cost[t.start])
            {
                let pair = self.by_cost[triples.start];
                triples.start += 1;
                for &(_, length) in &self.lengths[run.clone()] {
                    let combo = self.combo(pair, length);
                    if fits(&combo) {
                        found = Some(combo);
                        break 'costs;
                    }
                }
            }
        }
        self.groups = groups;
        found
    }

    /// Cheapest and dearest total costs.
    fn cost_range(&self) -> (usize, usize) {
        let min_turn = (0..self.cost_start.len() - 1)
            .find(|&c| !self.triples_at(c).is_empty())
            .unwrap_or(0);
        let max_turn = self.cost_start.len() - 2;
        let min_length = self.lengths.first().map_or(0, |l| l.0);
        let max_length = self.lengths.last().map_or(0, |l| l.0);
        (min_turn + min_length, max_turn + max_length)
    }

    /// The most expensive combination, last in loop order.
    fn last(&self) -> Combo {
        let max_turn = self.cost_start.len() - 2;
        let pair = self.by_cost[self.triples_at(max_turn)]
            .last()
            .copied()
            .expect("there is always at least one combination");
        let &(_, length) = self.lengths.last().expect("there is always a length");
        self.combo(pair, length)
    }
}

/// Writes into `order` the indices of `costs` ordered by cost, then index,
/// and into `start` where each cost starts among them (one past the dearest
/// at the end).
fn counting_sort(costs: &[usize], order: &mut Vec<u32>, start: &mut Vec<usize>) {
    let dearest = costs.iter().copied().max().unwrap_or(0);
    start.clear();
    start.resize(dearest + 2, 0);
    for &c in costs {
        start[c + 1] += 1;
    }
    for c in 1..start.len() {
        start[c] += start[c - 1];
    }
    order.clear();
    order.resize(costs.len(), 0);
    // Each cost's next free slot, moving `start` up by one cost.
    for (i, &c) in costs.iter().enumerate() {
        order[start[c]] = i as u32;
        start[c] += 1;
    }
    // Now `start[c]` is where cost c + 1 starts: shift back.
    start.rotate_right(1);
    start[0] = 0;
}

/// Appends `!(w)` if the decoded width is further than the radius budget
/// from the radius of node `id`. The new width is chosen to serve as many
/// nodes ahead on the main-extension chain as possible (the intersection of
/// their tolerance intervals), printed as the shortest number in it, so that
/// a slowly tapering branch needs few `!`.
fn write_width(
    turtle: &mut TurtleState,
    skeleton: &Skeleton,
    id: NodeId,
    tolerance: Tolerance,
    dims: &Dimensions,
    out: &mut Vec<Symbol>,
) {
    let interval = |n: NodeId| {
        let r = f64::from(skeleton.radius(n));
        let b = tolerance.radius_budget(r).max(0.0);
        (r - b, r + b)
    };
    let (mut lo, mut hi) = interval(id);
    if (lo..=hi).contains(&turtle.width_m) {
        return;
    }
    let mut node = id;
    while let Some(&next) = skeleton.children(node).first() {
        let (l, h) = interval(next);
        if l.max(lo) > h.min(hi) {
            break;
        }
        (lo, hi) = (l.max(lo), h.min(hi));
        node = next;
    }
    let w = shortest_within((lo + hi) / 2.0 / dims.unit_m, (hi - lo) / 2.0 / dims.unit_m);
    let s = Symbol::with(b'!', w.max(0.0));
    turtle.apply(s, dims, true);
    out.push(s);
}

/// Work items of the iterative traversal (Algorithm 3.1 without recursion,
/// so that a branch of any length cannot overflow the call stack).
enum Work {
    /// Write the internode into this node, then its subtree.
    Internode(NodeId),
    /// `[`: save the decoded state.
    Open,
    /// `]`: restore it.
    Close,
}

/// Tolerances of one encoding.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Tolerance {
    /// Node position, metres.
    pub(crate) position_m: f64,
    /// Radius, absolute floor, metres.
    pub(crate) radius_m: f64,
    /// Radius, relative to the radius.
    pub(crate) radius_rel: f64,
}

impl Tolerance {
    /// Position budget for a node at `target`: the tolerance, less what the
    /// reader's conversion to `f32` may add.
    pub(crate) fn position_budget(&self, target: DVec3) -> f64 {
        self.position_m * (1.0 - 1e-6) - target.length() * F32_SLACK
    }

    /// Radius error allowed for a node of radius `radius_m`.
    pub(crate) fn radius_allowed(&self, radius_m: f64) -> f64 {
        self.radius_m.max(self.radius_rel * radius_m)
    }

    /// Radius budget for a node of radius `radius_m`, less the `f32` slack.
    pub(crate) fn radius_budget(&self, radius_m: f64) -> f64 {
        self.radius_allowed(radius_m) * (1.0 - 1e-6) - radius_m * F32_SLACK
    }
}

/// Writes the whole skeleton (canonical order; `targets` relative to the
/// root) as an axiom. Laterals come first, each in `[...]`; the main
/// extension continues after them. Tips planned for generalisation are
/// written as a roll and one rule letter.
pub(crate) fn write_axiom(
    skeleton: &Skeleton,
    targets: &[DVec3],
    trunk_radius_m: f64,
    tolerance: Tolerance,
    dims: &Dimensions,
    plan: Option<&TipPlan>,
    favoured: &Favoured,
) -> Vec<Symbol> {
    let mut out = Vec::with_capacity(skeleton.len() * 4);
    let mut turtle = TurtleState::start(trunk_radius_m);
    let mut saved: Vec<TurtleState> = Vec::new();
    let mut work: Vec<Work> = Vec::new();
    let mut scratch = Scratch::default();
    push_children(skeleton, NodeId::ROOT, &mut work);
    while let Some(item) = work.pop() {
        match item {
            Work::Open => {
                out.push(Symbol::bare(b'['));
                saved.push(turtle);
            }
            Work::Close => {
                out.push(Symbol::bare(b']'));
                turtle = saved.pop().expect("every ] follows its [");
            }
            Work::Internode(id) => {
                if let Some(rule) = plan.and_then(|p| p.rule_at(id)) {
                    let target = targets[id.index()];
                    plan.expect("rule_at came from the plan").write_tip(
                        &mut turtle,
                        target,
                        rule,
                        tolerance,
                        dims,
                        &mut out,
                    );
                    continue;
                }
                let target = targets[id.index()];
                write_width(&mut turtle, skeleton, id, tolerance, dims, &mut out);
                write_internode(
                    &mut turtle,
                    target,
                    tolerance.position_budget(target),
                    (dims, favoured),
                    &mut scratch,
                    &mut out,
                );
                push_children(skeleton, id, &mut work);
            }
        }
    }
    out
}

/// Schedules the children of `id`: laterals in `[...]` in their order, then
/// the main extension (the stack runs in reverse).
fn push_children(skeleton: &Skeleton, id: NodeId, work: &mut Vec<Work>) {
    let kids = skeleton.children(id);
    if let Some((&main, laterals)) = kids.split_first() {
        work.push(Work::Internode(main));
        for &lateral in laterals.iter().rev() {
            work.push(Work::Close);
            work.push(Work::Internode(lateral));
            work.push(Work::Open);
        }
    }
}

/// Applies `symbols` with the reader's turtle, expanding rule letters by
/// `rules` (without nesting), and returns the positions drawn.
pub(crate) fn simulate<'r>(
    turtle: &mut TurtleState,
    symbols: &[Symbol],
    rules: &dyn Fn(u8) -> Option<&'r [Symbol]>,
    dims: &Dimensions,
    drawn: &mut Vec<DVec3>,
) {
    for &s in symbols {
        if let Some(body) = rules(s.ch) {
            simulate(turtle, body, rules, dims, drawn);
        } else if turtle.apply(s, dims, true) == Effect::Drew {
            drawn.push(turtle.position);
        }
    }
}
