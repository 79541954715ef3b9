//! The source's structure, as ARCHITECTURE.md draws it: the rooms of
//! `core` import only the rooms below them, `core` imports no UI, GPU or
//! file code, the layers import only the layers below, no two files import
//! each other (through any chain), and no file holds more than about 800
//! lines of code; and every integration test file is built.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The rooms of `core`, bottom floor first, with their floor.
const ROOMS: [(&str, usize); 9] = [
    ("core::numerics", 1),
    ("core::geometry", 2),
    ("core::robot", 3),
    ("core::surface", 4),
    ("core::estimate", 5),
    ("core::over_time", 6),
    ("core::config", 7),
    ("core::eval", 7),
    ("core::paint", 7),
];

/// The library's layers, bottom first.
const LAYERS: [&str; 5] = ["core", "io", "batch", "render", "app"];

/// What a layer may import besides itself.
fn layer_may_import(layer: &str, other: &str) -> bool {
    match layer {
        "core" => false,
        "io" | "render" => other == "core",
        "batch" => ["core", "io"].contains(&other),
        _ => true,
    }
}

/// Every `.rs` file under `src`, test files (`*_tests.rs`, `tests.rs`) apart.
fn sources() -> (Vec<PathBuf>, Vec<PathBuf>) {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }
    let mut all = Vec::new();
    walk(&Path::new(env!("CARGO_MANIFEST_DIR")).join("src"), &mut all);
    all.sort();
    all.into_iter().partition(|p| {
        let name = p.file_name().unwrap().to_string_lossy();
        !(name.ends_with("_tests.rs") || name == "tests.rs")
    })
}

/// `core::estimate::refine` for `src/core/estimate/refine.rs` (`mod.rs`
/// is its folder's module; the binary's files are `cli::…` and `main`).
fn module_of(path: &Path) -> String {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let rel = path.strip_prefix(&src).unwrap().with_extension("");
    let mut parts: Vec<String> = rel.iter().map(|p| p.to_string_lossy().into_owned()).collect();
    if parts.last().is_some_and(|p| p == "mod") {
        parts.pop();
    }
    parts.join("::")
}

/// The code of a file: its test module, comments and blank lines left out.
fn code(text: &str) -> Vec<&str> {
    let end = text.find("#[cfg(test)]\nmod tests {").unwrap_or(text.len());
    text[..end]
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with("//"))
        .collect()
}

/// The modules a file's code names (`crate::a::b::c` → the longest module
/// of `modules` it starts with), its own left out.
fn imports(module: &str, text: &str, modules: &BTreeSet<String>) -> BTreeSet<String> {
    let binary = module.starts_with("cli") || module == "main";
    let mut out = BTreeSet::new();
    for line in code(text) {
        for root in ["crate::", "proprioscope::"] {
            let mut rest = line;
            while let Some(i) = rest.find(root) {
                rest = &rest[i + root.len()..];
                // In the binary, `crate::` is the binary's own root.
                let in_library = root == "proprioscope::" || !binary;
                let path: String = rest
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':')
                    .collect();
                let parts: Vec<&str> = path.split("::").filter(|p| !p.is_empty()).collect();
                for k in (1..=parts.len()).rev() {
                    let candidate = parts[..k].join("::");
                    let known = if in_library {
                        modules.contains(&candidate) && !candidate.starts_with("cli")
                    } else {
                        modules.contains(&candidate)
                    };
                    if known {
                        if candidate != module {
                            out.insert(candidate);
                        }
                        break;
                    }
                }
            }
        }
    }
    // `super::x` in a file of a folder module: its sibling `x`, where
    // `x` is a module (an item of the folder's `mod.rs` is the parent's,
    // which declares its children and is left out of the circles).
    if let Some((parent, _)) = module.rsplit_once("::") {
        for line in code(text) {
            let mut rest = line;
            while let Some(i) = rest.find("super::") {
                rest = &rest[i + "super::".len()..];
                let names: Vec<String> = if let Some(group) = rest.strip_prefix('{') {
                    group
                        .split('}')
                        .next()
                        .unwrap_or_default()
                        .split(',')
                        .map(|n| n.trim().split("::").next().unwrap_or_default().to_owned())
                        .collect()
                } else {
                    vec![rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect()]
                };
                for name in names {
                    let sibling = format!("{parent}::{name}");
                    if modules.contains(&sibling) && sibling != module {
                        out.insert(sibling);
                    }
                }
            }
        }
    }
    out
}

/// The room of a `core` module and its floor.
fn room(module: &str) -> Option<(&'static str, usize)> {
    ROOMS
        .iter()
        .find(|(r, _)| module == *r || module.starts_with(&format!("{r}::")))
        .copied()
}

#[test]
fn the_rooms_and_layers_import_only_downwards_and_never_in_a_circle() {
    let (files, _) = sources();
    let texts: Vec<(String, String)> = files
        .iter()
        .map(|p| (module_of(p), std::fs::read_to_string(p).unwrap()))
        .collect();
    let modules: BTreeSet<String> = texts.iter().map(|(m, _)| m.clone()).collect();
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut problems = Vec::new();
    for (module, text) in &texts {
        let imported = imports(module, text, &modules);
        if module.starts_with("core") {
            for forbidden in ["egui", "eframe", "wgpu", "winit", "rfd", "std::fs", "std::net"] {
                if code(text).iter().any(|l| l.contains(forbidden)) {
                    problems.push(format!("{module} names {forbidden}"));
                }
            }
        }
        for other in &imported {
            if let (Some((from, a)), Some((to, b))) = (room(module), room(other))
                && b > a
            {
                problems.push(format!(
                    "{module} ({from}, floor {a}) imports {other} ({to}, floor {b})"
                ));
            }
            let (la, lb) = (
                module.split("::").next().unwrap_or_default(),
                other.split("::").next().unwrap_or_default(),
            );
            if la != lb && LAYERS.contains(&la) && LAYERS.contains(&lb) && !layer_may_import(la, lb) {
                problems.push(format!("{module} (layer {la}) imports {other} (layer {lb})"));
            }
        }
        graph.insert(module.clone(), imported);
    }
    // A circle: a module that reaches itself. Parents (`mod.rs`) that only
    // declare their children are left out of the walk.
    for start in graph.keys() {
        let mut seen = BTreeSet::new();
        let mut stack: Vec<&String> = graph[start].iter().collect();
        while let Some(m) = stack.pop() {
            if m == start {
                problems.push(format!("{start} imports itself through a chain"));
                break;
            }
            if seen.insert(m.clone())
                && let Some(next) = graph.get(m)
            {
                stack.extend(next.iter().filter(|n| !start.starts_with(&format!("{n}::"))));
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn no_source_file_holds_more_than_about_800_lines_of_code() {
    let (files, tests) = sources();
    let mut long = Vec::new();
    for path in files.iter().chain(&tests) {
        let text = std::fs::read_to_string(path).unwrap();
        let lines = code(&text).len();
        if lines > 820 {
            long.push(format!("{}: {lines} lines of code", path.display()));
        }
    }
    assert!(long.is_empty(), "{}", long.join("\n"));
}

#[test]
fn every_core_room_says_what_it_owns() {
    for (room, _) in ROOMS {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("src")
            .join(room.replace("::", "/"))
            .join("mod.rs");
        let text = std::fs::read_to_string(&path).unwrap();
        let doc: Vec<&str> = text.lines().take_while(|l| l.starts_with("//!")).collect();
        assert!((2..=4).contains(&doc.len()), "{}: {doc:?}", path.display());
        assert!(
            doc.iter().any(|l| l.contains("Imports")),
            "{} does not say what it may import",
            path.display()
        );
    }
}

/// With `autotests = false`, a file under `tests/` that `tests/main.rs`
/// does not declare would never be built: every one is declared.
#[test]
fn every_integration_test_file_is_built() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests");
    let main = std::fs::read_to_string(dir.join("main.rs")).unwrap();
    let declared: BTreeSet<&str> = main
        .lines()
        .filter_map(|line| line.strip_prefix("mod ")?.strip_suffix(';'))
        .collect();
    let mut missing = Vec::new();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let Some(stem) = path.file_stem().and_then(|s| s.to_str()) else {
            continue;
        };
        let is_module = if path.is_dir() {
            path.join("mod.rs").exists()
        } else {
            path.extension().is_some_and(|e| e == "rs") && stem != "main"
        };
        if is_module && !declared.contains(stem) {
            missing.push(stem.to_owned());
        }
    }
    assert!(missing.is_empty(), "tests/main.rs does not declare: {missing:?}");
}
