//! The LsJSON document: the raw serde mirror, the validated [`LsJson`], the
//! L-string lexer and printer. The grammar is in `docs/lsjson.md`.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use glam::DVec3;
use serde::{Deserialize, Serialize};

use super::{LsError, expand};
use crate::skeleton::Anchor;

/// Value of the `format` field.
pub(crate) const FORMAT: &str = "lsjson";
/// The LsJSON version this build writes. It also reads version 1, which
/// has no length unit (`dimensions.unit_m` = 1).
pub(crate) const VERSION: u32 = 2;
/// Longest number literal the lexer accepts, in characters.
const MAX_NUMBER_CHARS: usize = 40;

/// One L-string symbol: an ASCII character and its optional parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Symbol {
    /// The command or rule letter, ASCII.
    pub(crate) ch: u8,
    /// The value in parentheses, if any.
    pub(crate) param: Option<f64>,
}

impl Symbol {
    /// A symbol with a parameter.
    pub(crate) fn with(ch: u8, param: f64) -> Self {
        Self {
            ch,
            param: Some(param),
        }
    }

    /// A symbol without a parameter.
    pub(crate) fn bare(ch: u8) -> Self {
        Self { ch, param: None }
    }
}

/// Error statistics and the stated bound, stored in the document.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, utoipa::ToSchema)]
pub struct ErrorBound {
    /// Stated bound: every decoded node lies within this distance of the
    /// node it encodes, in metres (the writer's tolerance, or the
    /// generalisation error if that is larger).
    pub bound_m: f64,
    /// Stated bound on the radius error of thin branches, metres: every
    /// decoded radius `r'` of a node of radius `r` has
    /// `|r' − r| ≤ max(radius_bound_m, radius_bound_rel · r)`.
    pub radius_bound_m: f64,
    /// Stated bound on the radius error relative to the radius.
    pub radius_bound_rel: f64,
    /// Largest node position error the writer measured, metres.
    pub max_m: f64,
    /// Mean node position error the writer measured, metres.
    pub mean_m: f64,
    /// Largest radius error the writer measured, metres.
    pub radius_max_m: f64,
    /// `k` of tip generalisation (§3.3.1); 0 when tips are exact.
    #[serde(default)]
    pub generalised_steps: u32,
    /// Largest position error of a generalised tip node, metres (0 without
    /// generalisation).
    #[serde(default)]
    pub generalisation_max_m: f64,
}

/// Default parameter values for symbols written without one, and the
/// length unit of `F` and `!` parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Dimensions {
    /// Metres per length unit (1 in version 1).
    pub(crate) unit_m: f64,
    pub(crate) forward: f64,
    pub(crate) rotation: f64,
    pub(crate) roll: f64,
}

/// A validated LsJSON document (see `docs/lsjson.md`).
///
/// Built by [`super::encode`] or [`LsJson::parse`]; turned back into a
/// skeleton by [`super::decode`].
#[derive(Debug, Clone, PartialEq)]
pub struct LsJson {
    pub(crate) recursions: u32,
    pub(crate) axiom: Vec<Symbol>,
    pub(crate) rules: BTreeMap<u8, Vec<Symbol>>,
    pub(crate) anchor: Anchor,
    pub(crate) trunk_radius_m: f64,
    pub(crate) dimensions: Dimensions,
    pub(crate) degrees: bool,
    pub(crate) error: ErrorBound,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLsJson {
    format: String,
    version: u32,
    degrees: bool,
    recursions: u32,
    trunk: RawTrunk,
    dimensions: RawDimensions,
    error: ErrorBound,
    #[serde(default)]
    rules: BTreeMap<String, String>,
    axiom: String,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTrunk {
    anchor: [f64; 3],
    radius: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    crs: Option<String>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawDimensions {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    unit_m: Option<f64>,
    forward: f64,
    rotation: f64,
    roll: f64,
}

impl LsJson {
    /// Serialises to compact LsJSON text.
    pub fn to_json(&self) -> String {
        let raw = RawLsJson {
            format: FORMAT.into(),
            version: VERSION,
            degrees: self.degrees,
            recursions: self.recursions,
            trunk: RawTrunk {
                anchor: self.anchor.origin.to_array(),
                radius: self.trunk_radius_m,
                crs: self.anchor.crs.clone(),
            },
            dimensions: RawDimensions {
                unit_m: Some(self.dimensions.unit_m),
                forward: self.dimensions.forward,
                rotation: self.dimensions.rotation,
                roll: self.dimensions.roll,
            },
            error: self.error,
            rules: self
                .rules
                .iter()
                .map(|(&k, body)| (char::from(k).to_string(), print(body)))
                .collect(),
            axiom: print(&self.axiom),
        };
        serde_json::to_string(&raw).expect("LsJSON serialisation cannot fail")
    }

    /// Parses and validates LsJSON text. Checks, before anything is expanded,
    /// that the document fits in `limits` (input size, recursions, expanded
    /// length), so hostile input fails fast with a clear error.
    pub fn parse(text: &str, limits: &super::Limits) -> Result<LsJson, LsError> {
        if text.len() > limits.max_input_bytes {
            return Err(LsError::InputTooLarge {
                bytes: text.len(),
                limit: limits.max_input_bytes,
            });
        }
        let raw: RawLsJson = serde_json::from_str(text)?;
        let ls = Self::from_raw(raw)?;
        expand::check_size(&ls, limits)?;
        Ok(ls)
    }

    /// The document of a parsed file, each field checked (see
    /// docs/lsjson.md for what each may hold).
    fn from_raw(raw: RawLsJson) -> Result<LsJson, LsError> {
        if raw.format != FORMAT || !(1..=VERSION).contains(&raw.version) {
            return Err(LsError::Version {
                format: raw.format,
                version: raw.version,
            });
        }
        let unit_m = unit_m(&raw)?;
        check_numbers(&raw)?;
        let rules = lex_rules(&raw.rules)?;
        let d = &raw.dimensions;
        Ok(LsJson {
            recursions: raw.recursions,
            axiom: lex(&raw.axiom, "axiom")?,
            rules,
            anchor: Anchor {
                origin: DVec3::from_array(raw.trunk.anchor),
                crs: raw.trunk.crs,
            },
            trunk_radius_m: raw.trunk.radius,
            dimensions: Dimensions {
                unit_m,
                forward: d.forward,
                rotation: d.rotation,
                roll: d.roll,
            },
            degrees: raw.degrees,
            error: raw.error,
        })
    }

    /// The stated error bound and the errors the writer measured.
    pub fn error(&self) -> &ErrorBound {
        &self.error
    }

    /// Where the trunk base stands (the decoded root), with its CRS.
    pub fn anchor(&self) -> &Anchor {
        &self.anchor
    }

    /// How many times the rules are applied to the axiom.
    pub fn recursions(&self) -> u32 {
        self.recursions
    }

    /// Number of rules.
    pub fn rule_count(&self) -> usize {
        self.rules.len()
    }

    /// The axiom as L-string text.
    pub fn axiom_text(&self) -> String {
        print(&self.axiom)
    }
}

/// The unit of `F`'s length: 1 m in version 1, which has no such field;
/// stated, finite and positive from version 2.
fn unit_m(raw: &RawLsJson) -> Result<f64, LsError> {
    let unit_m = match (raw.version, raw.dimensions.unit_m) {
        (1, None) => 1.0,
        (1, Some(_)) => {
            return Err(LsError::Invalid {
                field: "dimensions.unit_m",
                reason: "is not part of version 1",
            });
        }
        (_, unit) => unit.ok_or(LsError::Invalid {
            field: "dimensions.unit_m",
            reason: "is required from version 2",
        })?,
    };
    require(
        unit_m.is_finite() && unit_m > 0.0,
        "dimensions.unit_m",
        "must be finite and positive",
    )?;
    Ok(unit_m)
}

/// The anchor, trunk radius, turtle dimensions and error figures are
/// finite; the radius and the error figures are not negative.
fn check_numbers(raw: &RawLsJson) -> Result<(), LsError> {
    let anchor = DVec3::from_array(raw.trunk.anchor);
    require(anchor.is_finite(), "trunk.anchor", "must be finite")?;
    let radius = raw.trunk.radius;
    require(
        radius.is_finite() && radius >= 0.0,
        "trunk.radius",
        "must be finite and non-negative",
    )?;
    let d = &raw.dimensions;
    require(
        d.forward.is_finite() && d.rotation.is_finite() && d.roll.is_finite(),
        "dimensions",
        "must be finite",
    )?;
    let e = &raw.error;
    let stats = [
        e.bound_m,
        e.radius_bound_m,
        e.radius_bound_rel,
        e.max_m,
        e.mean_m,
        e.radius_max_m,
        e.generalisation_max_m,
    ];
    require(
        stats.iter().all(|v| v.is_finite() && *v >= 0.0),
        "error",
        "must be finite and non-negative",
    )
}

/// The rules' bodies lexed, keyed by their one-letter names.
fn lex_rules(raw: &BTreeMap<String, String>) -> Result<BTreeMap<u8, Vec<Symbol>>, LsError> {
    let mut rules = BTreeMap::new();
    for (name, body) in raw {
        let key = match name.as_bytes() {
            [c] if c.is_ascii_alphabetic() => *c,
            _ => return Err(LsError::RuleName(name.clone())),
        };
        rules.insert(key, lex(body, &format!("rules.{name}"))?);
    }
    Ok(rules)
}

fn require(ok: bool, field: &'static str, reason: &'static str) -> Result<(), LsError> {
    if ok {
        Ok(())
    } else {
        Err(LsError::Invalid { field, reason })
    }
}

/// True for characters that are L-string commands or rule letters.
fn is_symbol_char(c: u8) -> bool {
    c.is_ascii_alphabetic() || b"+-&^/\\|![]".contains(&c)
}

/// Lexes an L-string; `field` names it in errors.
pub(crate) fn lex(text: &str, field: &str) -> Result<Vec<Symbol>, LsError> {
    let bytes = text.as_bytes();
    let syntax = |offset: usize, reason: &'static str| LsError::Syntax {
        field: field.to_owned(),
        offset,
        reason,
    };
    let mut out = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let c = bytes[i];
        if c.is_ascii_whitespace() {
            i += 1;
            continue;
        }
        if !is_symbol_char(c) {
            return Err(syntax(i, "not an L-string symbol"));
        }
        i += 1;
        if bytes.get(i) != Some(&b'(') {
            if c == b'!' {
                return Err(syntax(i - 1, "! needs a width parameter"));
            }
            out.push(Symbol::bare(c));
            continue;
        }
        if b"[]|".contains(&c) {
            return Err(syntax(i, "this symbol takes no parameter"));
        }
        let start = i + 1;
        let len = bytes[start..]
            .iter()
            .take(MAX_NUMBER_CHARS + 1)
            .position(|&b| b == b')')
            .ok_or_else(|| syntax(start, "parameter without closing ')' or too long"))?;
        let literal = &text[start..start + len];
        let value = parse_number(literal).ok_or_else(|| syntax(start, "not a finite number"))?;
        if c == b'!' && value < 0.0 {
            return Err(syntax(start, "a width cannot be negative"));
        }
        out.push(Symbol::with(c, value));
        i = start + len + 1;
    }
    Ok(out)
}

/// Parses a decimal literal: digits, one optional sign, point and exponent.
/// Rejects `inf`, `NaN` and anything that overflows to infinity.
fn parse_number(literal: &str) -> Option<f64> {
    let allowed = |b: u8| b.is_ascii_digit() || b"+-.eE".contains(&b);
    if literal.is_empty() || !literal.bytes().all(allowed) {
        return None;
    }
    literal.parse::<f64>().ok().filter(|v| v.is_finite())
}

/// Prints symbols as L-string text, numbers in their shortest exact form.
pub(crate) fn print(symbols: &[Symbol]) -> String {
    let mut out = String::with_capacity(symbols.len() * 5);
    for s in symbols {
        out.push(char::from(s.ch));
        if let Some(p) = s.param {
            out.push('(');
            push_number(&mut out, p);
            out.push(')');
        }
    }
    out
}

/// Shortest decimal that parses back to exactly `v`, without a leading zero
/// before the point (`.25`, `-.5`); in exponent form (`5.1e50`) when the
/// plain form would be longer than the reader takes ([`MAX_NUMBER_CHARS`]).
/// Written straight into `out`: documents hold a number per symbol, and
/// formatting each through temporary strings was 7 % of `encode`.
pub(crate) fn push_number(out: &mut String, v: f64) {
    // Whole numbers (lengths in the length unit mostly are) print as the
    // integer, which `Display` for `f64` also prints.
    if v.fract() == 0.0 && v.abs() < 1e15 && v != 0.0 {
        push_integer(out, v as i64);
        return;
    }
    let start = out.len();
    write!(out, "{v}").expect("writing to a String cannot fail");
    if out.len() - start > MAX_NUMBER_CHARS {
        out.truncate(start);
        write!(out, "{v:e}").expect("writing to a String cannot fail");
    }
    let text = &out[start..];
    if text.starts_with("0.") {
        out.remove(start);
    } else if text.starts_with("-0.") {
        out.remove(start + 1);
    }
}

/// Writes `n` in decimal, as `Display` for `i64` does.
fn push_integer(out: &mut String, n: i64) {
    let mut digits = [0u8; 20];
    let mut start = digits.len();
    let mut rest = n.unsigned_abs();
    loop {
        start -= 1;
        digits[start] = b'0' + (rest % 10) as u8;
        rest /= 10;
        if rest == 0 {
            break;
        }
    }
    if n < 0 {
        out.push('-');
    }
    out.push_str(std::str::from_utf8(&digits[start..]).expect("ASCII digits"));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lex_print_round_trip() {
        let text = "F(.25)[+(30)&(-1.5e1)F]\\(2)/(.001)!(0.05)FA";
        let symbols = lex(text, "axiom").unwrap();
        assert_eq!(symbols.len(), 11);
        assert_eq!(lex(&print(&symbols), "axiom").unwrap(), symbols);
        assert_eq!(print(&lex("F(0.5)+(-0.25)", "a").unwrap()), "F(.5)+(-.25)");
    }

    #[test]
    fn lex_rejects_bad_numbers_and_symbols() {
        for bad in [
            "F(NaN)", "F(inf)", "F(1e999)", "F(", "F(1", "[(2)]", "F#", "F()", "F(1..2)", "F!",
            "!(-1)",
        ] {
            assert!(lex(bad, "axiom").is_err(), "{bad}");
        }
    }
}
