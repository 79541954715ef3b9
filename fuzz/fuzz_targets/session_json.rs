//! Sessions in JSON: any text gives a session (strictly checked) or an
//! error, and the same one whether its frames are split out first and
//! parsed in parallel or the text is parsed whole; the start of a
//! session's text cut anywhere gives its first frames (the app's preview).
#![no_main]
use proprioscope::io::session::Session;
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let path = std::path::Path::new("fuzz.json");
    let split = Session::parse_json(&text, path);
    let whole = Session::parse_json_whole(&text, path);
    // Debug forms: a frame with no values holds NaN, unequal to itself.
    assert_eq!(format!("{split:?}"), format!("{whole:?}"));
    let Ok(session) = split else {
        return;
    };
    let _ = session.check();
    // Cut where the input's first byte says.
    let mut cut = usize::from(data.first().copied().unwrap_or(0)) * text.len() / 255;
    while !text.is_char_boundary(cut) {
        cut -= 1;
    }
    if let Some(start) = text.get(..cut).and_then(|t| Session::parse_json_start(t, path)) {
        let n = start.frames.len();
        assert!(n <= session.frames.len());
        let first = session.frames.get(..n).map(|f| format!("{f:?}"));
        assert_eq!(Some(format!("{:?}", start.frames)), first);
    }
});
