//! The reconstruction record of a model: which pipeline ran and why, the
//! best efforts it flagged, and the error bounds its encodings state.
//!
//! A job writes it as the `parameters` JSON of the model (see
//! [`super::process`]) and the API serves it with the tree, so that a client
//! can tell a measured DBH from an estimated one. Rows written by older
//! versions may lack any part of it: every field is optional or defaults, and
//! a part that no longer parses reads as absent rather than failing the
//! whole record.

use serde::de::DeserializeOwned;
use serde::{Deserialize, Deserializer, Serialize};
use utoipa::ToSchema;

use crate::encode::lsystem::ErrorBound;
use crate::reconstruct::Mode;

/// How a model was made and how far its encodings may be off.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ModelRecord {
    /// The pipeline that ran: `dense` (terrestrial/mobile) or `airborne`.
    #[serde(default, deserialize_with = "lenient")]
    #[schema(value_type = Option<String>, example = "airborne")]
    pub mode: Option<Mode>,
    /// Why that pipeline ran, in words (the survey of the cloud, or the
    /// mode asked for at upload).
    #[serde(default, deserialize_with = "lenient")]
    pub mode_reason: Option<String>,
    /// Best efforts the reconstruction flagged, in words: stray returns
    /// dropped, a trunk radius estimated by allometry rather than fitted, a
    /// height extrapolated to the apex, …
    #[serde(default, deserialize_with = "lenient_or_default")]
    pub notes: Vec<String>,
    /// Settings and error of the L-system encoding (LsJSON).
    #[serde(default, deserialize_with = "lenient")]
    pub lsystem: Option<LsystemRecord>,
    /// Settings and error bound of the DBF6 chain code.
    #[serde(default, deserialize_with = "lenient")]
    pub chaincode: Option<ChainCodeRecord>,
}

/// Settings and error of the LsJSON encoding of a model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct LsystemRecord {
    /// Position tolerance the writer was given, metres.
    pub tolerance_m: f32,
    /// Radius tolerance of thin branches the writer was given, metres.
    pub radius_tolerance_m: f32,
    /// The stated bounds and the measured error of the document.
    pub error: ErrorBound,
}

/// Settings and error bound of the chain code of a model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ChainCodeRecord {
    /// Voxel edge length `d`, metres.
    pub voxel_size_m: f64,
    /// The resolution `r` the voxel size came from (`d = l̄ / r`).
    pub resolution: Option<f32>,
    /// Radius quantisation step, metres.
    pub radius_step_m: f32,
    /// Guaranteed bound on a decoded node's distance from the original,
    /// `√3·d/2`, metres.
    pub error_bound_m: f64,
}

impl ModelRecord {
    /// The record stored as `text`; what does not parse reads as absent.
    pub fn parse(text: &str) -> Self {
        serde_json::from_str(text).unwrap_or_default()
    }
}

/// Deserializes `T`, or `None` when the value is null or does not parse.
fn lenient<'de, D: Deserializer<'de>, T: DeserializeOwned>(d: D) -> Result<Option<T>, D::Error> {
    let value = serde_json::Value::deserialize(d)?;
    Ok(serde_json::from_value(value).ok())
}

/// Deserializes `T`, or its default when the value does not parse.
fn lenient_or_default<'de, D: Deserializer<'de>, T: DeserializeOwned + Default>(
    d: D,
) -> Result<T, D::Error> {
    Ok(lenient(d)?.unwrap_or_default())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn old_or_partial_records_still_read() {
        assert_eq!(ModelRecord::parse("{}"), ModelRecord::default());
        assert_eq!(ModelRecord::parse("not json"), ModelRecord::default());
        let partial = ModelRecord::parse(
            r#"{"mode": "dense", "notes": ["1 stray return ignored"],
                "lsystem": {"tolerance_m": 0.001}, "chaincode": 7, "extra": true}"#,
        );
        assert_eq!(partial.mode, Some(Mode::Dense));
        assert_eq!(partial.notes, ["1 stray return ignored"]);
        assert_eq!(partial.mode_reason, None);
        assert_eq!(partial.lsystem, None);
        assert_eq!(partial.chaincode, None);
        let odd = ModelRecord::parse(r#"{"mode": "sideways", "notes": "one"}"#);
        assert_eq!((odd.mode, odd.notes.len()), (None, 0));
    }
}
