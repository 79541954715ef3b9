//! Generated real-robot sessions (`synth` with a simulated momentum
//! observer on a model with wrong inertials, link- or motor-side
//! sensing), seeds 1 and 2: the calibration finds the friction and cuts
//! the free residual, and `estimate` with its defaults keeps the free
//! motion free.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use crate::common;

use common::{estimate_figures, run, temp_dir};
use proprioscope::core::eval::synth::{ObserverSim, SynthSettings, synthesize_with_plant};
use proprioscope::core::over_time::calibration::{CalibrationSettings, calibrate};
use proprioscope::core::robot::builtin;
use proprioscope::core::robot::dynamics::RigidBodies;

fn settings(motor_side: bool) -> SynthSettings {
    SynthSettings {
        duration_secs: 4.0,
        rate_hz: 1000.0,
        noise_newton_metres: 0.02,
        motion_rad: 0.3,
        observer: Some(ObserverSim {
            motor_side,
            ..ObserverSim::default()
        }),
        ..SynthSettings::default()
    }
}

/// Motor side: every joint's Coulomb and viscous friction within 25 % of
/// the simulated; both sides: the free-motion RMS cut by 3× or more on
/// every joint where it was above the observer's filtered noise.
#[test]
fn the_calibration_finds_the_simulated_friction_and_model_error() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let links: Vec<usize> = ["lwr_4_link", "lwr_5_link", "lwr_6_link", "lwr_7_link"]
        .iter()
        .map(|n| robot.link_id(n).unwrap())
        .collect();
    let bodies = RigidBodies::new(&robot);
    let names: Vec<String> = robot.sensed_names().iter().map(|s| (*s).to_owned()).collect();
    for motor_side in [false, true] {
        for seed in [1, 2] {
            let (frames, plant) = synthesize_with_plant(&robot, &links, &settings(motor_side), seed).unwrap();
            let plant = plant.unwrap();
            let times: Vec<f64> = frames.iter().map(|f| f.t_secs).collect();
            let q: Vec<Vec<f64>> = frames.iter().map(|f| f.q.clone()).collect();
            let tau: Vec<Vec<f64>> = frames.iter().map(|f| f.tau.clone()).collect();
            let c = calibrate(
                &bodies,
                names.clone(),
                &times,
                &q,
                &tau,
                &CalibrationSettings::default(),
            )
            .unwrap();
            let case = format!("motor side {motor_side}, seed {seed}: {c:?}");
            assert!(c.found, "{case}");
            // The grid's neighbours of the simulated 50/s.
            let gain = c.observer_gain_per_s.unwrap();
            assert!((40.0..=70.0).contains(&gain), "{case}");
            for j in 0..names.len() {
                if c.rms_before_nm[j] > 0.01 {
                    assert!(c.rms_after_nm[j] * 3.0 <= c.rms_before_nm[j], "joint {j}, {case}");
                }
                if motor_side {
                    let (fc, fv) = (plant.coulomb_nm[j], plant.viscous_nms_per_rad[j]);
                    assert!(
                        (c.coulomb_nm[j] / fc - 1.0).abs() <= 0.25,
                        "joint {j} Coulomb {fc}, {case}"
                    );
                    assert!(
                        (c.viscous_nms_per_rad[j] / fv - 1.0).abs() <= 0.25,
                        "joint {j} viscous {fv}, {case}"
                    );
                }
            }
        }
    }
}

/// The command line on generated observer sessions: σ 0.05 without the
/// calibration calls most free frames contacts; the defaults do not.
#[test]
fn estimate_with_its_defaults_keeps_generated_free_motion_free() {
    let dir = temp_dir("observer-synth");
    for (sensing, seed, most_false_alarms) in [
        ("link", "1", 1.0),
        ("link", "2", 1.0),
        ("motor", "1", 2.0),
        ("motor", "2", 2.0),
    ] {
        let path = dir.join(format!("{sensing}-{seed}.session.json"));
        let path = path.to_str().unwrap();
        let made = run(&[
            "synth",
            path,
            "--seconds",
            "3",
            "--rate",
            "1000",
            "--seed",
            seed,
            "--observer-gain",
            "50",
            "--sensing",
            sensing,
            "--noise",
            "0.02",
            "--swing",
            "0.3",
            "--links",
            "lwr_4_link,lwr_5_link,lwr_6_link,lwr_7_link",
        ]);
        assert!(made.ok, "{}", made.err);
        let points = ["--points", "2000"];
        let raw = run(&[
            &["estimate", path, "--calibrate", "none", "--sigma", "0.05"],
            &points[..],
        ]
        .concat());
        assert!(raw.ok, "{}", raw.err);
        let (_, raw_false_alarms, _) = estimate_figures(&raw.out);
        assert!(raw_false_alarms > 30.0, "{sensing}: the test cannot tell\n{}", raw.out);
        let calibrated = run(&[&["estimate", path], &points[..]].concat());
        assert!(calibrated.ok, "{}", calibrated.err);
        let (detected, false_alarms, median_mm) = estimate_figures(&calibrated.out);
        assert!(detected >= 95.0, "{sensing}: {}", calibrated.out);
        assert!(false_alarms <= most_false_alarms, "{sensing}: {}", calibrated.out);
        assert!(median_mm <= 20.0, "{sensing}: {}", calibrated.out);
    }
}

/// A recording pressed three quarters of the time (presses of 1.5–3 s
/// sliding with kinetic friction, 0.3–1 s apart): the calibration reads σ
/// from its quietest tenth, so the presses are not taken into σ and the
/// free quarter stays free. Read from the quietest 30 %, as on recordings
/// that are mostly free, every free frame of this one was called contact
/// and the median error was 66 mm.
#[test]
fn a_recording_pressed_most_of_the_time_keeps_its_free_frames_free() {
    let dir = temp_dir("crowded");
    let path = dir.join("crowded.session.json");
    let more = ["--seconds", "12", "--rate", "50", "--press-secs", "1.5,3"];
    common::synth_slide_with(&path, "lwr_6_link", "2", &more);
    let path = path.to_str().unwrap();
    let estimated = run(&["estimate", path, "--points", "1000"]);
    assert!(estimated.ok, "{}", estimated.err);
    let (detected, false_alarms, median_mm) = estimate_figures(&estimated.out);
    assert!(detected >= 95.0, "{}", estimated.out);
    assert!(false_alarms <= 2.0, "{}", estimated.out);
    assert!(median_mm <= 10.0, "{}", estimated.out);
}

/// A session pressed four fifths of the time on link 4, where the fit
/// finds no model error: the gate's free frames read 6.3 times wider on
/// joint 1 than the frames the readings themselves call free, which
/// then set σ (0.048–0.052 N·m, 5–7 ms). From the gate's 586 free frames
/// (453 are), joint 1 read 0.31 N·m where the noise is 0.05, correlated
/// over 958 ms: σ 4.3 N·m once widened for it.
#[test]
fn a_crowded_recording_without_model_error_reads_sigma_from_its_free_frames() {
    let dir = temp_dir("crowded-sigma");
    let path = dir.join("crowded.session.json");
    common::synth_slide_with(&path, "lwr_4_link", "3", &["--seconds", "12", "--press-secs", "1.5,3"]);
    let learned = run(&[
        "calibrate",
        path.to_str().unwrap(),
        "--out",
        dir.join("c.json").to_str().unwrap(),
    ]);
    assert!(learned.ok, "{}", learned.err);
    assert!(learned.out.contains("no model error found"), "{}", learned.out);
    let rows: Vec<&str> = learned.out.lines().filter(|l| l.starts_with("| lwr_joint_")).collect();
    assert_eq!(rows.len(), 7, "{}", learned.out);
    for row in rows {
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        let rms: f64 = cells[2].parse().unwrap();
        let correlation_ms: f64 = cells[5].parse().unwrap();
        assert!(rms < 0.07 && correlation_ms < 20.0, "{row}\n{}", learned.out);
    }
}
