//! Output files shared by `silva reconstruct` and `silva export`: skeleton
//! (JSON or PLY), branch mesh (OBJ, PLY, GLB) at one LOD, CityJSON 2.0 with
//! every LOD, and the TreeQSM-style cylinder table. Formats follow the file
//! extension; the writers themselves live in `silva::mesh` and
//! `silva::cityjson`, so the CLI and the service produce identical bytes.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use serde_json::{Map, Value};
use silva::Skeleton;
use silva::cityjson::{TreeInfo, city_json};
use silva::mesh::{Lod, MeshFormat, build_mesh, cylinder_table_csv};

/// Output flags common to the commands that produce a skeleton.
#[derive(Debug, clap::Args)]
pub struct Outputs {
    /// Skeleton file: `.json` (silva skeleton) or `.ply` (absolute x y z, radius, edges).
    #[arg(long)]
    skeleton: Option<PathBuf>,
    /// Branch mesh: `.obj`, `.ply` or `.glb`.
    #[arg(long)]
    mesh: Option<PathBuf>,
    /// Level of detail of `--mesh` (0 = trunk and first-order branches … 3 = every branch).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u8).range(0..=3))]
    lod: u8,
    /// CityJSON 2.0 file with one geometry per LOD.
    #[arg(long)]
    cityjson: Option<PathBuf>,
    /// TreeQSM-style cylinder table (CSV).
    #[arg(long)]
    cylinders: Option<PathBuf>,
}

impl Outputs {
    /// True when no output was asked for.
    pub fn is_empty(&self) -> bool {
        self.skeleton.is_none()
            && self.mesh.is_none()
            && self.cityjson.is_none()
            && self.cylinders.is_none()
    }

    /// Checks the extensions before any work is done.
    pub fn validate(&self) -> anyhow::Result<()> {
        if let Some(p) = &self.skeleton {
            if !matches!(extension(p).as_deref(), Some("json" | "ply")) {
                bail!(
                    "{}: the skeleton file must end in .json or .ply",
                    p.display()
                );
            }
        }
        if let Some(p) = &self.mesh {
            mesh_format(p)?;
        }
        Ok(())
    }

    /// Writes every requested file. `attributes` are the tree's metrics for CityJSON.
    pub fn write(
        &self,
        skeleton: &Skeleton,
        species: Option<String>,
        attributes: Map<String, Value>,
    ) -> anyhow::Result<()> {
        if let Some(p) = &self.skeleton {
            let bytes = match extension(p).as_deref() {
                Some("ply") => skeleton.to_ply(),
                _ => skeleton.to_json().into_bytes(),
            };
            write(p, &bytes)?;
        }
        if let Some(p) = &self.mesh {
            let lod = Lod::from_level(self.lod).expect("clap keeps --lod in 0..=3");
            let mesh = build_mesh(skeleton, lod);
            let origin = skeleton.anchor().origin;
            write(p, &mesh_format(p)?.encode(&mesh, skeleton.anchor(), origin))?;
        }
        if let Some(p) = &self.cityjson {
            let tree = TreeInfo {
                id: "tree-1".into(),
                skeleton,
                species,
                attributes,
            };
            let doc = city_json(&tree, &[Lod::L0, Lod::L1, Lod::L2, Lod::L3]);
            write(p, serde_json::to_string(&doc)?.as_bytes())?;
        }
        if let Some(p) = &self.cylinders {
            write(p, cylinder_table_csv(skeleton).as_bytes())?;
        }
        Ok(())
    }
}

fn extension(path: &Path) -> Option<String> {
    path.extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
}

fn mesh_format(path: &Path) -> anyhow::Result<MeshFormat> {
    extension(path)
        .as_deref()
        .and_then(MeshFormat::from_extension)
        .with_context(|| {
            format!(
                "{}: the mesh file must end in .obj, .ply or .glb",
                path.display()
            )
        })
}

/// Writes a file, naming it in the error.
pub fn write(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    std::fs::write(path, bytes).with_context(|| format!("writing {}", path.display()))
}
