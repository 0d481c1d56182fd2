//! CityJSON 2.0 and CityJSONSeq output (issue 5).
//!
//! Will hold SolitaryVegetationObject documents with one geometry per LOD and
//! CityJSONFeature lines for many trees. No IO.
