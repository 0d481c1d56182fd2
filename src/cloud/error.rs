//! Typed reader errors that name the format and where in the input it failed.

use std::fmt;

/// A point cloud file format silva reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// Whitespace- or comma-separated text, one point per line.
    Xyz,
    /// Stanford PLY, ascii or binary.
    Ply,
    /// ASPRS LAS 1.0–1.4.
    Las,
    /// LASzip-compressed LAS.
    Laz,
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Format::Xyz => "XYZ",
            Format::Ply => "PLY",
            Format::Las => "LAS",
            Format::Laz => "LAZ",
        })
    }
}

/// Where in the input a problem was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Location {
    /// 1-based text line.
    Line(u64),
    /// 0-based byte offset.
    Byte(u64),
    /// 0-based point record.
    Point(u64),
    /// The header as a whole.
    Header,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line(n) => write!(f, "line {n}"),
            Location::Byte(n) => write!(f, "byte {n}"),
            Location::Point(n) => write!(f, "point {n}"),
            Location::Header => f.write_str("header"),
        }
    }
}

/// Why a point cloud could not be read.
#[derive(Debug, thiserror::Error)]
pub enum CloudError {
    /// The input breaks the format's rules at a known place.
    #[error("{format}: {location}: {reason}")]
    Malformed {
        /// The detected format.
        format: Format,
        /// Where the problem is.
        location: Location,
        /// What is wrong, in one line.
        reason: String,
    },
    /// The input is well-formed but holds no points.
    #[error("{0}: the file holds no points")]
    Empty(Format),
    /// The input holds more points than the configured limit.
    #[error("{format}: more than {limit} points (the configured point limit)")]
    TooManyPoints {
        /// The detected format.
        format: Format,
        /// The limit in force.
        limit: usize,
    },
    /// The content matches no supported format.
    #[error("unrecognised point cloud format (expected XYZ text, PLY, LAS or LAZ): {0}")]
    UnknownFormat(String),
    /// The underlying reader failed.
    #[error("reading point cloud: {0}")]
    Io(#[from] std::io::Error),
}
