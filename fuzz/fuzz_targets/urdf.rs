//! URDF reader: any text gives a robot or an error (meshes are looked for
//! in a folder that does not exist; primitives are built).
#![no_main]
use proprioscope::io::urdf::{UrdfOptions, read_urdf};
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let _ = read_urdf(
        &text,
        std::path::Path::new("/nonexistent-fuzz/fuzz.urdf"),
        &UrdfOptions::default(),
    );
});
