//! URDF import: the kinematic tree, visual meshes (STL, OBJ, glTF/GLB, DAE
//! and the box, cylinder and sphere primitives), `package://` resolution.

use std::path::{Path, PathBuf};

use glam::{DAffine3, DMat3, DQuat, DVec3};

use crate::core::geometry::mesh::TriMesh;
use crate::core::geometry::primitives::{self, Primitive};
use crate::core::robot::model::{JointKind, JointLimits, JointSpec, LinkSpec, Robot, RobotError};
use crate::core::robot::spatial::Inertial;
use crate::io::guard;
use crate::io::mesh::{MeshError, check_extent, load_mesh};

/// Facets around the round URDF primitives.
const PRIMITIVE_SEGMENTS: usize = 32;

/// The most links (and joints) a URDF may have.
pub const MAX_LINKS: usize = 10_000;

/// How many folders above a URDF's own `package://` URIs are looked for in.
pub const PACKAGE_SEARCH_LEVELS: usize = 6;

/// Which links' visual meshes to read.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub enum MeshSelection {
    /// Every link's (for display).
    #[default]
    All,
    /// None: kinematics only (torques need no surface).
    None,
    /// Only these links'.
    Links(Vec<String>),
}

/// Options of [`load_urdf`].
#[derive(Debug, Clone, Default)]
pub struct UrdfOptions {
    /// Extra folders searched for `package://` URIs (a package named `p`
    /// is looked for as `DIR/p/...` and the rest of the URI under `DIR`).
    pub package_paths: Vec<PathBuf>,
    /// Which meshes to read.
    pub meshes: MeshSelection,
}

/// Why a URDF could not be imported.
#[derive(Debug, thiserror::Error)]
pub enum UrdfError {
    /// The file could not be read.
    #[error("{path}: cannot read the URDF: {cause}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The system's reason.
        cause: std::io::Error,
    },
    /// The XML is not a URDF.
    #[error("{path}: not a valid URDF: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// The parser's message.
        message: String,
    },
    /// A joint type we do not model.
    #[error(
        "{path}: joint '{joint}' is of type {kind}, which is not supported (revolute, continuous, prismatic and fixed are)"
    )]
    UnsupportedJoint {
        /// The file.
        path: PathBuf,
        /// The joint.
        joint: String,
        /// Its type.
        kind: String,
    },
    /// A mesh file named by a link was not found.
    #[error("{path}: link '{link}' <visual> mesh '{filename}' not found (looked for {tried})")]
    MissingMesh {
        /// The URDF.
        path: PathBuf,
        /// The link.
        link: String,
        /// The filename as written.
        filename: String,
        /// Where we looked.
        tried: String,
    },
    /// A mesh file could not be read.
    #[error("{path}: link '{link}' <visual>: {cause}")]
    Mesh {
        /// The URDF.
        path: PathBuf,
        /// The link.
        link: String,
        /// The mesh error (names the mesh file).
        cause: MeshError,
    },
    /// A value that is not finite or not positive where it must be.
    #[error("{path}: link '{link}' <visual> {what} is invalid: {value}")]
    BadGeometry {
        /// The URDF.
        path: PathBuf,
        /// The link.
        link: String,
        /// Which value.
        what: String,
        /// The value as read.
        value: String,
    },
    /// An `<inertial>` with a negative mass or a number that is not finite.
    #[error(
        "{path}: link '{link}' <inertial> is invalid (mass {mass_kg} kg; the mass must be ≥ 0 and every number finite)"
    )]
    BadInertial {
        /// The URDF.
        path: PathBuf,
        /// The link.
        link: String,
        /// Its mass as read.
        mass_kg: f64,
    },
    /// The tree is not a valid robot.
    #[error("{path}: {cause}")]
    Robot {
        /// The URDF.
        path: PathBuf,
        /// What is wrong (names the joint or link).
        cause: RobotError,
    },
}

/// The rigid transform of a URDF `<origin xyz rpy>` (fixed axes: roll
/// about x, then pitch about y, then yaw about z).
#[must_use]
pub fn origin_transform(xyz: [f64; 3], rpy: [f64; 3]) -> DAffine3 {
    let rotation = DQuat::from_rotation_z(rpy[2]) * DQuat::from_rotation_y(rpy[1]) * DQuat::from_rotation_x(rpy[0]);
    DAffine3::from_rotation_translation(rotation, DVec3::from_array(xyz))
}

/// A link's `<inertial>`: the inertia tensor turned from the `<origin>`'s
/// axes into the link's. A link without one has the zero inertial.
fn inertial(given: &urdf_rs::Inertial, link: &str, path: &Path) -> Result<Inertial, UrdfError> {
    let i = &given.inertia;
    let com_frame = origin_transform(*given.origin.xyz, *given.origin.rpy);
    let about_com_in_origin_axes =
        DMat3::from_cols_array(&[i.ixx, i.ixy, i.ixz, i.ixy, i.iyy, i.iyz, i.ixz, i.iyz, i.izz]);
    let result = Inertial {
        mass_kg: given.mass.value,
        com_in_link_m: com_frame.translation,
        inertia_about_com: com_frame.matrix3 * about_com_in_origin_axes * com_frame.matrix3.transpose(),
    };
    if result.is_valid() {
        Ok(result)
    } else {
        Err(UrdfError::BadInertial {
            path: path.to_owned(),
            link: link.to_owned(),
            mass_kg: given.mass.value,
        })
    }
}

/// Reads a URDF file into a [`Robot`].
pub fn load_urdf(path: &Path, options: &UrdfOptions) -> Result<Robot, UrdfError> {
    let text = std::fs::read_to_string(path).map_err(|cause| UrdfError::Read {
        path: path.to_owned(),
        cause,
    })?;
    read_urdf(&text, path, options)
}

/// A URDF's text into a [`Robot`]; `path` names it in errors and is where
/// its relative mesh paths start.
pub fn read_urdf(text: &str, path: &Path, options: &UrdfOptions) -> Result<Robot, UrdfError> {
    let parse_error = |message: String| UrdfError::Parse {
        path: path.to_owned(),
        message,
    };
    if text.len() as u64 > guard::MAX_FILE_BYTES {
        return Err(parse_error(format!(
            "{} bytes, more than the limit of {}",
            text.len(),
            guard::MAX_FILE_BYTES
        )));
    }
    // The URDF reader recurses per level of nesting: a file nested
    // thousands deep would overflow its stack, so it is refused first.
    let depth = guard::xml_depth(text);
    if depth > guard::MAX_XML_DEPTH {
        return Err(parse_error(format!(
            "elements nested {depth} deep, more than the limit of {}",
            guard::MAX_XML_DEPTH
        )));
    }
    let urdf = guard::isolated(|| urdf_rs::read_from_string(text))
        .map_err(&parse_error)?
        .map_err(|e| parse_error(e.to_string()))?;
    if urdf.links.len() > MAX_LINKS || urdf.joints.len() > MAX_LINKS {
        return Err(parse_error(format!(
            "{} links and {} joints, more than the limit of {MAX_LINKS}",
            urdf.links.len(),
            urdf.joints.len()
        )));
    }
    // Relative to an absolute folder: `package://` search climbs from it.
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_owned());
    let path = absolute.as_path();
    let mut links = Vec::with_capacity(urdf.links.len());
    for link in &urdf.links {
        let wanted = match &options.meshes {
            MeshSelection::All => true,
            MeshSelection::None => false,
            MeshSelection::Links(names) => names.contains(&link.name),
        };
        let mut mesh = TriMesh::default();
        if wanted {
            for visual in &link.visual {
                mesh.append(&visual_mesh(visual, &link.name, path, options)?);
            }
        }
        links.push(LinkSpec {
            name: link.name.clone(),
            mesh,
            segment: None,
            inertial: inertial(&link.inertial, &link.name, path)?,
        });
    }
    let joints = urdf
        .joints
        .iter()
        .map(|j| joint_spec(j, path))
        .collect::<Result<Vec<_>, _>>()?;
    Robot::new(&urdf.name, &links, &joints).map_err(|cause| UrdfError::Robot {
        path: path.to_owned(),
        cause,
    })
}

/// One `<visual>` element's surface in its link's frame.
fn visual_mesh(visual: &urdf_rs::Visual, link: &str, path: &Path, options: &UrdfOptions) -> Result<TriMesh, UrdfError> {
    let bad = |what: &str, value: String| UrdfError::BadGeometry {
        path: path.to_owned(),
        link: link.to_owned(),
        what: what.to_owned(),
        value,
    };
    let positive = |what: &str, v: f64| {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(bad(what, v.to_string()))
        }
    };
    let origin = origin_transform(*visual.origin.xyz, *visual.origin.rpy);
    if !origin.is_finite() {
        return Err(bad(
            "<origin>",
            format!("{:?} {:?}", *visual.origin.xyz, *visual.origin.rpy),
        ));
    }
    let along_z = |half: f64| (DVec3::new(0.0, 0.0, -half), DVec3::new(0.0, 0.0, half));
    let part = match &visual.geometry {
        urdf_rs::Geometry::Box { size } => {
            let size = DVec3::from_array(**size);
            if !(size.is_finite() && size.min_element() > 0.0) {
                return Err(bad("<box size>", format!("{size}")));
            }
            primitives::cuboid(size)
        }
        urdf_rs::Geometry::Cylinder { radius, length } => {
            let (from, to) = along_z(0.5 * positive("<cylinder length>", *length)?);
            let radius = positive("<cylinder radius>", *radius)?;
            Primitive::Cylinder { from, to, radius }.mesh(PRIMITIVE_SEGMENTS)
        }
        urdf_rs::Geometry::Capsule { radius, length } => {
            let (from, to) = along_z(0.5 * positive("<capsule length>", *length)?);
            let radius = positive("<capsule radius>", *radius)?;
            Primitive::Capsule { from, to, radius }.mesh(PRIMITIVE_SEGMENTS)
        }
        urdf_rs::Geometry::Sphere { radius } => {
            primitives::sphere(positive("<sphere radius>", *radius)?, PRIMITIVE_SEGMENTS)
        }
        urdf_rs::Geometry::Mesh { filename, scale } => {
            let folder = path.parent().unwrap_or(Path::new("."));
            let file = resolve_mesh_path(filename, folder, &options.package_paths).map_err(|tried| {
                UrdfError::MissingMesh {
                    path: path.to_owned(),
                    link: link.to_owned(),
                    filename: filename.clone(),
                    tried: tried
                        .iter()
                        .map(|p| p.display().to_string())
                        .collect::<Vec<_>>()
                        .join(", "),
                }
            })?;
            let mesh = load_mesh(&file).map_err(|cause| UrdfError::Mesh {
                path: path.to_owned(),
                link: link.to_owned(),
                cause,
            })?;
            let s = scale.map_or(DVec3::ONE, |s| DVec3::from_array(*s));
            if !s.is_finite() || s.x * s.y * s.z == 0.0 {
                return Err(bad("<mesh scale>", format!("{s}")));
            }
            mesh.transformed(&DAffine3::from_scale(s))
        }
    };
    let part = part.transformed(&origin);
    check_extent(&part, path, &format!("link '{link}' <visual>")).map_err(|cause| UrdfError::Mesh {
        path: path.to_owned(),
        link: link.to_owned(),
        cause,
    })?;
    Ok(part)
}

/// A URDF joint as a [`JointSpec`].
fn joint_spec(j: &urdf_rs::Joint, path: &Path) -> Result<JointSpec, UrdfError> {
    let kind = match j.joint_type {
        urdf_rs::JointType::Revolute => JointKind::Revolute,
        urdf_rs::JointType::Continuous => JointKind::Continuous,
        urdf_rs::JointType::Prismatic => JointKind::Prismatic,
        urdf_rs::JointType::Fixed => JointKind::Fixed,
        ref other => {
            return Err(UrdfError::UnsupportedJoint {
                path: path.to_owned(),
                joint: j.name.clone(),
                kind: format!("{other:?}").to_lowercase(),
            });
        }
    };
    let limits = match kind {
        JointKind::Revolute | JointKind::Prismatic => Some(JointLimits {
            lower: j.limit.lower,
            upper: j.limit.upper,
        }),
        JointKind::Continuous | JointKind::Fixed => None,
    };
    Ok(JointSpec {
        name: j.name.clone(),
        kind,
        parent: j.parent.link.clone(),
        child: j.child.link.clone(),
        parent_from_joint: origin_transform(*j.origin.xyz, *j.origin.rpy),
        axis: DVec3::from_array(*j.axis.xyz),
        limits,
        mimic: j
            .mimic
            .as_ref()
            .map(|m| (m.joint.clone(), m.multiplier.unwrap_or(1.0), m.offset.unwrap_or(0.0))),
    })
}

/// Where a URDF mesh filename points: `package://` by the longest suffix
/// that exists under the URDF's folder or one of its ancestors up to
/// [`PACKAGE_SEARCH_LEVELS`] above it (or under a package path), `file://` and plain paths relative to the URDF's folder.
/// On failure, the places looked at.
pub fn resolve_mesh_path(
    filename: &str,
    urdf_folder: &Path,
    package_paths: &[PathBuf],
) -> Result<PathBuf, Vec<PathBuf>> {
    let mut tried = Vec::new();
    if let Some(rest) = filename.strip_prefix("package://") {
        let parts: Vec<&str> = rest.split('/').filter(|p| !p.is_empty()).collect();
        // Package paths first: DIR/<package>/<rest>, then the suffixes below.
        for dir in package_paths {
            let candidate = parts.iter().fold(dir.clone(), |p, part| p.join(part));
            if candidate.is_file() {
                return Ok(candidate);
            }
            tried.push(candidate);
        }
        let mut roots: Vec<PathBuf> = urdf_folder
            .ancestors()
            .take(PACKAGE_SEARCH_LEVELS + 1)
            .map(Path::to_path_buf)
            .collect();
        if roots.first().is_some_and(|r| r.as_os_str().is_empty()) {
            roots[0] = PathBuf::from(".");
        }
        roots.extend(package_paths.iter().cloned());
        for start in 0..parts.len() {
            for root in &roots {
                let candidate = parts[start..].iter().fold(root.clone(), |p, part| p.join(part));
                if candidate.is_file() {
                    return Ok(candidate);
                }
            }
            if start == 0 {
                tried.push(urdf_folder.join(parts.join("/")));
            }
        }
        tried.push(PathBuf::from(format!(
            "every suffix of '{rest}' under {} and {PACKAGE_SEARCH_LEVELS} folders above it",
            urdf_folder.display()
        )));
        return Err(tried);
    }
    let plain = filename.strip_prefix("file://").unwrap_or(filename);
    let candidate = urdf_folder.join(plain);
    if candidate.is_file() {
        Ok(candidate)
    } else {
        tried.push(candidate);
        Err(tried)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rpy_is_roll_then_pitch_then_yaw_about_fixed_axes() {
        let t = origin_transform(
            [0.0; 3],
            [std::f64::consts::FRAC_PI_2, 0.0, std::f64::consts::FRAC_PI_2],
        );
        // Roll maps y to z; yaw then leaves z alone.
        assert!((t.transform_vector3(DVec3::Y) - DVec3::Z).length() < 1e-12);
        // Roll leaves x alone; yaw maps x to y.
        assert!((t.transform_vector3(DVec3::X) - DVec3::Y).length() < 1e-12);
    }
}
