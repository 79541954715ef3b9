//! Any bytes as an MCAP written for Foxglove, read back at a time: what
//! it draws, or an error; never a panic or a hang (transforms that chain
//! in a cycle included).
#![no_main]
use proprioscope::io::foxglove::readback::Snapshot;
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = Snapshot::read(data, 1.0);
});
