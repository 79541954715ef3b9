//! Every command README.md and docs/*.md show runs as written (against `../shared`):
//! `view` as `screenshot` (the same target, robot and options, no
//! window), files written to a temporary folder instead of the paths
//! shown. Illustrations that name files the reader brings (`robot.bag`),
//! optional arguments in brackets, live pairs (`&`), `stream`, `bench`
//! (minutes) and `export-assets` (rewrites `assets/`) are listed and
//! skipped; each is exercised by its own tests.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// The documents whose commands run: README.md and docs/*.md, sorted.
fn documents() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root.join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    docs.insert(0, root.join("README.md"));
    docs
}

/// A document's shell commands: lines of `sh` code blocks that run
/// `proprioscope` or `cargo run --release --`, continuation lines joined.
fn readme_commands(path: &Path) -> Vec<(usize, Vec<String>)> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut out = Vec::new();
    let mut in_sh = false;
    let mut pending: Option<(usize, String)> = None;
    for (i, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            in_sh = !in_sh && line.trim() == "```sh";
            continue;
        }
        if !in_sh {
            continue;
        }
        let mut line = line.trim().trim_start_matches("$ ").to_owned();
        if let Some((start, head)) = pending.take() {
            line = format!("{head} {line}");
            if let Some(stripped) = line.strip_suffix('\\') {
                pending = Some((start, stripped.trim().to_owned()));
                continue;
            }
            out.push((start, line));
            continue;
        }
        let code = line.split(" #").next().unwrap_or_default().trim();
        let Some(rest) = code
            .strip_prefix("proprioscope ")
            .or_else(|| code.strip_prefix("cargo run --release -- "))
            .or_else(|| (code == "cargo run --release").then_some(""))
        else {
            continue;
        };
        let rest = rest.trim().to_owned();
        if let Some(stripped) = rest.strip_suffix('\\') {
            pending = Some((i + 1, stripped.trim().to_owned()));
        } else {
            out.push((i + 1, rest));
        }
    }
    out.into_iter()
        .map(|(line, text)| (line, text.split_whitespace().map(str::to_owned).collect()))
        .collect()
}

/// Why a command is not run, if it is not.
fn skipped(args: &[String]) -> Option<String> {
    let first = args.first().map_or("view", String::as_str);
    if ["bench", "stream", "export-assets"].contains(&first) {
        return Some(format!("`{first}` (its own tests)"));
    }
    if args.iter().any(|a| a == "&" || a.starts_with('[')) {
        return Some("a live pair or optional arguments".to_owned());
    }
    let missing: Vec<&String> = args
        .iter()
        .filter(|a| {
            let p = Path::new(a.as_str());
            [".bag", ".urdf", ".mcap", ".json", ".csv"]
                .iter()
                .any(|e| a.ends_with(e))
                && !a.starts_with("/tmp/")
                && !p.exists()
        })
        // Outputs the commands write (`--out est.jsonl`, `est.mcap`).
        .filter(|a| !a.starts_with("est") && !a.starts_with("live"))
        .collect();
    (!missing.is_empty()).then(|| format!("illustrative files {missing:?}"))
}

#[test]
#[ignore = "needs ../shared"]
fn every_documented_command_runs() {
    let tmp = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("readme");
    std::fs::create_dir_all(&tmp).unwrap();
    let mut ran = 0;
    for doc in documents() {
        let name = doc.file_name().unwrap().to_string_lossy().into_owned();
        let commands = readme_commands(&doc);
        if name == "README.md" {
            assert!(commands.len() >= 10, "{commands:?}");
        }
        for (line, args) in commands {
            ran += run_documented(&tmp, &format!("{name} line {line}"), args);
        }
    }
    assert!(ran >= 20, "only {ran} documented commands ran");
}

/// Runs one documented command (1), or says why not (0).
fn run_documented(tmp: &Path, at: &str, args: Vec<String>) -> usize {
    {
        if let Some(why) = skipped(&args) {
            eprintln!("{at}: skipped ({why}): {}", args.join(" "));
            return 0;
        }
        let mut args = args;
        // `view` (or no command: the app) as a screenshot.
        if args.first().is_none_or(|a| a == "view") {
            if !args.is_empty() {
                args.remove(0);
            }
            args.insert(0, "screenshot".to_owned());
            args.push("--out".to_owned());
            args.push(
                tmp.join(format!("{}.png", at.replace([' ', '.'], "-")))
                    .display()
                    .to_string(),
            );
        } else if let Some(i) = args.iter().position(|a| a == "--out") {
            let name = Path::new(&args[i + 1]).file_name().unwrap().to_owned();
            args[i + 1] = tmp.join(name).display().to_string();
        }
        // A file an earlier command wrote (`preview-mcap est.mcap`) is read
        // from where that command wrote it.
        for a in args.iter_mut().skip(1) {
            if a.starts_with("est") && !a.contains('/') && tmp.join(a.as_str()).is_file() {
                *a = tmp.join(a.as_str()).display().to_string();
            }
        }
        let out = Command::new(env!("CARGO_BIN_EXE_proprioscope"))
            .args(&args)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .env_remove("RUST_BACKTRACE")
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{at}: proprioscope {}\n{}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr)
        );
        1
    }
}
