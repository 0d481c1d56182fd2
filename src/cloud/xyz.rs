//! XYZ/TXT text reader and writer: one point per line, `x y z` first.
//!
//! Fields are separated by spaces, tabs or commas; columns after the third
//! are ignored; `#` starts a comment (so does a leading `//`, which is how
//! CloudCompare writes its column header); blank lines are skipped and the
//! last line may lack its newline. Lines are read with a length cap, so a
//! file without newlines cannot make the reader buffer it whole.

use std::io::{BufRead, BufReader, Read, Write};

use glam::DVec3;

use super::read::{Attributes, CloudBuilder, ReadOptions};
use super::{CloudError, Format, Location, PointCloud};

/// Longest accepted line in bytes; real XYZ lines are under 200.
const MAX_LINE: usize = 4096;

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
        if let Some(p) = parse_line(&line).map_err(|reason| malformed(location, reason))? {
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
fn parse_line(raw: &[u8]) -> Result<Option<DVec3>, String> {
    let text = std::str::from_utf8(raw).map_err(|_| "not UTF-8 text".to_owned())?;
    let data = text.split('#').next().unwrap_or_default().trim();
    if data.is_empty() || data.starts_with("//") {
        return Ok(None);
    }
    let mut fields = data
        .split(|c: char| c == ',' || c.is_ascii_whitespace())
        .filter(|f| !f.is_empty());
    let mut xyz = [0.0f64; 3];
    for (i, v) in xyz.iter_mut().enumerate() {
        let field = fields
            .next()
            .ok_or_else(|| format!("expected 3 coordinates, found {i}"))?;
        *v = field
            .parse::<f64>()
            .map_err(|_| format!("not a number: {:?}", truncate(field)))?;
    }
    Ok(Some(DVec3::from_array(xyz)))
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
