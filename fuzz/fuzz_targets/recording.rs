//! Recordings as the app writes them, possibly cut short: any text gives
//! the frames up to the last whole one, bad frames listed, or an error.
#![no_main]
use proprioscope::io::session::Session;
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let _ = Session::parse_skipping_bad_frames(&text, std::path::Path::new("fuzz.json"));
});
