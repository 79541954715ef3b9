//! COLLADA reader: any text gives a mesh or an error, and the mesh its
//! checks.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let path = std::path::Path::new("fuzz.dae");
    if let Ok(mesh) = proprioscope::io::mesh::read_dae(&String::from_utf8_lossy(data), path) {
        let _ = proprioscope::io::mesh::check_extent(&mesh, path, "mesh");
    }
});
