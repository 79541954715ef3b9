//! OBJ reader: any bytes give a mesh or an error.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = proprioscope::io::mesh::read_obj(data, std::path::Path::new("fuzz.obj"));
});
