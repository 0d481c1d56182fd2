//! Rule expansion with limits, and removal of empty nestings
//! (lsystem-from-adtree-skeletons §3.2.6, "Translate the axiom and rules").
//!
//! A user may upload LsJSON, and an L-system grows exponentially (`A → AA`
//! over 64 recursions is 2^64 symbols). So before anything is allocated, the
//! length of the string after every recursion is computed from symbol counts
//! alone — a 52×52 count recurrence per recursion, independent of the string
//! length — and the document is rejected if it would exceed
//! [`Limits::max_symbols`](super::Limits::max_symbols).

use super::format::{LsJson, Symbol};
use super::{Limits, LsError};

/// Rule letters: `A`–`Z`, `a`–`z`.
const LETTERS: usize = 52;

fn letter_index(ch: u8) -> Option<usize> {
    match ch {
        b'A'..=b'Z' => Some(usize::from(ch - b'A')),
        b'a'..=b'z' => Some(26 + usize::from(ch - b'a')),
        _ => None,
    }
}

/// Symbol composition of a string: how many symbols are not rewritten, and
/// how many of each rule letter it holds.
struct Composition {
    fixed: u64,
    letters: [u64; LETTERS],
}

impl Composition {
    fn of(symbols: &[Symbol], has_rule: &[bool; LETTERS]) -> Self {
        let mut c = Composition {
            fixed: 0,
            letters: [0; LETTERS],
        };
        for s in symbols {
            match letter_index(s.ch).filter(|&i| has_rule[i]) {
                Some(i) => c.letters[i] += 1,
                None => c.fixed += 1,
            }
        }
        c
    }

    /// Length of this string once each rule letter `i` has become `len[i]`
    /// symbols, saturating.
    fn length(&self, len: &[u64; LETTERS]) -> u64 {
        self.letters
            .iter()
            .zip(len)
            .fold(self.fixed, |acc, (&n, &l)| {
                acc.saturating_add(n.saturating_mul(l))
            })
    }
}

/// Rejects documents whose expansion would exceed `limits`, without
/// expanding them.
pub(crate) fn check_size(ls: &LsJson, limits: &Limits) -> Result<(), LsError> {
    if ls.recursions > limits.max_recursions {
        return Err(LsError::Recursions {
            recursions: ls.recursions,
            limit: limits.max_recursions,
        });
    }
    let mut has_rule = [false; LETTERS];
    for &k in ls.rules.keys() {
        if let Some(i) = letter_index(k) {
            has_rule[i] = true;
        }
    }
    let bodies: Vec<(usize, Composition)> = ls
        .rules
        .iter()
        .filter_map(|(&k, body)| letter_index(k).map(|i| (i, Composition::of(body, &has_rule))))
        .collect();
    let axiom = Composition::of(&ls.axiom, &has_rule);
    let too_many = || LsError::TooManySymbols {
        limit: limits.max_symbols,
    };
    // len[i]: symbols one rule letter i becomes after t recursions.
    let mut len = [1u64; LETTERS];
    let mut work = axiom.length(&len);
    if work > limits.max_symbols as u64 {
        return Err(too_many());
    }
    for _ in 0..ls.recursions {
        let mut next = len;
        for (i, body) in &bodies {
            next[*i] = body.length(&len);
        }
        len = next;
        let total = axiom.length(&len);
        work = work.saturating_add(total);
        // The work bound keeps `A → A` over many recursions cheap, too.
        if total > limits.max_symbols as u64 || work > work_limit(limits) {
            return Err(too_many());
        }
    }
    Ok(())
}

/// Total symbols the rewriting may produce over all recursions.
fn work_limit(limits: &Limits) -> u64 {
    (limits.max_symbols as u64).saturating_mul(16)
}

/// Expands the axiom over `recursions` (parallel rewriting: every symbol
/// that has a rule is replaced by the rule's body, whatever its parameter),
/// then removes empty nestings and checks that brackets balance.
pub(crate) fn expand(ls: &LsJson, limits: &Limits) -> Result<Vec<Symbol>, LsError> {
    check_size(ls, limits)?;
    let mut table: [Option<&[Symbol]>; 128] = [None; 128];
    for (&k, body) in &ls.rules {
        table[usize::from(k & 0x7f)] = Some(body);
    }
    let mut current = ls.axiom.clone();
    for _ in 0..ls.recursions {
        if !current
            .iter()
            .any(|s| table[usize::from(s.ch & 0x7f)].is_some())
        {
            break;
        }
        let mut next = Vec::with_capacity(current.len());
        for s in &current {
            match table[usize::from(s.ch & 0x7f)] {
                Some(body) => next.extend_from_slice(body),
                None => next.push(*s),
            }
        }
        current = next;
    }
    remove_empty_nestings(current, limits.max_depth)
}

/// Drops every `[ ... ]` that draws nothing (no `F` inside, at any depth):
/// the turtle state is restored at `]`, so such a nesting has no effect.
/// Also rejects unbalanced brackets and nesting deeper than `max_depth`.
pub(crate) fn remove_empty_nestings(
    symbols: Vec<Symbol>,
    max_depth: usize,
) -> Result<Vec<Symbol>, LsError> {
    let mut out = Vec::with_capacity(symbols.len());
    // Per open bracket: where it starts in `out`, and whether it drew.
    let mut open: Vec<(usize, bool)> = Vec::new();
    for (at, s) in symbols.into_iter().enumerate() {
        match s.ch {
            b'[' => {
                if open.len() >= max_depth {
                    return Err(LsError::TooDeep { limit: max_depth });
                }
                open.push((out.len(), false));
                out.push(s);
            }
            b']' => {
                let (start, drew) = open.pop().ok_or(LsError::Unbalanced {
                    symbol: at,
                    reason: "']' without a matching '['",
                })?;
                if drew {
                    out.push(s);
                    if let Some(parent) = open.last_mut() {
                        parent.1 = true;
                    }
                } else {
                    out.truncate(start);
                }
            }
            c => {
                if c == b'F' {
                    if let Some(top) = open.last_mut() {
                        top.1 = true;
                    }
                }
                out.push(s);
            }
        }
    }
    if let Some(&(start, _)) = open.last() {
        return Err(LsError::Unbalanced {
            symbol: start,
            reason: "'[' is never closed",
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::super::format::{lex, print};
    use super::*;

    fn clean(text: &str) -> String {
        print(&remove_empty_nestings(lex(text, "t").unwrap(), 100).unwrap())
    }

    #[test]
    fn empty_nestings_are_removed() {
        assert_eq!(clean("F[+][X[&]]F[+F[-]]"), "FF[+F]");
        assert_eq!(clean("[[[]]]F"), "F");
    }

    #[test]
    fn unbalanced_and_deep_nesting_are_errors() {
        assert!(remove_empty_nestings(lex("F]", "t").unwrap(), 10).is_err());
        assert!(remove_empty_nestings(lex("[F", "t").unwrap(), 10).is_err());
        assert!(remove_empty_nestings(lex("[[[F]]]", "t").unwrap(), 2).is_err());
    }
}
