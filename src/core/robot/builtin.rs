//! Robots built into the program: the thesis' simple robot and the KUKA LWR 4+.

use glam::{DAffine3, DVec3};

use crate::core::geometry::mesh::TriMesh;
use crate::core::geometry::primitives::Primitive;
use crate::core::robot::model::{JointKind, JointLimits, JointSpec, LinkSpec, Robot, RobotError};
use crate::core::robot::spatial::Inertial;

/// Names of the built-in robots.
pub const BUILTIN_NAMES: [&str; 2] = ["simple6", "lwr4plus"];

/// Height of the LWR's joint 1 above its base frame, m. The thesis measures
/// positions from joint 1; our world frame is the base frame, as in the URDF.
pub const LWR_JOINT1_HEIGHT_M: f64 = 0.11;

/// Facets around the round parts of the built-in LWR's primitives.
pub const LWR_SEGMENTS: usize = 40;

/// Radius of the simple robot's display and picking cylinders, m.
pub const SIMPLE6_DISPLAY_RADIUS_M: f64 = 0.03;

fn revolute(name: &str, parent: &str, child: &str, origin: DVec3, axis: DVec3, limit: Option<f64>) -> JointSpec {
    JointSpec {
        name: name.to_owned(),
        kind: if limit.is_some() {
            JointKind::Revolute
        } else {
            JointKind::Continuous
        },
        parent: parent.to_owned(),
        child: child.to_owned(),
        parent_from_joint: DAffine3::from_translation(origin),
        axis,
        limits: limit.map(|l| JointLimits { lower: -l, upper: l }),
        mimic: None,
    }
}

/// A one-joint arm, `base` and `link`, whose moving link is `mesh`: the
/// smallest robot that carries a mesh, for measuring and fuzzing a mesh's
/// way to a surface.
pub fn one_link(name: &str, mesh: TriMesh) -> Result<Robot, RobotError> {
    let links = [
        LinkSpec {
            name: "base".into(),
            ..LinkSpec::default()
        },
        LinkSpec {
            name: "link".into(),
            mesh,
            segment: None,
            ..LinkSpec::default()
        },
    ];
    let joints = [JointSpec {
        kind: JointKind::Revolute,
        ..revolute("joint", "base", "link", DVec3::ZERO, DVec3::Z, None)
    }];
    Robot::new(name, &links, &joints)
}

/// The thesis' simple robot (§3.1.1) as reconstructed in the notes: six
/// revolute joints at (0,0,0), (0,0,1), (1,0,1), (1,1,1), (1,1,2), (2,2,2)
/// with axes +z, +x, +y, +z, +x, +y; one-dimensional links `link_0` …
/// `link_5`, link k from joint k+1 to joint k+2 (the last to the tip at
/// (3,2,2)). Contacts lie on the segments; the thin cylinders are for display.
pub fn simple6() -> Result<Robot, RobotError> {
    // Offset of each joint from the previous one, and the tip's.
    let offsets = [
        DVec3::ZERO,
        DVec3::new(0.0, 0.0, 1.0),
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::new(0.0, 1.0, 0.0),
        DVec3::new(0.0, 0.0, 1.0),
        DVec3::new(1.0, 1.0, 0.0),
        DVec3::new(1.0, 0.0, 0.0),
    ];
    let axes = [DVec3::Z, DVec3::X, DVec3::Y, DVec3::Z, DVec3::X, DVec3::Y];
    let mut links = vec![LinkSpec {
        name: "base".to_owned(),
        ..LinkSpec::default()
    }];
    let mut joints = Vec::new();
    for k in 0..6 {
        let end = offsets[k + 1];
        links.push(LinkSpec {
            name: format!("link_{k}"),
            mesh: Primitive::Capsule {
                from: DVec3::ZERO,
                to: end,
                radius: SIMPLE6_DISPLAY_RADIUS_M,
            }
            .mesh(16),
            segment: Some([DVec3::ZERO, end]),
            ..LinkSpec::default()
        });
        let parent = if k == 0 {
            "base".to_owned()
        } else {
            format!("link_{}", k - 1)
        };
        joints.push(revolute(
            &format!("joint_{}", k + 1),
            &parent,
            &format!("link_{k}"),
            offsets[k],
            axes[k],
            None,
        ));
    }
    Robot::new("simple6", &links, &joints)
}

/// Joint origins of the LWR 4+ (relative to the parent, m) and the thesis'
/// axis convention +z, +y, +z, +y, +z, -y, +z (the public URDF has -y on
/// joint 2, which flips the sign of `tau_2`).
const LWR_JOINTS: [(f64, DVec3, f64); 7] = [
    (LWR_JOINT1_HEIGHT_M, DVec3::Z, 170.0),
    (0.2005, DVec3::Y, 120.0),
    (0.20, DVec3::Z, 170.0),
    (0.20, DVec3::Y, 120.0),
    (0.20, DVec3::Z, 170.0),
    (0.19, DVec3::NEG_Y, 120.0),
    (0.078, DVec3::Z, 170.0),
];

/// Link names of the built-in LWR, base first (as in the public URDF).
pub const LWR_LINKS: [&str; 8] = [
    "lwr_base_link",
    "lwr_1_link",
    "lwr_2_link",
    "lwr_3_link",
    "lwr_4_link",
    "lwr_5_link",
    "lwr_6_link",
    "lwr_7_link",
];

/// The built-in LWR's mean density, kg/m³: its primitives as solids of
/// this density weigh about what the real arm's links do (2–3 kg each).
pub const LWR_DENSITY_KG_M3: f64 = 700.0;

/// The LWR 4+ kinematics with the given link meshes (by link name; links
/// not named get none). Every link's inertial is that of its primitives
/// ([`lwr4plus_primitives`]) as uniform solids of [`LWR_DENSITY_KG_M3`]:
/// plausible dynamics for simulated observers, not the real arm's.
pub fn lwr4plus_with_meshes(meshes: &[(String, TriMesh)]) -> Result<Robot, RobotError> {
    let primitives = lwr4plus_primitives();
    let links: Vec<LinkSpec> = LWR_LINKS
        .iter()
        .map(|name| LinkSpec {
            inertial: primitives
                .iter()
                .find(|(n, _)| n == name)
                .map_or_else(Inertial::default, |(_, parts)| {
                    let solids: Vec<TriMesh> = parts.iter().map(|p| p.mesh(LWR_SEGMENTS)).collect();
                    Inertial::of_solids(&solids, LWR_DENSITY_KG_M3)
                }),
            name: (*name).to_owned(),
            mesh: meshes
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, m)| m.clone())
                .unwrap_or_default(),
            segment: None,
        })
        .collect();
    let joints: Vec<JointSpec> = LWR_JOINTS
        .iter()
        .enumerate()
        .map(|(k, &(height, axis, limit_deg))| {
            revolute(
                &format!("lwr_joint_{}", k + 1),
                LWR_LINKS[k],
                LWR_LINKS[k + 1],
                DVec3::new(0.0, 0.0, height),
                axis,
                Some(limit_deg.to_radians()),
            )
        })
        .collect();
    Robot::new("lwr4plus", &links, &joints)
}

/// The LWR 4+ kinematics without meshes (for torque-only work and tests).
pub fn lwr4plus_kinematics() -> Result<Robot, RobotError> {
    lwr4plus_with_meshes(&[])
}

/// The LWR 4+ with meshes generated now from [`lwr4plus_primitives`]
/// (the program itself loads the same meshes from `assets/lwr4plus.glb`).
pub fn lwr4plus_generated() -> Result<Robot, RobotError> {
    lwr4plus_with_meshes(&lwr4plus_meshes())
}

/// The signed distance (m, negative inside) from `p`, in the frame of the
/// link named `link`, to the union of that link's primitives in `shapes`
/// ([`lwr4plus_primitives`]); `None` for a link without primitives. The
/// exact shape the tests hold the generated meshes and tables against.
#[cfg(test)]
pub(crate) fn primitives_signed_distance(shapes: &[(&str, Vec<Primitive>)], link: &str, p: DVec3) -> Option<f64> {
    shapes
        .iter()
        .find(|(name, _)| *name == link)
        .map(|(_, parts)| parts.iter().map(|q| q.signed_distance(p)).fold(f64::INFINITY, f64::min))
}

/// The built-in LWR's shape: per link, rounded primitives sized to the real
/// arm's meshes (links 1–5 are 12 cm tubes whose joint housings sit off the
/// axis on alternating sides; link 6 is a ball, link 7 the flange).
#[must_use]
pub fn lwr4plus_primitives() -> Vec<(&'static str, Vec<Primitive>)> {
    const R: f64 = 0.06;
    // The housings' rims are rounded like the real arm's.
    const FILLET: f64 = 0.02;
    let v = DVec3::new;
    // A link that starts at a z-axis joint and ends at a y-axis joint `h`
    // above, whose housing bulges to side `s`.
    let to_y_joint = |h: f64, s: f64| {
        vec![
            Primitive::Cylinder {
                from: v(0.0, 0.0, -0.008),
                to: v(0.0, 0.0, 0.06),
                radius: R,
            },
            Primitive::Capsule {
                from: v(0.0, 0.0, 0.06),
                to: v(0.0, s * 0.035, h - 0.045),
                radius: R,
            },
            Primitive::RoundedCylinder {
                from: v(0.0, s * 0.004, h),
                to: v(0.0, s * 0.094, h),
                radius: R,
                fillet: FILLET,
            },
        ]
    };
    // A link that starts at a y-axis joint (housing on side `s`) and ends
    // at a z-axis joint 0.2 m above.
    let from_y_joint = |s: f64| {
        vec![
            Primitive::RoundedCylinder {
                from: v(0.0, -s * 0.006, 0.0),
                to: v(0.0, s * 0.094, 0.0),
                radius: R,
                fillet: FILLET,
            },
            Primitive::Capsule {
                from: v(0.0, s * 0.035, 0.045),
                to: v(0.0, 0.0, 0.14),
                radius: R,
            },
            Primitive::Cylinder {
                from: v(0.0, 0.0, 0.14),
                to: v(0.0, 0.0, 0.1915),
                radius: R,
            },
        ]
    };
    vec![
        (
            LWR_LINKS[0],
            vec![Primitive::Cylinder {
                from: v(0.0, 0.0, 0.0),
                to: v(0.0, 0.0, 0.102),
                radius: 0.08,
            }],
        ),
        (LWR_LINKS[1], to_y_joint(0.2005, 1.0)),
        (LWR_LINKS[2], from_y_joint(-1.0)),
        (LWR_LINKS[3], to_y_joint(0.20, -1.0)),
        (LWR_LINKS[4], from_y_joint(1.0)),
        (LWR_LINKS[5], to_y_joint(0.19, 1.0)),
        (
            LWR_LINKS[6],
            vec![Primitive::Sphere {
                center: v(0.0, -0.012, 0.0),
                radius: 0.07,
            }],
        ),
        (
            LWR_LINKS[7],
            vec![Primitive::RoundedCylinder {
                from: v(0.0, 0.0, -0.031),
                to: v(0.0, 0.0, 0.0),
                radius: 0.04,
                fillet: 0.005,
            }],
        ),
    ]
}

/// Per link, the union of its primitives' meshes (overlapping shells; the
/// surface sampler drops the buried parts).
#[must_use]
pub fn lwr4plus_meshes() -> Vec<(String, TriMesh)> {
    lwr4plus_primitives()
        .into_iter()
        .map(|(name, parts)| {
            let mut mesh = TriMesh::default();
            for p in &parts {
                mesh.append(&p.mesh(LWR_SEGMENTS));
            }
            (name.to_owned(), mesh)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_builtin_lwr_weighs_about_what_the_real_one_does() {
        let robot = lwr4plus_kinematics().unwrap();
        let masses: Vec<f64> = robot.links.iter().map(|l| l.inertial.mass_kg).collect();
        let arm: f64 = masses[1..].iter().sum();
        assert!((10.0..25.0).contains(&arm), "{masses:?}");
        for l in &robot.links[1..6] {
            assert!((1.0..4.5).contains(&l.inertial.mass_kg), "{}: {:?}", l.name, l.inertial);
            let i = l.inertial.inertia_about_com;
            assert!(i.x_axis.x > 0.0 && i.y_axis.y > 0.0 && i.z_axis.z > 0.0, "{i}");
        }
    }
}
