//! Broken robot descriptions: each error names the file and the element.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use std::path::PathBuf;

use proprioscope::io::urdf::{UrdfOptions, load_urdf};

/// Writes `text` as `name` in a fresh folder under the system temp dir.
fn write(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("proprioscope-test-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn error_of(name: &str, text: &str) -> String {
    let path = write(name, text);
    load_urdf(&path, &UrdfOptions::default()).unwrap_err().to_string()
}

fn joint(name: &str, parent: &str, child: &str, axis: &str) -> String {
    format!(
        r#"<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/><axis xyz="{axis}"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>"#
    )
}

#[test]
fn missing_mesh_file_is_named_with_its_link() {
    let text = format!(
        r#"<robot name="r"><link name="base"/><link name="arm"><visual><geometry><mesh filename="meshes/arm.stl"/></geometry></visual></link>{}</robot>"#,
        joint("j1", "base", "arm", "0 0 1")
    );
    let e = error_of("missing_mesh.urdf", &text);
    assert!(
        e.contains("missing_mesh.urdf") && e.contains("'arm'") && e.contains("meshes/arm.stl"),
        "{e}"
    );
}

#[test]
fn missing_package_mesh_says_where_it_looked() {
    let text = format!(
        r#"<robot name="r"><link name="base"/><link name="arm"><visual><geometry><mesh filename="package://nowhere/meshes/arm.dae"/></geometry></visual></link>{}</robot>"#,
        joint("j1", "base", "arm", "0 0 1")
    );
    let e = error_of("missing_package.urdf", &text);
    assert!(
        e.contains("package://nowhere/meshes/arm.dae") && e.contains("looked for"),
        "{e}"
    );
}

#[test]
fn cyclic_tree_is_named() {
    let text = format!(
        r#"<robot name="r"><link name="base"/><link name="a"/><link name="b"/>{}{}{}</robot>"#,
        joint("j0", "base", "a", "0 0 1"),
        joint("j1", "a", "b", "0 0 1"),
        joint("j2", "b", "a", "0 0 1")
    );
    let e = error_of("cyclic.urdf", &text);
    assert!(
        e.contains("cyclic.urdf") && (e.contains("cycle") || e.contains("two joints")),
        "{e}"
    );
}

#[test]
fn loop_without_root_is_a_cycle() {
    let text = format!(
        r#"<robot name="r"><link name="a"/><link name="b"/>{}{}</robot>"#,
        joint("j1", "a", "b", "0 0 1"),
        joint("j2", "b", "a", "0 0 1")
    );
    let e = error_of("loop.urdf", &text);
    assert!(e.contains("loop.urdf") && e.contains("cycle"), "{e}");
}

#[test]
fn disconnected_tree_is_named() {
    let text = format!(
        r#"<robot name="r"><link name="base"/><link name="arm"/><link name="stray"/>{}</robot>"#,
        joint("j1", "base", "arm", "0 0 1")
    );
    let e = error_of("disconnected.urdf", &text);
    assert!(e.contains("disconnected.urdf") && e.contains("stray"), "{e}");
}

#[test]
fn zero_axis_is_named() {
    let text = format!(
        r#"<robot name="r"><link name="base"/><link name="arm"/>{}</robot>"#,
        joint("elbow", "base", "arm", "0 0 0")
    );
    let e = error_of("zero_axis.urdf", &text);
    assert!(
        e.contains("zero_axis.urdf") && e.contains("elbow") && e.contains("axis"),
        "{e}"
    );
}

#[test]
fn primitives_and_scale_and_origin_are_applied() {
    let text = format!(
        r#"<robot name="r"><link name="base"/><link name="arm">
        <visual><origin xyz="0 0 1" rpy="0 0 0"/><geometry><box size="0.1 0.2 0.3"/></geometry></visual>
        <visual><geometry><sphere radius="0.05"/></geometry></visual>
        </link>{}</robot>"#,
        joint("j1", "base", "arm", "0 0 1")
    );
    let path = write("primitives.urdf", &text);
    let robot = load_urdf(&path, &UrdfOptions::default()).unwrap();
    let mesh = &robot.links[1].mesh;
    let (lo, hi) = mesh.bounds().unwrap();
    assert!((hi.z - 1.15).abs() < 1e-12 && (lo.z + 0.05).abs() < 1e-12, "{lo} {hi}");
    assert!((mesh.signed_volume() - (0.006 + 4.0 / 3.0 * std::f64::consts::PI * 0.05f64.powi(3))).abs() < 1e-5);
}

#[test]
fn package_uri_resolves_by_the_longest_existing_suffix() {
    let dir = std::env::temp_dir().join(format!("proprioscope-test-{}-pkg", std::process::id()));
    let urdf_dir = dir.join("robot/urdf");
    let mesh_dir = dir.join("robot/meshes/visual");
    std::fs::create_dir_all(&urdf_dir).unwrap();
    std::fs::create_dir_all(&mesh_dir).unwrap();
    // An ASCII STL tetrahedron.
    let stl = "solid t\nfacet normal 0 0 -1\nouter loop\nvertex 0 0 0\nvertex 0 1 0\nvertex 1 0 0\nendloop\nendfacet\n\
               facet normal 0 -1 0\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 0 1\nendloop\nendfacet\n\
               facet normal -1 0 0\nouter loop\nvertex 0 0 0\nvertex 0 0 1\nvertex 0 1 0\nendloop\nendfacet\n\
               facet normal 1 1 1\nouter loop\nvertex 1 0 0\nvertex 0 1 0\nvertex 0 0 1\nendloop\nendfacet\nendsolid t\n";
    std::fs::write(mesh_dir.join("tet.stl"), stl).unwrap();
    let text = format!(
        r#"<robot name="r"><link name="base"/><link name="arm"><visual><geometry><mesh filename="package://some_description/robots/meshes/visual/tet.stl" scale="2 2 2"/></geometry></visual></link>{}</robot>"#,
        joint("j1", "base", "arm", "0 0 1")
    );
    std::fs::write(urdf_dir.join("r.urdf"), text).unwrap();
    let robot = load_urdf(&urdf_dir.join("r.urdf"), &UrdfOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    assert!((robot.links[1].mesh.signed_volume() - 8.0 / 6.0).abs() < 1e-6);
}
