//! `estimate --press-gaps`: each true press fitted again from the
//! estimate's places and from the true ones.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use crate::common;

use common::run_out;

/// A cost cell: `-2 ln L`, with ` (μ_k …)` where kinetic friction
/// explains the press.
fn cost(cell: &str) -> f64 {
    cell.split_whitespace()
        .next()
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("{cell}"))
}

#[test]
fn each_true_press_is_fitted_from_the_estimate_and_from_the_truth() {
    let dir = common::temp_dir("gaps");
    let path = dir.join("slides.json");
    let (ok, _, err) = run_out(&[
        "synth",
        path.to_str().unwrap(),
        "--seconds",
        "4",
        "--rate",
        "50",
        "--seed",
        "1",
        "--links",
        "lwr_6_link",
        "--slide",
        "0.1",
        "--slide-min",
        "0.05",
        "--kinetic-friction",
        "0.3,0.6",
    ]);
    assert!(ok, "{err}");
    let estimate = |extra: &[&str]| {
        let mut args = vec![
            "estimate",
            path.to_str().unwrap(),
            "--points",
            "1000",
            "--temporal",
            "smooth",
        ];
        args.extend(extra);
        let (ok, out, err) = run_out(&args);
        assert!(ok, "{err}");
        out
    };
    let out = estimate(&["--press-gaps"]);
    let rows: Vec<Vec<&str>> = out
        .lines()
        .filter(|l| l.starts_with("| ") && l.contains("_link |"))
        .map(|l| l.trim_matches('|').split('|').map(str::trim).collect())
        .collect();
    let summary = out
        .lines()
        .find(|l| l.starts_with("the search lost "))
        .unwrap_or_else(|| panic!("{out}"));
    // "the search lost L of N presses (…)": one row per press.
    let words: Vec<&str> = summary.split_whitespace().collect();
    let (lost, presses): (usize, usize) = (words[3].parse().unwrap(), words[5].parse().unwrap());
    assert!(presses >= 3 && rows.len() == presses, "{out}");
    let mut marked = 0;
    for row in &rows {
        assert_eq!(row.len(), 8, "{row:?}");
        assert_eq!(row[2], "lwr_6_link", "{row:?}");
        let frames: usize = row[1].parse().unwrap();
        assert!(frames > 0, "{row:?}");
        // A press is lost where the fit from the truth costs more than
        // 30 less than the fit from the estimate's places.
        let (from_estimate, from_truth) = (cost(row[3]), cost(row[5]));
        let is_lost = from_estimate - from_truth > 30.0;
        assert_eq!(row[7] == "yes", is_lost, "{row:?}");
        marked += usize::from(is_lost);
        // Started at the truth, the fit stays within a few centimetres of it.
        let truth_error_mm: f64 = row[6].parse().unwrap();
        assert!(truth_error_mm < 30.0, "{row:?}");
    }
    assert_eq!(marked, lost, "{out}");
    // Without the flag, no table.
    let out = estimate(&[]);
    assert!(!out.contains("the search lost"), "{out}");
    std::fs::remove_dir_all(&dir).ok();
}
