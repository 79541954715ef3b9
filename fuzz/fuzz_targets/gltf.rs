//! glTF/GLB reader: any bytes give meshes or an error (external buffers
//! are looked for in a folder that does not exist).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = proprioscope::io::mesh::read_gltf_nodes(data, std::path::Path::new("/nonexistent-fuzz/fuzz.gltf"));
});
