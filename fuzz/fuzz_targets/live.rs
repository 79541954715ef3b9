//! Live streams: any text, line by line, gives headers, frames or
//! reported lines; frames that pass keep time going forwards.
#![no_main]
use proprioscope::io::session::{LiveLine, LiveReader};
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let mut reader = LiveReader::new(None);
    let mut last = f64::NEG_INFINITY;
    for line in text.lines() {
        if let LiveLine::Frame(frame) = reader.line(line) {
            assert!(frame.t >= last && frame.t.is_finite());
            assert!(frame.q.iter().chain(&frame.tau).all(|v| v.is_finite()));
            last = frame.t;
        }
    }
});
