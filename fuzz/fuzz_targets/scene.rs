//! Scene files: any text gives a scene (loaded on a built-in robot when it
//! names one) or an error.
#![no_main]
use proprioscope::io::scene::Scene;
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let path = std::path::Path::new("/nonexistent-fuzz/fuzz.json");
    if let Ok(scene) = Scene::parse(&text, path) {
        if proprioscope::io::builtin::is_builtin(&scene.robot) {
            let _ = scene.load(path);
        }
    }
});
