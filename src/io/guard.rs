//! Defences against malformed files: third-party readers run isolated (a
//! panic inside one becomes an error naming the file, not an abort), and
//! the limits on what a file may ask of the program.

use std::cell::Cell;
use std::sync::Once;

/// The most triangles one mesh file may hold.
pub const MAX_TRIANGLES: usize = 5_000_000;

/// The most vertices one mesh file may hold.
pub const MAX_VERTICES: usize = 15_000_000;

/// The farthest a mesh vertex may lie from its link's origin, m (an arm's
/// mesh beyond a kilometre is a unit or scale error).
pub const MAX_EXTENT_M: f64 = 1000.0;

/// The deepest element nesting a URDF or COLLADA file may have (the URDF
/// reader recurses per level; deeper files would overflow its stack).
pub const MAX_XML_DEPTH: usize = 128;

/// The most nodes one glTF or COLLADA scene may expand to (instances
/// included): a bound that catches reference cycles.
pub const MAX_SCENE_NODES: usize = 100_000;

/// The largest file any reader takes, bytes.
pub const MAX_FILE_BYTES: u64 = 1 << 30;

thread_local! {
    /// True while this thread runs an isolated reader: its panic is
    /// turned into an error, so the panic message is not printed.
    static ISOLATED: Cell<bool> = const { Cell::new(false) };
}

static QUIET_HOOK: Once = Once::new();

/// Runs `read`, turning a panic inside it into `Err` with the panic's
/// message. For third-party parsers that panic on some malformed inputs.
pub fn isolated<T>(read: impl FnOnce() -> T) -> Result<T, String> {
    QUIET_HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !ISOLATED.with(Cell::get) {
                previous(info);
            }
        }));
    });
    let was = ISOLATED.with(|i| i.replace(true));
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(read));
    ISOLATED.with(|i| i.set(was));
    result.map_err(|payload| {
        let message = payload
            .downcast_ref::<&str>()
            .map(|s| (*s).to_owned())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown failure".to_owned());
        format!("the reader failed on this file ({message})")
    })
}

/// The deepest element nesting of an XML text (start tags minus end tags,
/// comments, declarations, CDATA and processing instructions skipped); a
/// cheap scan made before a recursive parser sees the text.
#[must_use]
pub fn xml_depth(text: &str) -> usize {
    let bytes = text.as_bytes();
    let (mut depth, mut deepest, mut i) = (0usize, 0usize, 0usize);
    while let Some(offset) = bytes.get(i..).and_then(|rest| rest.iter().position(|&b| b == b'<')) {
        i += offset;
        let rest = bytes.get(i..).unwrap_or_default();
        let skip_to = |end: &[u8]| {
            rest.windows(end.len())
                .position(|w| w == end)
                .map_or(bytes.len(), |p| i + p + end.len())
        };
        if rest.starts_with(b"<!--") {
            i = skip_to(b"-->");
        } else if rest.starts_with(b"<![CDATA[") {
            i = skip_to(b"]]>");
        } else if rest.starts_with(b"<?") || rest.starts_with(b"<!") {
            i = skip_to(b">");
        } else if rest.starts_with(b"</") {
            depth = depth.saturating_sub(1);
            i = skip_to(b">");
        } else {
            let end = skip_to(b">");
            let self_closing = end >= 2 && bytes.get(end - 2) == Some(&b'/');
            if !self_closing {
                depth += 1;
                deepest = deepest.max(depth);
            }
            i = end;
        }
    }
    deepest
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_inside_becomes_an_error() {
        let r: Result<(), String> = isolated(|| panic!("bad file"));
        assert!(r.unwrap_err().contains("bad file"));
        assert_eq!(isolated(|| 3), Ok(3));
    }

    #[test]
    fn xml_depth_counts_open_elements() {
        assert_eq!(xml_depth("<a><b/><c><d></d></c></a>"), 3);
        assert_eq!(
            xml_depth("<?xml version='1.0'?><!-- <x><y> --><a><![CDATA[<q><r>]]></a>"),
            1
        );
        let deep = "<a>".repeat(20_000);
        assert_eq!(xml_depth(&deep), 20_000);
    }
}
