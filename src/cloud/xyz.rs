//! XYZ/TXT text reader and writer: one point per line, `x y z` first.
//!
//! Fields are separated by spaces, tabs or commas; columns after the third
//! are ignored; a UTF-8 byte-order mark at the start is skipped; `#`
//! starts a comment (so does a leading `//`, which is how
//! CloudCompare writes its column header); blank lines are skipped and the
//! last line may lack its newline. Lines are read with a length cap, so a
//! file without newlines cannot make the reader buffer it whole.

use std::io::{BufRead, BufReader, Read, Write};

use glam::DVec3;

use super::read::{Attributes, CloudBuilder, ReadOptions};
use super::{CloudError, Format, Location, PointCloud};

/// Longest accepted line in bytes; real XYZ lines are under 200.
const MAX_LINE: usize = 4096;

/// The UTF-8 byte-order mark, skipped at the start of a file.
pub(super) const BOM: &[u8] = "\u{feff}".as_bytes();

/// Reads XYZ text from `input`.
pub(super) fn read<R: Read>(input: R, opts: &ReadOptions) -> Result<PointCloud, CloudError> {
    let mut reader = BufReader::new(input);
    let mut builder = CloudBuilder::new(Format::Xyz, opts, 0, Attributes::default());
    let mut line = Vec::with_capacity(256);
    let mut line_no = 0u64;
    loop {
        line.clear();
        let n = (&mut reader)
            .take(MAX_LINE as u64 + 1)
            .read_until(b'\n', &mut line)?;
        if n == 0 {
            break;
        }
        line_no += 1;
        let location = Location::Line(line_no);
        if line.len() > MAX_LINE {
            return Err(malformed(
                location,
                format!("line longer than {MAX_LINE} bytes"),
            ));
        }
        // A UTF-8 byte-order mark, as Windows editors write, is not data.
        let text = match line_no {
            1 => line.strip_prefix(BOM).unwrap_or(&line),
            _ => &line,
        };
        if let Some(p) = parse_line(text).map_err(|reason| malformed(location, reason))? {
            builder.push(p, Attributes::default(), location)?;
        }
    }
    Ok(builder.finish())
}

fn malformed(location: Location, reason: String) -> CloudError {
    CloudError::Malformed {
        format: Format::Xyz,
        location,
        reason,
    }
}

/// One line: `Ok(None)` for blank or comment lines, the point otherwise.
///
/// Works on the bytes of ASCII lines (nearly all), with 40 % fewer
/// instructions than splitting a `str` (callgrind, 800,000 scanner lines);
/// a line with other bytes takes [`parse_text_line`], which the ASCII path
/// matches exactly.
fn parse_line(raw: &[u8]) -> Result<Option<DVec3>, String> {
    if !raw.is_ascii() {
        let text = std::str::from_utf8(raw).map_err(|_| "not UTF-8 text".to_owned())?;
        return parse_text_line(text);
    }
    let data = trim_white_space(raw.split(|&b| b == b'#').next().unwrap_or_default());
    if data.is_empty() || data.starts_with(b"//") {
        return Ok(None);
    }
    let fields = data
        .split(|&b| b == b',' || b.is_ascii_whitespace())
        .filter(|f| !f.is_empty());
    coordinates(fields, parse_decimal, truncate_bytes).map(Some)
}

/// The first three of `fields` as coordinates; `shown` gives a field that
/// is not a number for the error.
fn coordinates<F: Copy>(
    mut fields: impl Iterator<Item = F>,
    parse: impl Fn(F) -> Option<f64>,
    shown: impl Fn(F) -> String,
) -> Result<DVec3, String> {
    let mut xyz = [0.0f64; 3];
    for (i, v) in xyz.iter_mut().enumerate() {
        let field = fields
            .next()
            .ok_or_else(|| format!("expected 3 coordinates, found {i}"))?;
        *v = parse(field).ok_or_else(|| format!("not a number: {:?}", shown(field)))?;
    }
    Ok(DVec3::from_array(xyz))
}

/// `data` without leading and trailing white space, as `str::trim` sees it
/// in ASCII: `u8::is_ascii_whitespace` and the vertical tab (0x0B), which
/// that leaves out.
fn trim_white_space(mut data: &[u8]) -> &[u8] {
    let trimmed = |b: &u8| b.is_ascii_whitespace() || *b == 0x0B;
    while data.first().is_some_and(trimmed) {
        data = &data[1..];
    }
    while data.last().is_some_and(trimmed) {
        data = &data[..data.len() - 1];
    }
    data
}

/// The line parser for lines with non-ASCII text, on `str`.
fn parse_text_line(text: &str) -> Result<Option<DVec3>, String> {
    let data = text.split('#').next().unwrap_or_default().trim();
    if data.is_empty() || data.starts_with("//") {
        return Ok(None);
    }
    let fields = data
        .split(|c: char| c == ',' || c.is_ascii_whitespace())
        .filter(|f| !f.is_empty());
    coordinates(fields, |f: &str| f.parse().ok(), truncate).map(Some)
}

/// A decimal number of an ASCII field, exactly as `str::parse::<f64>`
/// reads it. Plain decimals with at most 15 significant digits and 22
/// decimals (every coordinate a scanner writes) take Clinger's fast path:
/// the digits as an integer, exact in an `f64`, divided by an exact power
/// of ten, which IEEE division rounds correctly. Anything else (exponents,
/// `inf`, long mantissas) goes to the standard parser.
fn parse_decimal(field: &[u8]) -> Option<f64> {
    fast_decimal(field).or_else(|| std::str::from_utf8(field).ok()?.parse().ok())
}

/// Powers of ten that an `f64` holds exactly.
const EXACT_POWERS_OF_TEN: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// Clinger's fast path of [`parse_decimal`]: `[+-]digits[.digits]` (either
/// side of the point may be empty, not both), or `None`.
fn fast_decimal(field: &[u8]) -> Option<f64> {
    let (negative, body) = match field.split_first()? {
        (b'-', rest) => (true, rest),
        (b'+', rest) => (false, rest),
        _ => (false, field),
    };
    let mut mantissa = 0u64;
    let mut digits = 0usize;
    let mut decimals = None;
    for (i, &b) in body.iter().enumerate() {
        match b {
            b'0'..=b'9' => {
                mantissa = mantissa * 10 + u64::from(b - b'0');
                digits += 1;
                if digits > 15 {
                    return None;
                }
            }
            b'.' if decimals.is_none() => decimals = Some(body.len() - i - 1),
            _ => return None,
        }
    }
    if digits == 0 {
        return None;
    }
    let value = mantissa as f64 / *EXACT_POWERS_OF_TEN.get(decimals.unwrap_or(0))?;
    Some(if negative { -value } else { value })
}

/// At most 32 characters of an ASCII field, for error messages.
fn truncate_bytes(field: &[u8]) -> String {
    String::from_utf8_lossy(&field[..field.len().min(32)]).into_owned()
}

/// At most 32 characters of a field, for error messages.
fn truncate(field: &str) -> String {
    field.chars().take(32).collect()
}

/// Writes absolute coordinates, one `x y z` line per point, to 0.1 mm.
pub(super) fn write<W: Write>(cloud: &PointCloud, mut out: W) -> Result<(), CloudError> {
    for i in 0..cloud.len() {
        let p = cloud.absolute(i);
        writeln!(out, "{:.4} {:.4} {:.4}", p.x, p.y, p.z)?;
    }
    out.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    /// Lines from the characters that matter to the parser: digits, signs,
    /// points, exponents, separators, comments and the words `inf`/`NaN`.
    fn line() -> impl Strategy<Value = String> {
        let piece = prop_oneof![
            "[-+]?[0-9]{0,18}[.]?[0-9]{0,18}",
            "[-+]?[0-9]{1,3}[.][0-9]{1,4}[eE][-+]?[0-9]{1,3}",
            Just("inf".to_owned()),
            Just("NaN".to_owned()),
            "[ ,\t\x0b\x0c\r#/a]{1,2}",
        ];
        prop::collection::vec(piece, 0..9).prop_map(|p| p.concat())
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4000))]

        /// The byte parser of ASCII lines gives what the `str` parser gives:
        /// the same point (bit for bit), the same blank line, the same error.
        #[test]
        fn ascii_lines_parse_as_text_lines(text in line()) {
            let bytes = parse_line(text.as_bytes());
            let chars = parse_text_line(&text);
            match (bytes, chars) {
                (Ok(Some(a)), Ok(Some(b))) => {
                    for (x, y) in a.to_array().into_iter().zip(b.to_array()) {
                        prop_assert!(x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()));
                    }
                }
                (a, b) => prop_assert_eq!(a, b),
            }
        }

        /// Coordinates written with any number of decimals read back as
        /// `str::parse` reads them.
        #[test]
        fn decimals_parse_as_the_standard_parser(v in -1e7f64..1e7, decimals in 0usize..12) {
            let text = format!("{v:.decimals$}");
            let std: f64 = text.parse().expect("a number");
            let fast = parse_decimal(text.as_bytes()).expect("a number");
            prop_assert_eq!(fast.to_bits(), std.to_bits(), "{}", text);
        }
    }

    #[test]
    fn fast_path_takes_plain_decimals_only() {
        assert_eq!(fast_decimal(b"-12.5"), Some(-12.5));
        assert_eq!(fast_decimal(b"+.5"), Some(0.5));
        assert_eq!(fast_decimal(b"7."), Some(7.0));
        assert_eq!(
            fast_decimal(b"-0").map(f64::to_bits),
            Some((-0.0f64).to_bits())
        );
        for other in [
            &b"."[..],
            b"-",
            b"1e3",
            b"1.2.3",
            b"inf",
            b"1234567890123456",
        ] {
            assert_eq!(
                fast_decimal(other),
                None,
                "{:?}",
                std::str::from_utf8(other)
            );
        }
        assert_eq!(parse_decimal(b"1e3"), Some(1000.0));
        assert_eq!(
            parse_decimal(b"1234567890123456.5"),
            Some(1_234_567_890_123_456.5)
        );
    }

    #[test]
    fn lines_with_other_text_are_read_as_before() {
        assert_eq!(
            parse_line("1 2 3 # Ü".as_bytes()),
            Ok(Some(DVec3::new(1.0, 2.0, 3.0)))
        );
        assert_eq!(
            parse_line("\u{a0}1 2 3\u{a0}".as_bytes()),
            Ok(Some(DVec3::new(1.0, 2.0, 3.0)))
        );
        assert_eq!(parse_line(b"1 2 \xff"), Err("not UTF-8 text".to_owned()));
        assert_eq!(
            parse_line(b"\x0b1,2,3\x0b"),
            Ok(Some(DVec3::new(1.0, 2.0, 3.0)))
        );
    }
}
