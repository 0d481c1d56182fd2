//! Repeated patterns into rules, where it pays (a byte-costed Re-Pair).
//!
//! After writing, the axiom is a sequence of symbols with parameters. A
//! symbol or a pair of adjacent symbols that occurs often (the width at which
//! every twig starts, `][`, a common small pitch) is replaced by a free rule
//! letter and a rule `X → pattern`, when the bytes saved exceed the rule's
//! own cost in the document. Repeated, pairs of rule letters become longer
//! patterns. The expanded L-string is exactly the one written, so the
//! closed-loop guarantee is untouched.

use std::cmp::Reverse;
use std::collections::{BTreeMap, BinaryHeap, HashMap};
use std::ops::Range;

use super::format::{Symbol, print};
use crate::interrupt::{Interrupt, Interrupted};

/// JSON overhead of one rule: `,"X":""`.
const RULE_OVERHEAD: usize = 7;

/// A symbol as a hashable key (parameters compared bit for bit).
type Key = (u8, Option<u64>);

fn key(s: &Symbol) -> Key {
    (s.ch, s.param.map(f64::to_bits))
}

/// Bytes of a symbol in the JSON document (a backslash is escaped).
fn cost(s: &Symbol) -> usize {
    print(std::slice::from_ref(s)).len() + usize::from(s.ch == b'\\')
}

/// Distinct symbols, numbered in order of first appearance, so that the
/// search below counts small integers instead of hashing symbols.
#[derive(Default)]
struct Symbols {
    table: Vec<Symbol>,
    cost: Vec<usize>,
    index: foldhash::HashMap<Key, u32>,
}

impl Symbols {
    fn id(&mut self, s: &Symbol) -> u32 {
        *self.index.entry(key(s)).or_insert_with(|| {
            self.table.push(*s);
            self.cost.push(cost(s));
            (self.table.len() - 1) as u32
        })
    }
}

/// Replaces repeated symbols and pairs of `axiom` by rules, using letters
/// not in `taken` (nor `F`/`f`). `depth` gives, for letters that already have
/// rules, how many recursions they need; the new rules are added to `rules`
/// and `depth`. `interrupt` is checked before each round (one rule each).
pub(crate) fn compress(
    axiom: &mut Vec<Symbol>,
    rules: &mut BTreeMap<u8, Vec<Symbol>>,
    depth: &mut HashMap<u8, u32>,
    interrupt: &Interrupt,
) -> Result<(), Interrupted> {
    let taken: Vec<u8> = rules.keys().copied().collect();
    let mut free = (b'A'..=b'Z')
        .chain(b'a'..=b'z')
        .filter(|c| !b"Ff".contains(c) && !taken.contains(c));
    let mut symbols = Symbols::default();
    let mut ids: Vec<u32> = axiom.iter().map(|s| symbols.id(s)).collect();
    let mut counts = Counts::new(&ids, &symbols);
    while let Some(pattern) = counts.best(&symbols) {
        interrupt.check("a Re-Pair round of the L-system")?;
        let Some(letter) = free.next() else {
            break;
        };
        let body: Vec<Symbol> = pattern.iter().map(|&i| symbols.table[i as usize]).collect();
        let body_depth = body
            .iter()
            .filter_map(|s| depth.get(&s.ch))
            .max()
            .copied()
            .unwrap_or(0);
        let letter_id = symbols.id(&Symbol::bare(letter));
        counts.replace(&mut ids, &pattern, letter_id, &symbols);
        depth.insert(letter, body_depth + 1);
        rules.insert(letter, body);
    }
    *axiom = ids.iter().map(|&i| symbols.table[i as usize]).collect();
    Ok(())
}

/// A candidate pattern as the search orders ties: `(a, 0)` is the single
/// `a`, `(a, b + 1)` the pair `a b`, so a single comes before the pairs that
/// start with it and smaller ids come first.
type PatternKey = (u32, u32);

/// Occurrences of the parametrised symbols and of the adjacent pairs of the
/// text, kept up to date through each replacement instead of recounted for
/// every rule: the incremental pair counts and priority queue of Re-Pair
/// (Larsson & Moffat 2000, "Off-line dictionary-based compression", §2).
/// Pairs of equal symbols are counted without overlap: `⌊r/2⌋` in a run of
/// `r`, as the left-to-right replacement takes them.
struct Counts {
    singles: Vec<usize>,
    pairs: foldhash::HashMap<[u32; 2], usize>,
    /// Patterns by saving, then smallest key. A pattern whose count has
    /// changed since it was queued is stale and skipped; every pattern that
    /// occurs has an entry at its current saving.
    queue: BinaryHeap<(i64, Reverse<PatternKey>)>,
}

impl Counts {
    fn new(ids: &[u32], symbols: &Symbols) -> Self {
        let mut counts = Self {
            singles: vec![0; symbols.table.len()],
            pairs: foldhash::HashMap::default(),
            queue: BinaryHeap::new(),
        };
        for &id in ids {
            if symbols.table[id as usize].param.is_some() {
                counts.singles[id as usize] += 1;
            }
        }
        counts.count_pairs(ids, true, &mut Vec::new());
        let singles = (0..symbols.table.len() as u32).map(|a| (a, 0));
        let pairs = counts.pairs.keys().map(|&[a, b]| (a, b + 1));
        let keys: Vec<PatternKey> = singles.chain(pairs).collect();
        counts.enqueue(keys, symbols);
        counts
    }

    /// Occurrences of `key` now.
    fn count(&self, (a, b): PatternKey) -> usize {
        match b.checked_sub(1) {
            None => self.singles[a as usize],
            Some(b) => self.pairs.get(&[a, b]).copied().unwrap_or(0),
        }
    }

    /// Bytes saved by a rule for `key` now.
    fn saving(&self, key: PatternKey, symbols: &Symbols) -> i64 {
        let cost = |id: u32| symbols.cost[id as usize];
        let len = cost(key.0) + key.1.checked_sub(1).map_or(0, cost);
        saving(self.count(key), len)
    }

    /// Queues the patterns of `keys` (distinct) that occur, at their
    /// current saving.
    fn enqueue(&mut self, keys: Vec<PatternKey>, symbols: &Symbols) {
        for key in keys {
            if self.count(key) > 0 {
                self.queue.push((self.saving(key, symbols), Reverse(key)));
            }
        }
    }

    /// The single symbol or adjacent pair whose replacement saves most
    /// bytes, if any saves some; ties go to the smallest ids, so the result
    /// does not depend on counting order.
    fn best(&mut self, symbols: &Symbols) -> Option<Vec<u32>> {
        while let Some(&(gain, Reverse(key))) = self.queue.peek() {
            if self.count(key) > 0 && self.saving(key, symbols) == gain {
                let (a, b) = key;
                return (gain > 0).then(|| std::iter::once(a).chain(b.checked_sub(1)).collect());
            }
            self.queue.pop();
        }
        None
    }

    /// Adds (or removes) the pairs of `ids`, a stretch of whole runs, and
    /// notes the pairs whose count changed in `touched`.
    fn count_pairs(&mut self, ids: &[u32], add: bool, touched: &mut Vec<PatternKey>) {
        let mut run_start = 0;
        for i in 1..ids.len() {
            let pair = [ids[i - 1], ids[i]];
            if pair[0] != pair[1] {
                run_start = i;
            } else if (i - run_start) % 2 == 0 {
                continue;
            }
            let n = self.pairs.entry(pair).or_default();
            if add {
                *n += 1;
            } else {
                *n -= 1;
            }
            touched.push((pair[0], pair[1] + 1));
        }
    }

    /// Replaces every non-overlapping occurrence of `pattern`, left to
    /// right, by `letter` (the text only shrinks) and updates the counts:
    /// only the pairs in the runs around each occurrence change.
    fn replace(&mut self, ids: &mut Vec<u32>, pattern: &[u32], letter: u32, symbols: &Symbols) {
        let starts = occurrences(ids, pattern);
        let regions = regions(ids, &starts, pattern.len());
        let mut touched = Vec::new();
        for (old, _) in &regions {
            self.count_pairs(&ids[old.clone()], false, &mut touched);
        }
        replace_at(ids, &starts, pattern.len(), letter);
        for (_, new) in &regions {
            self.count_pairs(&ids[new.clone()], true, &mut touched);
        }
        // Only pairs whose count changed can have dropped to zero.
        for &(a, b) in &touched {
            if let Some(b) = b.checked_sub(1)
                && self.pairs.get(&[a, b]) == Some(&0)
            {
                self.pairs.remove(&[a, b]);
            }
        }
        self.singles.resize(symbols.table.len(), 0);
        for &id in pattern {
            if symbols.table[id as usize].param.is_some() {
                self.singles[id as usize] -= starts.len();
                touched.push((id, 0));
            }
        }
        touched.sort_unstable();
        touched.dedup();
        self.enqueue(touched, symbols);
    }
}

/// Starts of the non-overlapping occurrences of `pattern`, left to right.
fn occurrences(ids: &[u32], pattern: &[u32]) -> Vec<usize> {
    let mut starts = Vec::new();
    let mut i = 0;
    while let Some(offset) = ids[i..].iter().position(|&id| id == pattern[0]) {
        let s = i + offset;
        let end = s + pattern.len();
        if end <= ids.len() && pattern[1..].iter().zip(&ids[s + 1..]).all(|(p, q)| p == q) {
            starts.push(s);
            i = end;
        } else {
            i = s + 1;
        }
    }
    starts
}

/// The stretches of `ids` whose pairs a replacement at `starts` changes,
/// before and after it: each occurrence with its neighbours, widened to
/// whole runs (so that runs of equal symbols are counted whole) and merged
/// where they overlap. Outside them, pairs and runs stay as they are.
fn regions(ids: &[u32], starts: &[usize], len: usize) -> Vec<(Range<usize>, Range<usize>)> {
    let shrink = len - 1;
    // (first index, last index inclusive, first and last occurrence).
    let mut merged: Vec<(usize, usize, usize, usize)> = Vec::new();
    for (j, &s) in starts.iter().enumerate() {
        let mut lo = s.saturating_sub(1);
        while lo > 0 && ids[lo - 1] == ids[lo] {
            lo -= 1;
        }
        let mut hi = (s + len).min(ids.len() - 1);
        while hi + 1 < ids.len() && ids[hi + 1] == ids[hi] {
            hi += 1;
        }
        match merged.last_mut() {
            Some(last) if lo <= last.1 => {
                last.1 = last.1.max(hi);
                last.3 = j;
            }
            _ => merged.push((lo, hi, j, j)),
        }
    }
    merged
        .into_iter()
        .map(|(lo, hi, first, last)| {
            let new = lo - shrink * first..hi + 1 - shrink * (last + 1);
            (lo..hi + 1, new)
        })
        .collect()
}

/// Replaces the occurrences starting at `starts` (non-overlapping, in
/// order) by `letter`, in place.
fn replace_at(ids: &mut Vec<u32>, starts: &[usize], len: usize, letter: u32) {
    let mut kept = 0;
    let mut from = 0;
    for &s in starts {
        ids.copy_within(from..s, kept);
        kept += s - from;
        ids[kept] = letter;
        kept += 1;
        from = s + len;
    }
    ids.copy_within(from.., kept);
    ids.truncate(kept + ids.len() - from);
}

/// Bytes saved by replacing `count` occurrences of a pattern of `len` bytes
/// by one letter, less the rule's own cost.
fn saving(count: usize, len: usize) -> i64 {
    (count * len.saturating_sub(1)) as i64 - (len + RULE_OVERHEAD) as i64
}

/// Recursions each rule letter needs to expand fully: 1 + the most any
/// letter in its body needs. Rules written by the encoder are acyclic.
pub(crate) fn rule_depths(rules: &BTreeMap<u8, Vec<Symbol>>) -> HashMap<u8, u32> {
    let mut depth: HashMap<u8, u32> = rules.keys().map(|&k| (k, 1)).collect();
    for _ in 0..rules.len() {
        for (&k, body) in rules {
            let d = 1 + body
                .iter()
                .filter_map(|s| depth.get(&s.ch))
                .max()
                .copied()
                .unwrap_or(0);
            depth.insert(k, d);
        }
    }
    depth
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::super::format::lex;
    use super::*;

    fn expand_once(axiom: &[Symbol], rules: &BTreeMap<u8, Vec<Symbol>>, times: u32) -> String {
        let mut cur = axiom.to_vec();
        for _ in 0..times {
            cur = cur
                .iter()
                .flat_map(|s| rules.get(&s.ch).cloned().unwrap_or_else(|| vec![*s]))
                .collect();
        }
        print(&cur)
    }

    #[test]
    fn compression_expands_back_exactly() {
        let text = "!(.027)F(.1)[!(.027)&(12.5)F(.2)][!(.027)&(12.5)F(.3)]!(.027)&(12.5)F(.1)\
                    [!(.027)&(12.5)F][!(.027)&(12.5)F(.4)]&(12.5)F(.1)";
        let original = lex(text, "t").unwrap();
        let mut axiom = original.clone();
        let mut rules = BTreeMap::new();
        let mut depth = HashMap::new();
        let passed = Interrupt::at(Some(std::time::Instant::now()));
        let err = compress(&mut axiom.clone(), &mut rules, &mut depth, &passed).unwrap_err();
        assert_eq!(err.step, "a Re-Pair round of the L-system");
        assert!(rules.is_empty());
        compress(&mut axiom, &mut rules, &mut depth, &Interrupt::never()).unwrap();
        assert!(!rules.is_empty());
        assert!(print(&axiom).len() < text.len());
        let recursions = depth.values().copied().max().unwrap_or(0);
        assert_eq!(expand_once(&axiom, &rules, recursions), print(&original));
    }

    /// Full recount, as the search did before every rule: singles of
    /// parametrised symbols, and pairs without overlap inside runs.
    fn recount(ids: &[u32], symbols: &Symbols) -> (Vec<usize>, HashMap<[u32; 2], usize>) {
        let mut singles = vec![0; symbols.table.len()];
        let mut pairs = HashMap::new();
        let mut last_counted = usize::MAX;
        for (i, &id) in ids.iter().enumerate() {
            if symbols.table[id as usize].param.is_some() {
                singles[id as usize] += 1;
            }
            if i == 0 {
                continue;
            }
            let overlaps = last_counted == i - 1 && ids[i - 2] == ids[i - 1] && ids[i - 1] == id;
            if !overlaps {
                *pairs.entry([ids[i - 1], id]).or_default() += 1;
                last_counted = i;
            }
        }
        (singles, pairs)
    }

    /// The best pattern by a full recount: most bytes saved, then the
    /// smallest ids, a single before a pair.
    fn best_by_recount(ids: &[u32], symbols: &Symbols) -> Option<Vec<u32>> {
        let (singles, pairs) = recount(ids, symbols);
        let cost = |id: u32| symbols.cost[id as usize];
        let singles = (0..singles.len() as u32)
            .filter(|&a| singles[a as usize] > 0)
            .map(|a| (saving(singles[a as usize], cost(a)), (a, None)));
        let pairs = pairs
            .iter()
            .map(|(&[a, b], &n)| (saving(n, cost(a) + cost(b)), (a, Some(b))));
        let (gain, (a, b)) = singles
            .chain(pairs)
            .max_by(|x, y| x.0.cmp(&y.0).then_with(|| y.1.cmp(&x.1)))?;
        (gain > 0).then(|| std::iter::once(a).chain(b).collect())
    }

    /// Every non-overlapping occurrence of `pattern` replaced, left to right.
    fn replace_by_scan(ids: &mut Vec<u32>, pattern: &[u32], letter: u32) {
        let mut out = Vec::new();
        let mut i = 0;
        while i < ids.len() {
            if ids[i..].starts_with(pattern) {
                out.push(letter);
                i += pattern.len();
            } else {
                out.push(ids[i]);
                i += 1;
            }
        }
        *ids = out;
    }

    /// Symbols from a small alphabet, so that runs, repeats and ties occur.
    fn text() -> impl Strategy<Value = Vec<Symbol>> {
        let symbol = (0usize..6, 0usize..4).prop_map(|(c, p)| {
            let ch = b"F&[]\\!"[c];
            match p {
                0 => Symbol::bare(ch),
                p => Symbol::with(ch, [0.5, 12.25, 7.0][p - 1]),
            }
        });
        proptest::collection::vec(symbol, 0..300)
    }

    proptest! {
        #[test]
        fn incremental_counts_equal_a_full_recount(text in text(), picks in proptest::collection::vec(0usize..1000, 1..40)) {
            let mut symbols = Symbols::default();
            let mut ids: Vec<u32> = text.iter().map(|s| symbols.id(s)).collect();
            let mut counts = Counts::new(&ids, &symbols);
            for (letter, pick) in (b'A'..=b'Z').zip(picks) {
                // Any pattern that occurs, not only the best one.
                let Some(&start) = ids.get(pick % ids.len().max(1)) else { break };
                let pattern: Vec<u32> = match ids.get(pick % ids.len() + 1) {
                    Some(&next) if pick % 3 != 0 => vec![start, next],
                    _ => vec![start],
                };
                let letter = symbols.id(&Symbol::bare(letter));
                counts.replace(&mut ids, &pattern, letter, &symbols);
                let (singles, pairs) = recount(&ids, &symbols);
                prop_assert_eq!(&counts.singles, &singles);
                let counted: HashMap<[u32; 2], usize> =
                    counts.pairs.iter().map(|(&k, &n)| (k, n)).collect();
                prop_assert_eq!(counted, pairs);
            }
        }

        #[test]
        fn rules_are_those_of_a_full_recount(text in text()) {
            let mut symbols = Symbols::default();
            let start: Vec<u32> = text.iter().map(|s| symbols.id(s)).collect();
            let mut by_recount = start.clone();
            let mut ids = start;
            let mut counts = Counts::new(&ids, &symbols);
            for letter in b'A'..=b'Z' {
                let expected = best_by_recount(&by_recount, &symbols);
                prop_assert_eq!(&counts.best(&symbols), &expected);
                let Some(pattern) = expected else { break };
                let letter = symbols.id(&Symbol::bare(letter));
                replace_by_scan(&mut by_recount, &pattern, letter);
                counts.replace(&mut ids, &pattern, letter, &symbols);
                prop_assert_eq!(&ids, &by_recount);
            }
        }
    }
}
