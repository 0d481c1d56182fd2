//! Compact skeleton encodings (issue 4).
//!
//! The L-system writer/reader (LsJSON, lsystem-from-adtree-skeletons
//! §3.2–3.3) and the DBF6 chain code with LOD reduction and interpolative
//! compression (chain-code-tree-compression-lod §3), and [`decode_stored`],
//! which reads any file form of a skeleton recognised by content. No IO.

pub mod chaincode;
pub mod lsystem;

use crate::Skeleton;

/// Reads a skeleton from any of its file forms, recognised by content (as
/// `silva encode`, `silva decode` and `silva export` do): a chain code starts
/// with the `SLVC` magic (either byte form), a skeleton PLY (silva's or
/// AdTree's, [`Skeleton::from_ply`]) with the line `ply`, a silva skeleton
/// JSON names the format `"silva-skeleton"`, any other text is LsJSON. Every
/// reader runs with its default limits ([`chaincode::Limits`],
/// [`lsystem::Limits`], [`crate::skeleton::MAX_PLY_NODES`]), so hostile bytes
/// give a typed error, never an unbounded expansion.
pub fn decode_stored(bytes: &[u8]) -> crate::Result<Skeleton> {
    if bytes.starts_with(b"ply\n") || bytes.starts_with(b"ply\r\n") {
        return Ok(Skeleton::from_ply(bytes)?);
    }
    if chaincode::is_chain_code(bytes) {
        return Ok(chaincode::decode_bytes(
            bytes,
            &chaincode::Limits::default(),
        )?);
    }
    let text = std::str::from_utf8(bytes).map_err(|_| lsystem::LsError::Invalid {
        field: "document",
        reason: "is neither a chain code nor UTF-8 text",
    })?;
    if text.contains("\"silva-skeleton\"") {
        return Ok(Skeleton::from_json(text)?);
    }
    let limits = lsystem::Limits::default();
    let ls = lsystem::LsJson::parse(text, &limits)?;
    Ok(lsystem::decode(&ls, &limits)?)
}

/// Length of `bytes` after gzip at maximum compression: the "gzip" size
/// that issue 4 reports beside each encoding's own (in memory, no IO).
pub fn gzip_len(bytes: &[u8]) -> usize {
    use std::io::Write;
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    gz.write_all(bytes).expect("writing to memory cannot fail");
    gz.finish().expect("writing to memory cannot fail").len()
}
