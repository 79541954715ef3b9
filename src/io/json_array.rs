//! The elements of a JSON object's array field, found without parsing
//! them, so that a session's frames are parsed on every core.
//!
//! Our own pass rather than `serde_json`'s borrowed `RawValue`: that scan
//! checks every number of every frame on one thread, and was a fifth of
//! the time to read a 10-minute, 1 kHz session (241 MB). This pass only
//! follows strings and nesting. Whatever it does not expect gives
//! `None`, and the caller parses the whole text as before, whose error
//! then names the line.

/// A document split at one array field.
#[derive(Debug, PartialEq, Eq)]
pub(crate) struct Split<'a> {
    /// The document with the array emptied (`"field":[]`), for the
    /// fields around it.
    pub rest: String,
    /// Each element's text, in order, without the whitespace around it.
    pub elements: Vec<&'a str>,
}

/// Splits `text`, a JSON object, at its top-level field `field`, an
/// array. `None` when the text is not an object, the field is missing,
/// given twice, spelt with escapes or not an array, or the array is not
/// well formed; elements themselves are not checked.
pub(crate) fn split_array_field<'a>(text: &'a str, field: &str) -> Option<Split<'a>> {
    split(text, field, false)
}

/// As [`split_array_field`] for the start of a document cut anywhere
/// after the array opens: the fields before the array (the object closed
/// after it) and the elements that end before the cut.
pub(crate) fn split_array_field_start<'a>(text: &'a str, field: &str) -> Option<Split<'a>> {
    split(text, field, true)
}

fn split<'a>(text: &'a str, field: &str, start_only: bool) -> Option<Split<'a>> {
    let bytes = text.as_bytes();
    let mut scan = Scan { bytes, at: 0 };
    scan.skip_whitespace();
    if scan.next()? != b'{' {
        return None;
    }
    let mut found: Option<(usize, usize, Vec<&'a str>)> = None;
    loop {
        scan.skip_whitespace();
        match scan.peek()? {
            b'}' => break,
            b'"' => {}
            _ => return None,
        }
        let key = scan.string()?;
        scan.skip_whitespace();
        if scan.next()? != b':' {
            return None;
        }
        scan.skip_whitespace();
        if key == field.as_bytes() {
            if found.is_some() || scan.peek()? != b'[' {
                return None;
            }
            let open = scan.at;
            if start_only {
                let elements = scan.elements_before_end(text)?;
                let mut rest = text.get(..open)?.to_owned();
                rest.push_str("[]}");
                return Some(Split { rest, elements });
            }
            let elements = scan.elements(text)?;
            found = Some((open, scan.at, elements));
        } else {
            scan.value()?;
        }
        scan.skip_whitespace();
        match scan.next()? {
            b',' => {}
            b'}' => break,
            _ => return None,
        }
    }
    let (open, close, elements) = found?;
    // `open` is the '[' and `close` just after the ']'.
    let mut rest = String::with_capacity(text.len() - (close - open) + 2);
    rest.push_str(text.get(..open)?);
    rest.push_str("[]");
    rest.push_str(text.get(close..)?);
    Some(Split { rest, elements })
}

/// A cursor over the document's bytes.
struct Scan<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Scan<'a> {
    fn peek(&self) -> Option<u8> {
        self.bytes.get(self.at).copied()
    }

    fn next(&mut self) -> Option<u8> {
        let b = self.peek()?;
        self.at += 1;
        Some(b)
    }

    fn skip_whitespace(&mut self) {
        while matches!(self.peek(), Some(b' ' | b'\t' | b'\n' | b'\r')) {
            self.at += 1;
        }
    }

    /// Skips the bytes before the next quote, backslash, bracket, brace
    /// or comma, eight at a time (numbers are most of a session's text).
    fn skip_plain(&mut self) {
        while let Some(word) = self.word() {
            // `[` and `{`, `]` and `}` differ in the 0x20 bit alone.
            let folded = word | (SPREAD * 0x20);
            let found = has_byte(word, b'"')
                | has_byte(word, b',')
                | has_byte(word, b'\\')
                | has_byte(folded, b'{')
                | has_byte(folded, b'}');
            if found != 0 {
                self.at += (found.trailing_zeros() / 8) as usize;
                return;
            }
            self.at += 8;
        }
    }

    /// Skips the bytes of a string before its next quote or backslash.
    fn skip_in_string(&mut self) {
        while let Some(word) = self.word() {
            let found = has_byte(word, b'"') | has_byte(word, b'\\');
            if found != 0 {
                self.at += (found.trailing_zeros() / 8) as usize;
                return;
            }
            self.at += 8;
        }
    }

    /// The eight bytes at the cursor, the first in the lowest byte.
    fn word(&self) -> Option<u64> {
        let bytes: [u8; 8] = self.bytes.get(self.at..self.at + 8)?.try_into().ok()?;
        Some(u64::from_le_bytes(bytes))
    }

    /// A string from its opening quote; its raw bytes between the quotes
    /// (escapes left as written).
    fn string(&mut self) -> Option<&'a [u8]> {
        if self.next()? != b'"' {
            return None;
        }
        let start = self.at;
        loop {
            self.skip_in_string();
            match self.next()? {
                b'"' => return self.bytes.get(start..self.at - 1),
                b'\\' => {
                    self.next()?;
                }
                _ => {}
            }
        }
    }

    /// Skips one value: up to the first ',', ']' or '}' outside strings
    /// and brackets, which it leaves. Only nesting is followed: the
    /// value's own text is checked by whoever parses it.
    fn value(&mut self) -> Option<()> {
        let mut depth = 0_usize;
        loop {
            self.skip_plain();
            match self.peek()? {
                b'"' => {
                    self.string()?;
                    continue;
                }
                b'[' | b'{' => depth += 1,
                b']' | b'}' | b',' if depth == 0 => return Some(()),
                b']' | b'}' => depth -= 1,
                _ => {}
            }
            self.at += 1;
        }
    }

    /// The elements of the array at the cursor that end (with a ',' or
    /// the ']') before the text does.
    fn elements_before_end(&mut self, text: &'a str) -> Option<Vec<&'a str>> {
        if self.next()? != b'[' {
            return None;
        }
        let mut elements = Vec::new();
        loop {
            self.skip_whitespace();
            if matches!(self.peek(), None | Some(b']')) {
                return Some(elements);
            }
            let start = self.at;
            if self.value().is_none() {
                // The text ends inside it.
                return Some(elements);
            }
            let element = text.get(start..self.at)?.trim_end_matches([' ', '\t', '\n', '\r']);
            match self.next() {
                // It may go on after the cut.
                None => return Some(elements),
                Some(b',') if !element.is_empty() => elements.push(element),
                Some(b']') if !element.is_empty() => {
                    elements.push(element);
                    return Some(elements);
                }
                Some(_) => return None,
            }
        }
    }

    /// The elements of the array at the cursor, which ends after its ']'.
    fn elements(&mut self, text: &'a str) -> Option<Vec<&'a str>> {
        if self.next()? != b'[' {
            return None;
        }
        let mut elements = Vec::new();
        self.skip_whitespace();
        if self.peek()? == b']' {
            self.at += 1;
            return Some(elements);
        }
        loop {
            self.skip_whitespace();
            let start = self.at;
            self.value()?;
            let element = text.get(start..self.at)?.trim_end_matches([' ', '\t', '\n', '\r']);
            if element.is_empty() {
                return None;
            }
            elements.push(element);
            match self.next()? {
                b',' => {}
                b']' => return Some(elements),
                _ => return None,
            }
        }
    }
}

/// A byte repeated in each of a word's eight bytes.
const SPREAD: u64 = 0x0101_0101_0101_0101;

/// A word whose lowest set bit is in the first byte of `word` equal to
/// `byte` (0 when none is): bits above it may be set by the borrow.
fn has_byte(word: u64, byte: u8) -> u64 {
    let x = word ^ (SPREAD * u64::from(byte));
    x.wrapping_sub(SPREAD) & !x & (SPREAD * 0x80)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn elements_are_found_through_strings_and_nesting() {
        let text = r#" { "a": [1, {"frames": [9]}], "frames" : [ {"q":[1,2],"s":"x],\"{"} ,
            [3] , 4.5e-3 ] , "z":"}" } "#;
        let split = split_array_field(text, "frames").unwrap();
        assert_eq!(split.elements, vec![r#"{"q":[1,2],"s":"x],\"{"}"#, "[3]", "4.5e-3"]);
        assert_eq!(
            split.rest,
            r#" { "a": [1, {"frames": [9]}], "frames" : [] , "z":"}" } "#
        );
        let empty = split_array_field(r#"{"frames":[ ]}"#, "frames").unwrap();
        assert!(empty.elements.is_empty());
        assert_eq!(empty.rest, r#"{"frames":[]}"#);
    }

    #[test]
    fn a_word_finds_the_first_byte_of_each_kind() {
        // Every position of every byte the skip stops at, among others.
        for special in [b'"', b',', b'\\', b'[', b']', b'{', b'}'] {
            for at in 0..8 {
                let mut bytes = *b"01234567";
                bytes[at] = special;
                let mut text = bytes.to_vec();
                text.extend_from_slice(b"89abcdef");
                let mut scan = Scan { bytes: &text, at: 0 };
                scan.skip_plain();
                assert_eq!(scan.at, at, "{}", special as char);
            }
        }
        // The bytes that share a bit pattern with them do not stop it.
        let text = b"Kk;+@`\x7f\x00zZ|\x02---------";
        let mut scan = Scan { bytes: text, at: 0 };
        scan.skip_plain();
        assert!(scan.at >= 8, "{}", scan.at);
    }

    #[test]
    fn a_cut_document_gives_the_elements_before_the_cut() {
        let text = r#"{"robot":"r","frames":[{"t":0},{"t":1} , {"t":2},{"t":3"#;
        let start = split_array_field_start(text, "frames").unwrap();
        assert_eq!(start.elements, vec![r#"{"t":0}"#, r#"{"t":1}"#, r#"{"t":2}"#]);
        assert_eq!(start.rest, r#"{"robot":"r","frames":[]}"#);
        // A number cut at the end may have gone on.
        let cut = split_array_field_start(r#"{"frames":[1,22"#, "frames").unwrap();
        assert_eq!(cut.elements, vec!["1"]);
        let whole = split_array_field_start(r#"{"frames":[1,2],"version":1}"#, "frames").unwrap();
        assert_eq!(whole.elements, vec!["1", "2"]);
        assert_eq!(whole.rest, r#"{"frames":[]}"#);
        for text in [r#"{"version":1,"fra"#, r#"{"frames":[1,,2,3]"#, r#"{"frames":[1}"#] {
            assert_eq!(split_array_field_start(text, "frames"), None, "{text}");
        }
    }

    #[test]
    fn what_it_does_not_expect_is_left_to_the_parser() {
        for text in [
            "",
            "[]",
            r#"{"frames":[1,]}"#,
            r#"{"frames":[,1]}"#,
            r#"{"frames":[1 2"#,
            r#"{"frames":{}}"#,
            r#"{"frames":[1],"frames":[2]}"#,
            r#"{"fr\u0061mes":[1]}"#,
            r#"{"other":[1]}"#,
            r#"{"frames":[1] "x":2}"#,
            r#"{"frames":["unterminated]}"#,
            r#"{"frames":[1]"#,
        ] {
            assert_eq!(split_array_field(text, "frames"), None, "{text}");
        }
    }
}
