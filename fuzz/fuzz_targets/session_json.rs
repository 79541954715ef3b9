//! Sessions in JSON: any text gives a session (strictly checked) or an
//! error, and the same one whether its frames are split out first and
//! parsed in parallel or the text is parsed whole.
#![no_main]
use proprioscope::io::session::Session;
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let path = std::path::Path::new("fuzz.json");
    let split = Session::parse_json(&text, path);
    let whole = Session::parse_json_whole(&text, path);
    // Debug forms: a frame with no values holds NaN, unequal to itself.
    assert_eq!(format!("{split:?}"), format!("{whole:?}"));
    if let Ok(session) = split {
        let _ = session.check();
    }
});
