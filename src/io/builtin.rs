//! Robots by name or by URDF path; the built-in LWR's meshes ship as
//! `assets/lwr4plus.glb`, written by `proprioscope export-assets` and read
//! back through the glTF reader at start-up.

use std::path::{Path, PathBuf};

use crate::core::robot::builtin;
use crate::core::robot::model::{Robot, RobotError};
use crate::io::mesh::{MeshError, encode_glb, read_gltf_nodes};
use crate::io::urdf::{UrdfError, UrdfOptions, load_urdf};

/// Where the built-in LWR's meshes live in the repository.
pub const LWR4PLUS_GLB_PATH: &str = "assets/lwr4plus.glb";

/// The shipped LWR meshes, compiled into the program.
pub const LWR4PLUS_GLB: &[u8] = include_bytes!("../../assets/lwr4plus.glb");

/// Why a robot could not be had.
#[derive(Debug, thiserror::Error)]
pub enum LoadRobotError {
    /// The shipped asset does not decode.
    #[error("built-in robot '{name}': its asset {asset} is unreadable: {cause}")]
    Asset {
        /// Robot name.
        name: String,
        /// Asset path in the repository.
        asset: String,
        /// What went wrong.
        cause: MeshError,
    },
    /// The built-in description is inconsistent (a bug).
    #[error("built-in robot '{name}': {cause}")]
    Builtin {
        /// Robot name.
        name: String,
        /// What is wrong.
        cause: RobotError,
    },
    /// A URDF failed to import.
    #[error(transparent)]
    Urdf(#[from] UrdfError),
    /// Neither a built-in name nor a file.
    #[error("robot '{spec}' is neither a built-in robot ({}) nor an existing URDF file ({})", builtin::BUILTIN_NAMES.join(", "), path.display())]
    Unknown {
        /// What was asked for.
        spec: String,
        /// The path tried.
        path: PathBuf,
    },
}

/// The bytes `assets/lwr4plus.glb` must hold: the generator's meshes today.
#[must_use]
pub fn lwr4plus_glb_generated() -> Vec<u8> {
    encode_glb(&builtin::lwr4plus_meshes())
}

/// True when `spec` names a built-in robot.
#[must_use]
pub fn is_builtin(spec: &str) -> bool {
    builtin::BUILTIN_NAMES.contains(&spec)
}

/// A built-in robot by name, or a URDF at `spec` (relative to `base_dir`).
pub fn load_robot(spec: &str, base_dir: &Path, options: &UrdfOptions) -> Result<Robot, LoadRobotError> {
    let builtin_error = |cause| LoadRobotError::Builtin {
        name: spec.to_owned(),
        cause,
    };
    match spec {
        "simple6" => builtin::simple6().map_err(builtin_error),
        "lwr4plus" => {
            let meshes =
                read_gltf_nodes(LWR4PLUS_GLB, Path::new(LWR4PLUS_GLB_PATH)).map_err(|cause| LoadRobotError::Asset {
                    name: spec.to_owned(),
                    asset: LWR4PLUS_GLB_PATH.to_owned(),
                    cause,
                })?;
            builtin::lwr4plus_with_meshes(&meshes).map_err(builtin_error)
        }
        _ => {
            let path = base_dir.join(spec);
            if path.is_file() {
                Ok(load_urdf(&path, options)?)
            } else {
                Err(LoadRobotError::Unknown {
                    spec: spec.to_owned(),
                    path,
                })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shipped_lwr_asset_is_exactly_what_the_generator_makes_today() {
        assert!(
            LWR4PLUS_GLB == lwr4plus_glb_generated().as_slice(),
            "{LWR4PLUS_GLB_PATH} is stale: run `cargo run -- export-assets`"
        );
    }

    #[test]
    fn builtin_lwr_loads_its_meshes_from_the_asset() {
        let robot = load_robot("lwr4plus", Path::new("."), &UrdfOptions::default()).unwrap();
        let generated = builtin::lwr4plus_meshes();
        for (name, mesh) in &generated {
            let link = &robot.links[robot.link_id(name).unwrap()];
            assert_eq!(link.mesh.triangles, mesh.triangles, "{name}");
            for (a, b) in link.mesh.positions.iter().zip(&mesh.positions) {
                // Stored as f32.
                assert!((*a - *b).length() < 1e-7, "{name}");
            }
        }
    }

    #[test]
    fn unknown_robot_is_named() {
        let e = load_robot("ur5", Path::new("scenes"), &UrdfOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("ur5") && e.contains("lwr4plus"), "{e}");
    }
}
