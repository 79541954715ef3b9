//! Robot recordings (ROS 2 MCAP, ROS 1 bags; the reader tells them by
//! their first bytes): any bytes list topics and make frames, or give an
//! error; frames made keep the rules of a session, read whole or as the
//! start of a file (the app's preview).
#![no_main]
use proprioscope::io::recording::{TopicChoice, index, read_session, read_session_start};
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let path = std::path::Path::new("fuzz.recording");
    let _ = index(path, data);
    let whole = read_session(path, data, &TopicChoice::default(), &|_| {});
    let start = read_session_start(path, data, &TopicChoice::default());
    for read in [whole, start].into_iter().flatten() {
        let mut last = f64::NEG_INFINITY;
        for frame in &read.session.frames {
            assert!(frame.t >= last && frame.t.is_finite());
            assert!(frame.q.iter().chain(&frame.tau).all(|v| v.is_finite()));
            last = frame.t;
        }
    }
});
