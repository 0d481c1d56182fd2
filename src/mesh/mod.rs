//! Branch meshes and LOD levels (issue 5).
//!
//! Will hold generalised-cylinder meshes with rotation-minimising frames, the
//! LOD 0–3 definitions, and OBJ, PLY and glTF (GLB) writers. No IO.
