//! Repeated patterns into rules, where it pays (a byte-costed Re-Pair).
//!
//! After writing, the axiom is a sequence of symbols with parameters. A
//! symbol or a pair of adjacent symbols that occurs often (the width at which
//! every twig starts, `][`, a common small pitch) is replaced by a free rule
//! letter and a rule `X → pattern`, when the bytes saved exceed the rule's
//! own cost in the document. Repeated, pairs of rule letters become longer
//! patterns. The expanded L-string is exactly the one written, so the
//! closed-loop guarantee is untouched.

use std::collections::{BTreeMap, HashMap};

use super::format::{Symbol, print};

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
    index: HashMap<Key, u32>,
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
/// and `depth`.
pub(crate) fn compress(
    axiom: &mut Vec<Symbol>,
    rules: &mut BTreeMap<u8, Vec<Symbol>>,
    depth: &mut HashMap<u8, u32>,
) {
    let taken: Vec<u8> = rules.keys().copied().collect();
    let mut free = (b'A'..=b'Z')
        .chain(b'a'..=b'z')
        .filter(|c| !b"Ff".contains(c) && !taken.contains(c));
    let mut symbols = Symbols::default();
    let mut ids: Vec<u32> = axiom.iter().map(|s| symbols.id(s)).collect();
    let mut scratch = Scratch::default();
    while let Some(pattern) = best_pattern(&ids, &symbols, &mut scratch) {
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
        replace(&mut ids, &pattern, symbols.id(&Symbol::bare(letter)));
        depth.insert(letter, body_depth + 1);
        rules.insert(letter, body);
    }
    *axiom = ids.iter().map(|&i| symbols.table[i as usize]).collect();
}

/// The single symbol or adjacent pair whose replacement saves most bytes,
/// if any saves some. Ties go to the smallest ids, so the result does not
/// depend on counting order. Pairs are counted by sorting, without overlap
/// inside runs such as `aaa`.
fn best_pattern(ids: &[u32], symbols: &Symbols, scratch: &mut Scratch) -> Option<Vec<u32>> {
    let singles = &mut scratch.singles;
    singles.clear();
    singles.resize(symbols.table.len(), 0);
    let pairs = &mut scratch.pairs;
    pairs.clear();
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
            pairs.push([ids[i - 1], id]);
            last_counted = i;
        }
    }
    sort_pairs(
        pairs,
        symbols.table.len(),
        &mut scratch.sorted,
        &mut scratch.start,
    );
    let cost = |id: u32| symbols.cost[id as usize];
    // A single `[a]` orders before the pair `[a, b]`, as `None` before `Some`.
    let singles = singles
        .iter()
        .enumerate()
        .filter(|&(_, &n)| n > 0)
        .map(|(id, &n)| (saving(n, cost(id as u32)), (id as u32, None)));
    let pairs = pairs.chunk_by(|a, b| a == b).map(|run| {
        let [a, b] = run[0];
        (saving(run.len(), cost(a) + cost(b)), (a, Some(b)))
    });
    let (gain, (first, second)) = singles
        .chain(pairs)
        .max_by(|x, y| x.0.cmp(&y.0).then_with(|| y.1.cmp(&x.1)))?;
    (gain > 0).then(|| std::iter::once(first).chain(second).collect())
}

/// Buffers that [`best_pattern`] reuses from one rule to the next.
#[derive(Default)]
struct Scratch {
    singles: Vec<usize>,
    pairs: Vec<[u32; 2]>,
    sorted: Vec<[u32; 2]>,
    start: Vec<usize>,
}

/// Sorts pairs of ids below `symbol_count` by a two-pass radix sort (by
/// the second id, then stably by the first): linear, where a comparison
/// sort of every pair for every rule dominated the encoder.
fn sort_pairs(
    pairs: &mut Vec<[u32; 2]>,
    symbol_count: usize,
    sorted: &mut Vec<[u32; 2]>,
    start: &mut Vec<usize>,
) {
    for digit in [1, 0] {
        start.clear();
        start.resize(symbol_count + 1, 0);
        for p in pairs.iter() {
            start[p[digit] as usize + 1] += 1;
        }
        for i in 1..start.len() {
            start[i] += start[i - 1];
        }
        sorted.clear();
        sorted.resize(pairs.len(), [0; 2]);
        for &p in pairs.iter() {
            let slot = &mut start[p[digit] as usize];
            sorted[*slot] = p;
            *slot += 1;
        }
        std::mem::swap(pairs, sorted);
    }
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

/// Replaces every non-overlapping occurrence of `pattern`, left to right,
/// in place (the text only shrinks).
fn replace(ids: &mut Vec<u32>, pattern: &[u32], letter: u32) {
    let mut kept = 0;
    let mut i = 0;
    while i < ids.len() {
        if ids[i] == pattern[0] && ids[i + 1..].starts_with(&pattern[1..]) {
            ids[kept] = letter;
            i += pattern.len();
        } else {
            ids[kept] = ids[i];
            i += 1;
        }
        kept += 1;
    }
    ids.truncate(kept);
}

#[cfg(test)]
mod tests {
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
        compress(&mut axiom, &mut rules, &mut depth);
        assert!(!rules.is_empty());
        assert!(print(&axiom).len() < text.len());
        let recursions = depth.values().copied().max().unwrap_or(0);
        assert_eq!(expand_once(&axiom, &rules, recursions), print(&original));
    }
}
