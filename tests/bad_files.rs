//! Malformed mesh and URDF files of the kinds a fuzzer and a black-box
//! run found: each is an error naming the file (no panic, hang, stack
//! overflow or runaway allocation).

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use base64::Engine as _;
use proprioscope::io::mesh::{load_mesh, read_dae, read_gltf_nodes, read_stl};
use proprioscope::io::urdf::{UrdfOptions, load_urdf};

fn temp_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("bad_files").join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A COLLADA document with one triangle; `scene` replaces the visual scene's nodes.
fn dae(scene: &str, inputs: &str, p: &str) -> String {
    format!(
        r##"<?xml version="1.0"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit meter="1"/><up_axis>Z_UP</up_axis></asset>
  <library_geometries><geometry id="g"><mesh>
    <source id="pos"><float_array id="pa" count="9">0 0 0 1 0 0 0 1 0</float_array>
      <technique_common><accessor source="#pa" count="3" stride="3"/></technique_common></source>
    <vertices id="v"><input semantic="POSITION" source="#pos"/></vertices>
    <triangles count="1">{inputs}<p>{p}</p></triangles>
  </mesh></geometry></library_geometries>
  <library_nodes><node id="lib"><instance_node url="#lib"/></node></library_nodes>
  <library_visual_scenes><visual_scene id="s">{scene}</visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#s"/></scene>
</COLLADA>"##
    )
}

const VERTEX: &str = r##"<input semantic="VERTEX" source="#v" offset="0"/>"##;

fn dae_error(text: &str) -> String {
    read_dae(text, Path::new("bad.dae")).unwrap_err().to_string()
}

#[test]
fn collada_instance_node_cycles_end_with_an_error() {
    let e = dae_error(&dae(
        r##"<node id="a"><instance_node url="#lib"/></node>"##,
        VERTEX,
        "0 1 2",
    ));
    assert!(e.contains("bad.dae") && e.contains("cycle"), "{e}");
    // Two nodes instancing each other.
    let mutual = dae(
        r##"<node id="a"><instance_node url="#b"/></node><node id="b"><instance_node url="#a"/></node>"##,
        VERTEX,
        "0 1 2",
    );
    assert!(dae_error(&mutual).contains("cycle"));
}

#[test]
fn collada_offsets_counts_and_indices_out_of_range_are_errors() {
    let scene = r##"<node id="a"><instance_geometry url="#g"/></node>"##;
    let huge = r##"<input semantic="VERTEX" source="#v" offset="18446744073709551615"/>"##;
    assert!(dae_error(&dae(scene, huge, "0 1 2")).contains("offset"));
    let e = dae_error(&dae(scene, VERTEX, "0 1 -5"));
    assert!(e.contains("<p> index -5"), "{e}");
    let e = dae_error(&dae(scene, VERTEX, "0 1 1e300"));
    assert!(e.contains("not a vertex index"), "{e}");
    let poly = dae(scene, VERTEX, "0 1 2")
        .replace(
            "<triangles count=\"1\">",
            "<polylist count=\"1\"><vcount>18446744073709551615</vcount>",
        )
        .replace("</p></triangles>", "</p></polylist>");
    assert!(dae_error(&poly).contains("vcount"), "{}", dae_error(&poly));
}

#[test]
fn collada_transforms_that_blow_up_are_refused() {
    let dir = temp_dir("dae-transform");
    let file = dir.join("big.dae");
    let scene = r##"<node id="a"><matrix>1e308 0 0 0 0 1e308 0 0 0 0 1e308 0 0 0 0 1</matrix><instance_geometry url="#g"/></node>"##;
    std::fs::write(&file, dae(scene, VERTEX, "0 1 2")).unwrap();
    let e = load_mesh(&file).unwrap_err().to_string();
    assert!(e.contains("big.dae") && e.contains("not within"), "{e}");
}

#[test]
fn a_binary_stl_claiming_more_triangles_than_it_holds_is_refused() {
    let mut bytes = vec![0u8; 84 + 50];
    bytes[80..84].copy_from_slice(&1_000_000_000u32.to_le_bytes());
    let e = read_stl(&bytes, Path::new("short.stl")).unwrap_err().to_string();
    assert!(e.contains("short.stl") && e.contains("1000000000"), "{e}");
}

#[test]
fn an_obj_whose_material_library_is_broken_still_loads() {
    let dir = temp_dir("obj-mtl");
    std::fs::write(dir.join("m.mtl"), "newmtl a\nKd 0.5\n").unwrap();
    std::fs::write(
        dir.join("m.obj"),
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n",
    )
    .unwrap();
    let mesh = load_mesh(&dir.join("m.obj")).unwrap();
    assert_eq!(mesh.triangles.len(), 1);
}

/// A glTF document with one triangle in a data URI and the given nodes.
fn gltf(nodes: &str, accessor_count: usize, position_accessor: usize) -> Vec<u8> {
    let floats: Vec<u8> = [0f32, 0., 0., 1., 0., 0., 0., 1., 0.]
        .iter()
        .flat_map(|f| f.to_le_bytes())
        .collect();
    let data = base64::engine::general_purpose::STANDARD.encode(&floats);
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":{nodes},
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":{position_accessor}}}}}]}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":{accessor_count},"type":"VEC3","min":[0,0,0],"max":[1,1,0]}}],
        "bufferViews":[{{"buffer":0,"byteLength":36}}],
        "buffers":[{{"byteLength":36,"uri":"data:application/octet-stream;base64,{data}"}}]}}"#
    )
    .into_bytes()
}

#[test]
fn gltf_node_cycles_end_with_an_error() {
    let path = Path::new("cycle.gltf");
    assert_eq!(read_gltf_nodes(&gltf(r#"[{"mesh":0}]"#, 3, 0), path).unwrap().len(), 1);
    for nodes in [
        r#"[{"mesh":0,"children":[0]}]"#,
        r#"[{"mesh":0,"children":[1]},{"children":[0]}]"#,
    ] {
        let e = read_gltf_nodes(&gltf(nodes, 3, 0), path).unwrap_err().to_string();
        assert!(e.contains("cycle.gltf") && e.contains("cycle"), "{e}");
    }
}

#[test]
fn gltf_accessors_beyond_their_buffers_and_missing_ones_are_errors() {
    let path = Path::new("acc.gltf");
    let e = read_gltf_nodes(&gltf(r#"[{"mesh":0}]"#, 4_000_000_000, 0), path)
        .unwrap_err()
        .to_string();
    assert!(e.contains("acc.gltf"), "{e}");
    let e = read_gltf_nodes(&gltf(r#"[{"mesh":0}]"#, 3, 7), path)
        .unwrap_err()
        .to_string();
    assert!(e.contains("acc.gltf"), "{e}");
}

#[test]
fn a_urdf_nested_thousands_deep_is_refused_without_overflowing() {
    let dir = temp_dir("urdf-deep");
    let file = dir.join("deep.urdf");
    let depth = 12_000;
    let text = format!(
        "<robot name=\"r\"><link name=\"a\">{}{}</link></robot>",
        "<x>".repeat(depth),
        "</x>".repeat(depth)
    );
    std::fs::write(&file, text).unwrap();
    let e = load_urdf(&file, &UrdfOptions::default()).unwrap_err().to_string();
    assert!(e.contains("deep.urdf") && e.contains("nested"), "{e}");
}

#[test]
fn a_mesh_scaled_beyond_reason_is_refused() {
    let dir = temp_dir("urdf-scale");
    std::fs::write(dir.join("m.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    std::fs::write(
        dir.join("r.urdf"),
        r#"<robot name="r"><link name="base"/><link name="a"><visual><geometry><mesh filename="m.obj" scale="1e308 1e308 1e308"/></geometry></visual></link>
        <joint name="j" type="continuous"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/></joint></robot>"#,
    )
    .unwrap();
    let e = load_urdf(&dir.join("r.urdf"), &UrdfOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("r.urdf") && e.contains("not within"), "{e}");
}
