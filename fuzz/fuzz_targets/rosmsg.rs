//! Message definitions and messages: the bytes before the first NUL are a
//! definition (its first byte picks CDR or ROS 1), the rest a message;
//! any of them parse and decode, or give an error.
#![no_main]
use proprioscope::io::rosmsg::{Encoding, MessageDefinition};
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let split = data.iter().position(|&b| b == 0).unwrap_or(data.len());
    let (text, message) = data.split_at(split);
    let encoding = if text.first().is_some_and(|b| b % 2 == 0) {
        Encoding::Cdr
    } else {
        Encoding::Ros1
    };
    let text = String::from_utf8_lossy(text.get(1..).unwrap_or_default());
    if let Ok(definition) = MessageDefinition::parse("fuzz/msg/Root", &text, encoding) {
        let _ = definition.decode(message.get(1..).unwrap_or_default());
    }
});
