//! Tests of [`super`]: `mesh.rs`.

use super::*;

const DAE: &str = r##"<?xml version="1.0"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="centimeter" meter="0.01"/><up_axis>Z_UP</up_axis></asset>
  <library_geometries>
    <geometry id="tri-mesh"><mesh>
      <source id="tri-pos"><float_array id="tri-pos-array" count="12">0 0 0 1 0 0 0 1 0 1 1 0</float_array>
        <technique_common><accessor source="#tri-pos-array" count="4" stride="3"/></technique_common></source>
      <vertices id="tri-verts"><input semantic="POSITION" source="#tri-pos"/></vertices>
      <polylist count="1"><input semantic="VERTEX" source="#tri-verts" offset="0"/>
        <input semantic="NORMAL" source="#n" offset="1"/>
        <vcount>4</vcount><p>0 0 1 0 3 0 2 0</p></polylist>
    </mesh></geometry>
  </library_geometries>
  <library_visual_scenes><visual_scene id="Scene">
    <node id="n1"><matrix>1 0 0 100  0 1 0 0  0 0 1 0  0 0 0 1</matrix>
      <node id="n2"><rotate>0 0 1 90</rotate><instance_geometry url="#tri-mesh"/></node>
    </node>
  </visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#Scene"/></scene>
</COLLADA>"##;

#[test]
fn dae_applies_units_nested_transforms_and_triangulates_polylists() {
    let mesh = read_dae(DAE, Path::new("t.dae")).unwrap();
    assert_eq!(mesh.triangles.len(), 2);
    // Vertex (1, 0, 0) cm, turned 90° about z, then moved 100 cm along x.
    let expected = DVec3::new(1.0, 0.01, 0.0);
    assert!(
        mesh.positions.iter().any(|p| (*p - expected).length() < 1e-12),
        "{:?}",
        mesh.positions
    );
    assert!((mesh.area() - 1e-4).abs() < 1e-15);
}

#[test]
fn dae_y_up_is_turned_to_z_up() {
    let text = DAE.replace("Z_UP", "Y_UP").replace("<rotate>0 0 1 90</rotate>", "");
    let mesh = read_dae(&text, Path::new("t.dae")).unwrap();
    // (0, 1, 0) cm in a y-up file is up: (1 m offset, 0, 0.01) once z is up.
    let expected =
        DVec3::new(0.0, 0.0, 0.01) + DMat3::from_rotation_x(std::f64::consts::FRAC_PI_2) * DVec3::new(1.0, 0.0, 0.0);
    assert!(
        mesh.positions.iter().any(|p| (*p - expected).length() < 1e-12),
        "{:?}",
        mesh.positions
    );
}

#[test]
fn dae_errors_name_the_element() {
    let text = DAE.replace("0 0 0 1 0 0", "0 0 zero 1 0 0");
    let e = read_dae(&text, Path::new("t.dae")).unwrap_err().to_string();
    assert!(
        e.contains("t.dae") && e.contains("tri-mesh") && e.contains("zero"),
        "{e}"
    );
    let text = DAE.replace("<p>0 0 1 0 3 0 2 0</p>", "<p>0 0 1 0 9 0 2 0</p>");
    let e = read_dae(&text, Path::new("t.dae")).unwrap_err().to_string();
    assert!(e.contains("tri-mesh") && e.contains("past"), "{e}");
}

#[test]
fn glb_round_trips_names_and_geometry() {
    let cube = crate::core::geometry::primitives::cuboid(DVec3::new(0.5, 0.25, 1.0));
    let meshes = vec![
        ("b".to_owned(), cube.clone()),
        ("a".to_owned(), cube.transformed(&DAffine3::from_translation(DVec3::X))),
    ];
    let bytes = encode_glb(&meshes);
    assert_eq!(bytes, encode_glb(&meshes));
    let back = read_gltf_nodes(&bytes, Path::new("x.glb")).unwrap();
    assert_eq!(back.len(), 2);
    assert_eq!(back[0].0, "a");
    assert_eq!(back[1].1, cube);
    assert!((back[0].1.signed_volume() - 0.125).abs() < 1e-9);
}

#[test]
fn unsupported_and_missing_files_are_named() {
    let e = load_mesh(Path::new("robot/link.ply")).unwrap_err().to_string();
    assert!(e.contains("link.ply") && e.contains("ply"), "{e}");
    let e = load_mesh(Path::new("/nonexistent/link.stl")).unwrap_err().to_string();
    assert!(e.contains("/nonexistent/link.stl"), "{e}");
}
