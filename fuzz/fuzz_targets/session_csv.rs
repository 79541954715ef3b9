//! Sessions in CSV: any text gives a session (strictly checked) or an error.
#![no_main]
use proprioscope::io::session::Session;
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    if let Ok(session) = Session::parse_csv(&text, std::path::Path::new("fuzz.csv")) {
        let _ = session.check();
    }
});
