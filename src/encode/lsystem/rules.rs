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
    let mut costs = HashMap::new();
    loop {
        let Some(pattern) = best_pattern(axiom, &mut costs) else {
            return;
        };
        let Some(letter) = free.next() else {
            return;
        };
        let body_depth = pattern
            .iter()
            .filter_map(|s| depth.get(&s.ch))
            .max()
            .copied()
            .unwrap_or(0);
        replace(axiom, &pattern, letter);
        depth.insert(letter, body_depth + 1);
        rules.insert(letter, pattern);
    }
}

/// The single symbol or adjacent pair whose replacement saves most bytes,
/// if any saves some. Ties go to the smallest key, so the result does not
/// depend on hash order. `costs` caches printed lengths across calls.
fn best_pattern(axiom: &[Symbol], costs: &mut HashMap<Key, usize>) -> Option<Vec<Symbol>> {
    let mut singles: HashMap<Key, usize> = HashMap::new();
    let mut pairs: HashMap<(Key, Key), usize> = HashMap::new();
    // Pairs are counted without overlap inside runs such as `aaa`.
    let mut last_counted = usize::MAX;
    for (i, s) in axiom.iter().enumerate() {
        let k = key(s);
        costs.entry(k).or_insert_with(|| cost(s));
        if s.param.is_some() {
            *singles.entry(k).or_default() += 1;
        }
        if i == 0 {
            continue;
        }
        let pair = (key(&axiom[i - 1]), k);
        let overlaps = last_counted == i - 1 && pair == (key(&axiom[i - 2]), key(&axiom[i - 1]));
        if !overlaps {
            *pairs.entry(pair).or_default() += 1;
            last_counted = i;
        }
    }
    let singles = singles
        .into_iter()
        .map(|(k, n)| (saving(n, costs[&k]), [Some(k), None]));
    let pairs = pairs
        .into_iter()
        .map(|((a, b), n)| (saving(n, costs[&a] + costs[&b]), [Some(a), Some(b)]));
    let (gain, keys) = singles
        .chain(pairs)
        .max_by_key(|&(gain, keys)| (gain, std::cmp::Reverse(keys)))?;
    (gain > 0).then(|| keys.into_iter().flatten().map(symbol).collect())
}

/// Bytes saved by replacing `count` occurrences of a pattern of `len` bytes
/// by one letter, less the rule's own cost.
fn saving(count: usize, len: usize) -> i64 {
    (count * len.saturating_sub(1)) as i64 - (len + RULE_OVERHEAD) as i64
}

/// The symbol a key stands for.
fn symbol((ch, param): Key) -> Symbol {
    Symbol {
        ch,
        param: param.map(f64::from_bits),
    }
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

/// Replaces every non-overlapping occurrence of `pattern`, left to right.
fn replace(axiom: &mut Vec<Symbol>, pattern: &[Symbol], letter: u8) {
    let keys: Vec<Key> = pattern.iter().map(key).collect();
    let mut out = Vec::with_capacity(axiom.len());
    let mut i = 0;
    while i < axiom.len() {
        let end = i + keys.len();
        if end <= axiom.len() && axiom[i..end].iter().map(key).eq(keys.iter().copied()) {
            out.push(Symbol::bare(letter));
            i = end;
        } else {
            out.push(axiom[i]);
            i += 1;
        }
    }
    *axiom = out;
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
