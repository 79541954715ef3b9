//! The torque model in the app (`egui_kittest` on Mesa's software
//! Vulkan): a recording whose torques come from a momentum observer opens
//! with the model error taken off and σ learned per joint, estimates
//! every frame as `estimate` does with its defaults, shows the
//! calibration per joint, and can take its calibration from a recording
//! of free motion or a file.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use crate::common;

use std::path::Path;

use common::{run, temp_dir};
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;
use proprioscope::app::{Command, ProprioscopeApp, open_target};
use proprioscope::core::estimate::summary::Verdict;

/// Runs frames until every frame of the session has its estimate.
fn settle_session(harness: &mut Harness<'_, ProprioscopeApp>) {
    for _ in 0..12_000 {
        harness.step();
        let app = harness.state();
        if app.is_up_to_date()
            && !app.calibration_pending()
            && !app.session.estimates.is_empty()
            && app.session.estimates.iter().all(Option::is_some)
        {
            harness.run_steps(2);
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    panic!("the session was not estimated within 120 s");
}

/// A 2 s motor-side observer recording at 1 kHz (friction, model error,
/// a lag of 20 ms) with presses on links 4–7.
fn observer_recording(dir: &Path) -> String {
    let path = dir.join("motor.session.json");
    let path = path.to_str().unwrap().to_owned();
    let made = run(&[
        "synth",
        &path,
        "--seconds",
        "2",
        "--rate",
        "1000",
        "--seed",
        "1",
        "--observer-gain",
        "50",
        "--sensing",
        "motor",
        "--noise",
        "0.02",
        "--swing",
        "0.3",
        "--links",
        "lwr_4_link,lwr_5_link,lwr_6_link,lwr_7_link",
    ]);
    assert!(made.ok, "{}", made.err);
    path
}

fn cli_estimates(path: &str, out: &Path) -> Vec<serde_json::Value> {
    let ran = run(&["estimate", path, "--out", out.to_str().unwrap()]);
    assert!(ran.ok, "{}", ran.err);
    std::fs::read_to_string(out)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// Frames whose verdict or place differ between the app and the command line.
fn differing(app: &ProprioscopeApp, cli: &[serde_json::Value]) -> usize {
    assert_eq!(app.session.estimates.len(), cli.len());
    app.session
        .estimates
        .iter()
        .zip(cli)
        .filter(|(e, c)| {
            let e = e.unwrap();
            match c["point"].as_array() {
                None => e.verdict != Verdict::NoContact,
                Some(p) => {
                    e.verdict == Verdict::NoContact
                        || e.point_world
                            .to_array()
                            .iter()
                            .zip(p)
                            .any(|(x, y)| (x - y.as_f64().unwrap()).abs() > 1e-9)
                }
            }
        })
        .count()
}

#[test]
fn an_observer_recording_opens_calibrated_as_the_command_line_estimates_it() {
    let dir = temp_dir("app-torque-model");
    let path = observer_recording(&dir);
    let cli = cli_estimates(&path, &dir.join("motor.jsonl"));
    let mut harness = proprioscope::app::headless_harness(open_target(Some(&path)).unwrap(), [1400.0, 900.0]);
    settle_session(&mut harness);
    {
        let app = harness.state();
        let done = app.session_calibration().expect("calibrated");
        assert!(done.applied && done.calibration.found);
        assert_eq!(done.calibration.observer_gain_per_s, Some(50.0));
        // σ is the one learned for frames combined over time, not the
        // default, and the per-joint table shows it.
        assert_eq!(app.model.sigma(), done.sigma_over_time.as_slice());
        assert!(app.model.sigma().iter().any(|s| (s - 0.05).abs() > 1e-3));
        assert_eq!(differing(app, &cli), 0, "the app and estimate differ");
    }
    assert!(harness.query_by_label("take off the model error").is_some());
    assert!(harness.query_by_label("RMS before").is_some());
    assert!(harness.query_by_label("taken off: model error and lag [N·m]").is_some());

    // Without the correction the frames estimate otherwise.
    // (The checkbox sends this command; it may lie below the panel's fold.)
    harness.state_mut().apply(Command::SetCalibrate(false));
    harness.run_steps(2);
    settle_session(&mut harness);
    {
        let app = harness.state();
        assert!(!app.model.config.torques.calibrate);
        assert!(!app.session_calibration().unwrap().applied);
        assert!(differing(app, &cli) > 0, "the correction changes nothing");
    }
    // σ set by hand is no longer learned.
    harness.state_mut().apply(Command::SetSigma(0.2));
    harness.run_steps(2);
    let app = harness.state();
    assert!(!app.model.config.torques.sigma_auto);
    assert!(app.model.sigma().iter().all(|s| (s - 0.2).abs() < 1e-12));
}

#[test]
fn a_calibration_comes_from_free_motion_or_a_file() {
    let dir = temp_dir("app-torque-model-file");
    let path = observer_recording(&dir);
    let mut harness = proprioscope::app::headless_harness(open_target(Some(&path)).unwrap(), [1400.0, 900.0]);
    settle_session(&mut harness);
    let learned = harness.state().session_calibration().unwrap().calibration.clone();
    // Saved, then read back as the calibration of the session.
    let file = dir.join("robot.calib.json");
    harness.state_mut().save_calibration(&file);
    assert!(harness.state().error.is_none(), "{:?}", harness.state().error);
    harness.state_mut().open_calibration(file.clone());
    assert!(harness.state().error.is_none(), "{:?}", harness.state().error);
    settle_session(&mut harness);
    {
        let done = harness.state().session_calibration().unwrap();
        assert_eq!(done.source.as_deref(), Some(file.as_path()));
        assert_eq!(done.calibration, learned);
    }
    assert!(harness.query_by_label(&format!("from {}", file.display())).is_some());
    // Learned from a recording taken as free motion (every frame fits).
    harness.state_mut().calibrate_from(Path::new(&path).to_owned());
    for _ in 0..6000 {
        harness.step();
        if harness
            .state()
            .session
            .external_calibration
            .as_ref()
            .is_some_and(|e| e.source.as_path() == Path::new(&path))
        {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    settle_session(&mut harness);
    let done = harness.state().session_calibration().unwrap();
    assert_eq!(done.source.as_deref(), Some(Path::new(&path)));
    assert!(done.calibration.found && done.applied);
    // Every frame was read as free.
    assert_eq!(done.calibration.free_frames, done.calibration.frames_read);
    // A file for other joints is refused, naming them.
    let mut other = std::fs::read_to_string(&file).unwrap();
    other = other.replace("lwr_joint_1", "elbow");
    let bad = dir.join("other.calib.json");
    std::fs::write(&bad, other).unwrap();
    harness.state_mut().open_calibration(bad);
    let error = harness.state().error.clone().unwrap_or_default();
    assert!(error.contains("elbow"), "{error}");
}
