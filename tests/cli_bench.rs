//! The `proprioscope` binary `bench`: its tables, repeats, resolutions and what it writes.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use crate::common;

use common::{THESIS_SESSION, run_out, temp_file};

/// `bench --session`: each estimator's per-frame times also split by the
/// truth (frames without contact, frames with one), beside the errors.
#[test]
fn bench_on_a_session_splits_its_times_by_the_truth() {
    let session = temp_file("thesis-bench.session.json", THESIS_SESSION);
    let (ok, stdout, stderr) = run_out(&[
        "bench",
        "--sessions-only",
        "--seeds",
        "0",
        "--session",
        session.to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    assert!(
        stdout.contains("| without contact p50 / p99 [µs] | with a contact p50 / p99 [µs] |"),
        "{stdout}"
    );
    let refined = stdout
        .lines()
        .find(|l| l.starts_with("| refined (patches) |"))
        .unwrap_or_else(|| panic!("{stdout}"));
    // One frame of each kind: each split is its one time, p50 = p99.
    let cells: Vec<&str> = refined.split('|').map(str::trim).collect();
    for cell in [cells[6], cells[7]] {
        let parts: Vec<u64> = cell.split(" / ").map(|v| v.parse().unwrap()).collect();
        assert!(parts.len() == 2 && parts[0] > 0 && parts[0] == parts[1], "{refined}");
    }
}

/// `bench --repeat K` times each frame by the fastest of K runs in a row
/// and says so; the estimates are counted once, so every column but the
/// times is what one run gives.
#[test]
fn bench_repeats_count_the_estimates_once() {
    let session = temp_file("thesis-bench-repeat.session.json", THESIS_SESSION);
    let table = |repeat: &str| {
        let (ok, stdout, stderr) = run_out(&[
            "bench",
            "--sessions-only",
            "--seeds",
            "0",
            "--repeat",
            repeat,
            "--session",
            session.to_str().unwrap(),
        ]);
        assert!(ok, "{stderr}");
        stdout
    };
    let (once, thrice) = (table("1"), table("3"));
    assert!(!once.contains("fastest of"), "{once}");
    // Below the estimates, where the time of a frame alone goes: a row
    // per estimator of frames alone (not over time), each part timed.
    let split = |text: &str| -> (String, String) {
        let (estimates, stages) = text
            .split_once("Where the time of a frame alone goes")
            .unwrap_or((text, ""));
        (estimates.to_owned(), stages.to_owned())
    };
    let ((once, once_stages), (thrice, thrice_stages)) = (split(&once), split(&thrice));
    for stages in [&once_stages, &thrice_stages] {
        let rows: Vec<&str> = stages
            .lines()
            .filter(|l| l.starts_with("| ") && !l.starts_with("| estimator"))
            .collect();
        let labels: Vec<&str> = rows.iter().filter_map(|l| l.split('|').nth(1)).map(str::trim).collect();
        assert_eq!(
            labels,
            ["refined (patches)", "grid of points", "grid of points"],
            "{stages}"
        );
        for row in rows {
            // Three parts, each "p50 / p99" in µs, p50 ≤ p99.
            let parts: Vec<Vec<f64>> = row
                .split('|')
                .skip(3)
                .take(3)
                .map(|cell| cell.split('/').map(|x| x.trim().parse::<f64>().unwrap()).collect())
                .collect();
            assert_eq!(parts.len(), 3, "{row}");
            assert!(
                parts.iter().all(|p| p.len() == 2 && p[0] >= 0.0 && p[0] <= p[1]),
                "{row}"
            );
        }
    }
    assert!(
        thrice_stages.contains("each part timed by its fastest run"),
        "{thrice_stages}"
    );
    assert!(
        thrice.contains("surface seeds [0], each frame timed by the fastest of 3 runs in a row."),
        "{thrice}"
    );
    // Columns 8 on: median error per seed (one each), spread, poorly
    // explained, detection, false alarms, credible sets.
    let estimates = |text: &str| -> Vec<String> {
        text.lines()
            .filter(|l| l.starts_with("| refined (patches) |") || l.starts_with("| grid of points |"))
            .map(|l| l.split('|').skip(8).collect::<Vec<_>>().join("|"))
            .collect()
    };
    let counted = estimates(&thrice);
    assert_eq!(counted.len(), 3, "{thrice}");
    assert_eq!(counted, estimates(&once));
    for row in &counted {
        let per_seed = row.split('|').next().unwrap_or_default();
        assert_eq!(per_seed.split(',').count(), 1, "{row}");
    }
}

/// `bench --session-points` adds a refined row per surface resolution,
/// in both tables, without changing the others; each row estimates as
/// `estimate --n` does (its median error is that of `estimate`'s frames).
#[test]
fn bench_session_points_add_a_refined_row_per_resolution() {
    let session = temp_file("thesis-bench-points.session.json", THESIS_SESSION);
    let bench = |extra: &[&str]| {
        let mut args = vec![
            "bench",
            "--sessions-only",
            "--seeds",
            "0",
            "--session",
            session.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let (ok, stdout, stderr) = run_out(&args);
        assert!(ok, "{stderr}");
        stdout
    };
    let (plain, coarser) = (bench(&[]), bench(&["--session-points", "300,1000"]));
    // (estimator, points, the columns from the median error on) per row.
    let rows = |text: &str| -> Vec<(String, String, String)> {
        let estimates = text.split("Where the time").next().unwrap_or_default();
        estimates
            .lines()
            .filter(|l| l.starts_with("| refined (patches) |") || l.starts_with("| grid of points |"))
            .map(|l| {
                let cells: Vec<&str> = l.split('|').map(str::trim).collect();
                (cells[1].to_owned(), cells[2].to_owned(), cells[8..].join("|"))
            })
            .collect()
    };
    let (plain_rows, coarser_rows) = (rows(&plain), rows(&coarser));
    assert_eq!(plain_rows.len(), 3, "{plain}");
    assert_eq!(coarser_rows[..3], plain_rows[..], "{coarser}");
    let added: Vec<(&str, &str)> = coarser_rows[3..]
        .iter()
        .map(|(label, points, _)| (label.as_str(), points.as_str()))
        .collect();
    assert_eq!(added, [("refined (patches)", "300"), ("refined (patches)", "1000")]);
    let stage_rows: Vec<&str> = coarser
        .split("Where the time")
        .nth(1)
        .unwrap_or_default()
        .lines()
        .filter(|l| l.starts_with("| refined (patches) |"))
        .collect();
    assert_eq!(stage_rows.len(), 3, "{coarser}");
    // The one contact frame's error as `estimate --points 1000` reports it.
    let out = session.with_extension("points.jsonl");
    let (ok, _, stderr) = run_out(&[
        "estimate",
        session.to_str().unwrap(),
        "--points",
        "1000",
        "--seed",
        "0",
        "--temporal",
        "none",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    let first: serde_json::Value =
        serde_json::from_str(std::fs::read_to_string(&out).unwrap().lines().next().unwrap()).unwrap();
    let error_mm = first["truth"]["position_error_m"].as_f64().unwrap() * 1e3;
    let bench_mm: f64 = coarser_rows[4].2.split('|').next().unwrap().trim().parse().unwrap();
    assert_eq!(format!("{error_mm:.1}"), format!("{bench_mm:.1}"), "{coarser}");
}

/// Frames estimated alone tell where each update's time went: the
/// posterior, the refinement and the summary, within the update's time.
#[test]
fn frames_alone_report_the_parts_of_their_update_time() {
    let session = temp_file("thesis-parts.session.json", THESIS_SESSION);
    let out = session.with_extension("jsonl");
    let (ok, _, stderr) = run_out(&[
        "estimate",
        session.to_str().unwrap(),
        "--temporal",
        "none",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    let text = std::fs::read_to_string(&out).unwrap();
    for line in text.lines() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        let parts: Vec<f64> = ["posterior", "refinement", "summary"]
            .iter()
            .map(|k| v["update_parts_ms"][k].as_f64().unwrap())
            .collect();
        assert!(parts.iter().all(|p| *p >= 0.0), "{v}");
        let sum: f64 = parts.iter().sum();
        assert!(sum > 0.0 && sum <= v["update_ms"].as_f64().unwrap(), "{v}");
        // Only a refined contact spends time refining.
        assert_eq!(parts[1] > 0.0, v["refined"] == true, "{v}");
    }
}

/// The README's bench table and plot are committed: a quick run refuses
/// to replace them, and leaves both files as they were.
#[test]
fn a_quick_bench_never_writes_the_readme_or_its_plot() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("bench-quick");
    std::fs::create_dir_all(&dir).unwrap();
    let readme = dir.join("README.md");
    let text = "# x\n<!-- bench:begin -->\nold\n<!-- bench:end -->\n";
    std::fs::write(&readme, text).unwrap();
    let (ok, _, err) = run_out(&["bench", "--quick", "--readme", readme.to_str().unwrap()]);
    assert!(!ok && err.contains("--quick"), "{err}");
    assert_eq!(std::fs::read_to_string(&readme).unwrap(), text);
}
