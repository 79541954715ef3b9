//! Extreme numbers: every numeric input outside its range is refused with
//! its name and range, nothing overflows into `inf` or `NaN`, a summary of
//! nothing says so in words, and a mesh that repeats one face 20,000 times
//! loads with its area counted once.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use crate::common;

use std::fmt::Write as _;

use common::{null_number, run, run_with_env, temp_dir};
use proprioscope::core::config::limits::{self, Range};
use proprioscope::core::estimate::estimator::Estimator;
use proprioscope::core::estimate::settings::EstimatorSettings;
use proprioscope::core::eval::synth::{SynthSettings, as_sequence, joint_positions, synthesize};
use proprioscope::core::over_time::sequence::{Temporal, estimate_sequence_while};
use proprioscope::core::over_time::temporal::{TemporalModel, TemporalSettings};
use proprioscope::core::robot::builtin;
use proprioscope::core::surface::sampling::SurfaceRequest;

/// `torques` on a push of `simple6`, with `flag` set to `value` (given
/// as `--flag=value`, so that a value may start with a minus).
fn torques(flag: &str, value: &str) -> common::Ran {
    let given = format!("{flag}={value}");
    let mut args = vec!["torques", "--robot", "simple6", "--link", "link_3"];
    for (f, default) in [
        ("--point", "--point=0.1,0,0.5"),
        ("--force", "--force=-0.988,-0.759,-0.318"),
    ] {
        if f != flag {
            args.push(default);
        }
    }
    args.push(&given);
    run(&args)
}

#[test]
fn overflowing_pushes_are_refused_naming_the_argument_and_its_range() {
    for (flag, value, range) in [
        ("--point", "1.7976931348623157e308,0,0", limits::COORDINATE),
        ("--point", "0,-1e308,0", limits::COORDINATE),
        ("--force", "-1e308,1e308,0", limits::FORCE_COMPONENT),
        ("--q", "-1e308,0,0,0,0,0", limits::JOINT_POSITION),
        ("--q", "inf,0,0,0,0,0", limits::JOINT_POSITION),
    ] {
        let ran = torques(flag, value);
        assert!(!ran.ok, "{flag} {value}: {}", ran.out);
        assert!(
            ran.err.contains(flag) && ran.err.contains(&range.interval()),
            "{flag} {value}: {}",
            ran.err
        );
        assert!(!ran.out.contains("inf"), "{}", ran.out);
    }
    // At the edges of the ranges every torque is a finite number.
    let ran = run(&[
        "torques",
        "--robot",
        "simple6",
        "--link",
        "link_5",
        "--point=-1000,1000,-1000",
        "--force=1e6,-1e6,1e6",
        "--q=10000,-10000,10000,-10000,10000,-10000",
        "--json",
    ]);
    assert!(ran.ok, "{}", ran.err);
    let v: serde_json::Value = serde_json::from_str(&ran.out).unwrap();
    for joint in v["joints"].as_array().unwrap() {
        assert!(joint["torque"].as_f64().unwrap().is_finite(), "{joint}");
    }
}

/// Every numeric option of the commands: its range in `--help`, and a
/// value outside refused with the option and the range named.
#[test]
fn every_numeric_option_documents_its_range_and_refuses_values_outside() {
    let cases: [(&[&str], &str, Range, &str); 18] = [
        (&["estimate", "x.json"], "--sigma", limits::SIGMA, "1e-9"),
        (&["estimate", "x.json"], "--fmin", limits::FORCE_MIN, "1e308"),
        (&["estimate", "x.json"], "--fmax", limits::FORCE_MAX, "0"),
        (&["estimate", "x.json"], "--alpha", limits::ALPHA, "1"),
        (&["estimate", "x.json"], "--friction", limits::FRICTION, "3"),
        (&["estimate", "x.json"], "--onset-rate", limits::EVENT_RATE, "-1"),
        (&["estimate", "x.json"], "--release-rate", limits::EVENT_RATE, "1e9"),
        (&["estimate", "x.json"], "--jump-rate", limits::EVENT_RATE, "nan"),
        (&["estimate", "x.json"], "--slide", limits::SLIDE, "5"),
        (&["estimate", "x.json"], "--bias-window", limits::BIAS_WINDOW, "0"),
        (&["synth", "x.json"], "--seconds", limits::SECONDS, "1e308"),
        (&["synth", "x.json"], "--rate", limits::RATE_HZ, "0"),
        (&["synth", "x.json"], "--friction", limits::FRICTION, "-0.1"),
        (&["synth", "x.json"], "--bias", limits::BIAS, "1e300"),
        (&["synth", "x.json"], "--slide", limits::SLIDE_SPEED, "2"),
        (&["synth", "x.json"], "--noise", limits::NOISE, "-1"),
        (&["synth", "x.json"], "--press-secs", limits::SECONDS, "0,1"),
        (&["bench"], "--noise", limits::NOISE, "1e200"),
    ];
    for (command, flag, range, bad) in cases {
        let help = run(&[command[0], "--help"])
            .out
            .split_whitespace()
            .collect::<Vec<_>>()
            .join(" ")
            .to_lowercase();
        let documented = format!("valid: {}", range.interval());
        let at = help
            .find(&format!("{flag} <"))
            .unwrap_or_else(|| panic!("{flag} in {help}"));
        let next = help[at + 2..].find(" --").map_or(help.len(), |n| at + 2 + n);
        assert!(
            help[at..next].contains(&documented),
            "{} {flag}: help says {}",
            command[0],
            &help[at..next]
        );
        let mut args = command.to_vec();
        let joined = format!("{flag}={bad}");
        args.push(&joined);
        let ran = run(&args);
        assert!(!ran.ok, "{} {joined}", command[0]);
        assert!(
            ran.err.contains(flag) && ran.err.contains(&range.interval()),
            "{} {joined}: {}",
            command[0],
            ran.err
        );
    }
    for (command, flag, bad, range) in [
        ("estimate", "--points", "0", "1 to"),
        ("estimate", "--particles", "0", "1 to"),
        ("estimate", "--m", "5000", "1 to 1000"),
        ("estimate", "--phase-sizes", "0,10", "1 to"),
        ("estimate", "--threads", "0", "1 to 1024"),
        ("bench", "--contacts", "0", "1 to"),
    ] {
        let joined = format!("{flag}={bad}");
        let ran = if command == "bench" {
            run(&[command, &joined])
        } else {
            run(&[command, "x.json", &joined])
        };
        assert!(
            !ran.ok && ran.err.contains(flag) && ran.err.contains(range),
            "{joined}: {}",
            ran.err
        );
    }
    let ran = run(&["estimate", "x.json", "--fmin=20", "--fmax=10"]);
    assert!(!ran.ok, "{}", ran.out);
}

#[test]
fn a_session_of_bad_frames_only_summarises_nothing_in_words() {
    let dir = temp_dir("bad-only");
    let path = dir.join("bad.session.json");
    std::fs::write(
        &path,
        r#"{"format": "contact-session", "version": 1, "robot": "lwr4plus", "frames": [
          {"t": 0, "q": [0, 0, 0, 0, 0, 0, 0], "tau": [1e300, 0, 0, 0, 0, 0, 0]},
          {"t": 1, "q": [0, 0, 0, 0, 0, 0, 0], "tau": [0, 0, 0]}]}"#,
    )
    .unwrap();
    let ran = run(&["estimate", path.to_str().unwrap(), "--skip-bad-frames"]);
    assert!(ran.ok, "{}", ran.err);
    assert!(ran.out.contains("update time: no frame was estimated"), "{}", ran.out);
    for text in [&ran.out, &ran.err] {
        assert!(!text.contains("NaN") && !text.contains("inf"), "{text}");
    }
    assert!(
        ran.err.contains("tau[0]") && ran.err.contains("joint torque"),
        "{}",
        ran.err
    );
}

/// The fields of an estimate's JSON line that may be null, and when.
fn nullable(line: &serde_json::Value) -> Vec<&'static str> {
    // A slide needs a contact on one link in the frame before too.
    let mut ok = vec![
        "update_parts_ms",
        "contact_probability",
        "truth",
        "slide_velocity_in_link",
    ];
    if line["verdict"] == "no_contact" {
        ok.extend([
            "link",
            "point",
            "force",
            "grid",
            "links",
            "point_in_link",
            "force_tangential",
        ]);
    }
    ok
}

/// At the edges of every range the estimator is given (σ at its least,
/// the widest force range, the most friction, the fastest model), every
/// frame's estimate is finite, each alone, filtered and smoothed.
#[test]
fn estimates_at_the_edges_of_the_ranges_are_finite_numbers() {
    let dir = temp_dir("edges");
    let session = dir.join("synth.session.json");
    let ran = run(&[
        "synth",
        session.to_str().unwrap(),
        "--seconds",
        "1.5",
        "--rate",
        "40",
        "--seed",
        "3",
        "--friction",
        "0.3",
        "--links",
        "lwr_5_link,lwr_6_link",
    ]);
    assert!(ran.ok, "{}", ran.err);
    for (temporal, extra) in [
        ("none", ["--sigma=0.0001", "--fmin=0", "--fmax=10000", "--friction=2"]),
        (
            "filter",
            ["--sigma=0.0001", "--fmin=0", "--fmax=10000", "--release-rate=1000"],
        ),
        ("smooth", ["--sigma=0.0001", "--fmin=0", "--fmax=10000", "--slide=1"]),
        (
            "smooth",
            ["--sigma=100", "--fmin=10000", "--fmax=10000", "--onset-rate=0"],
        ),
    ] {
        let out = dir.join(format!("{temporal}.jsonl"));
        let mut args = vec![
            "estimate",
            session.to_str().unwrap(),
            "--points",
            "600",
            "--temporal",
            temporal,
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend(extra);
        let ran = run(&args);
        assert!(ran.ok, "{temporal} {extra:?}: {}", ran.err);
        for text in [&ran.out, &ran.err] {
            assert!(
                !text.contains("NaN") && !text.contains("inf"),
                "{temporal} {extra:?}: {text}"
            );
        }
        let lines = std::fs::read_to_string(&out).unwrap();
        assert!(!lines.is_empty());
        for line in lines.lines() {
            let v: serde_json::Value = serde_json::from_str(line).unwrap();
            assert_eq!(null_number(&v, &nullable(&v), ""), None, "{temporal} {extra:?}: {line}");
        }
    }
}

/// The library itself takes a σ far below the command line's range; its
/// estimates are then finite numbers or an error for the frame (torques
/// beyond what a frame may hold), never a NaN point: a σ of 1e-9 N·m once
/// smoothed the shared link-4 example to `[NaN, NaN, NaN]` in 101 frames.
#[test]
fn a_sigma_far_below_the_torques_precision_never_gives_a_nan_estimate() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let links = robot.default_candidate_links();
    let pressed: Vec<usize> = links.iter().copied().filter(|&l| l >= 4).collect();
    let synth = SynthSettings {
        duration_secs: 1.5,
        ..SynthSettings::default()
    };
    let frames = synthesize(&robot, &pressed, &synth, 2).unwrap();
    let positions = joint_positions(&robot, &frames).unwrap();
    let sequence = as_sequence(&frames, &positions);
    for sigma in [1e-6, 1e-9, 1e-12] {
        let request = SurfaceRequest {
            links: links.clone(),
            total_points: 1000,
            seed: 0,
        };
        let estimator = Estimator::new(&robot, &request, EstimatorSettings::exact(vec![sigma; 7]), None).unwrap();
        let model = TemporalModel::new(&estimator.surface, TemporalSettings::default(), true).unwrap();
        for temporal in [Temporal::None, Temporal::Filter, Temporal::Smooth] {
            let (mut finite, mut refused) = (0, 0);
            estimate_sequence_while(
                &estimator,
                &robot,
                (Some(&model), temporal),
                &sequence,
                || true,
                |_, update, _| {
                    assert_eq!(update.summary.non_finite_field(), None, "σ {sigma} {temporal:?}");
                    assert!(update.summary.map.point_world.is_finite());
                    finite += 1;
                },
                |_, _| {
                    refused += 1;
                    true
                },
            )
            .unwrap();
            assert_eq!(finite + refused, sequence.len(), "σ {sigma} {temporal:?}");
            if sigma >= 1e-6 {
                assert_eq!(refused, 0, "σ {sigma} {temporal:?}");
            }
        }
    }
}

#[test]
fn a_mesh_repeating_one_face_loads_with_its_area_counted_once() {
    let dir = temp_dir("repeated-faces");
    // A 0.1 × 0.1 × 0.3 m box (area 0.14 m²), its first face 20,000 times more.
    let mut obj = String::new();
    for x in [-0.05, 0.05] {
        for y in [-0.05, 0.05] {
            for z in [0.0, 0.3] {
                let _ = writeln!(obj, "v {x} {y} {z}");
            }
        }
    }
    let quads = [
        [1, 3, 4, 2],
        [5, 6, 8, 7],
        [1, 2, 6, 5],
        [3, 7, 8, 4],
        [1, 5, 7, 3],
        [2, 4, 8, 6],
    ];
    for [a, b, c, d] in quads {
        let _ = write!(obj, "f {a} {b} {c}\nf {a} {c} {d}\n");
    }
    obj += &"f 1 3 4\n".repeat(20_000);
    std::fs::write(dir.join("box.obj"), obj).unwrap();
    std::fs::write(
        dir.join("arm.urdf"),
        r#"<robot name="repeats"><link name="base"/>
        <link name="arm"><visual><geometry><mesh filename="box.obj"/></geometry></visual></link>
        <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
        <limit lower="-3" upper="3" effort="1" velocity="1"/></joint></robot>"#,
    )
    .unwrap();
    std::fs::write(
        dir.join("scene.json"),
        r#"{"version": 1, "robot": "arm.urdf", "q": [0.2], "surface_points": 500}"#,
    )
    .unwrap();
    let ran = run(&["surface", dir.join("scene.json").to_str().unwrap()]);
    assert!(ran.ok, "{}", ran.err);
    let row = ran.out.lines().find(|l| l.starts_with("arm ")).unwrap();
    let area: f64 = row.split_whitespace().nth(1).unwrap().parse().unwrap();
    assert!((area - 0.14).abs() < 1e-4, "{}", ran.out);
}

/// The libraries' messages reach stderr through the logger (a GPU
/// validation error would otherwise vanish), `RUST_LOG` chooses, and our
/// own warnings say so.
#[test]
fn the_logger_shows_warnings_and_respects_rust_log() {
    let dir = temp_dir("logger");
    let path = dir.join("one-bad.session.json");
    std::fs::write(
        &path,
        r#"{"format": "contact-session", "version": 1, "robot": "lwr4plus", "frames": [
          {"t": 0, "q": [0, 0, 0, 0, 0, 0, 0], "tau": [0, 0, 0, 0, 0, 0, 0]},
          {"t": 1, "q": [0, 0, 0, 0, 0, 0, 0], "tau": [0, 0, 0]}]}"#,
    )
    .unwrap();
    let args = [
        "estimate",
        path.to_str().unwrap(),
        "--skip-bad-frames",
        "--points",
        "300",
    ];
    let by_default = run(&args);
    assert!(by_default.ok, "{}", by_default.err);
    assert!(
        by_default.err.contains("warning: ") && by_default.err.contains("skipped frame 1"),
        "{}",
        by_default.err
    );
    assert!(by_default.err.contains("300 surface points"), "{}", by_default.err);
    let errors_only = run_with_env(&args, &[("RUST_LOG", "error")]);
    assert!(errors_only.ok);
    assert!(
        !errors_only.err.contains("skipped") && !errors_only.err.contains("surface points"),
        "{}",
        errors_only.err
    );
}

/// A library's own messages reach stderr named by the library: the GPU
/// stack's, on the headless renderer.
#[cfg(feature = "gui")]
#[test]
fn the_gpu_stack_reports_through_the_logger() {
    let out = temp_dir("gpu-log").join("shot.png");
    let ran = run_with_env(
        &[
            "screenshot",
            "--out",
            out.to_str().unwrap(),
            "--width",
            "160",
            "--height",
            "120",
        ],
        &[("RUST_LOG", "wgpu_core=debug,wgpu_hal=debug,egui_wgpu=debug")],
    );
    assert!(ran.ok, "{}", ran.err);
    assert!(
        ["[wgpu_core", "[wgpu_hal", "[egui_wgpu"]
            .iter()
            .any(|t| ran.err.contains(t)),
        "{}",
        ran.err.chars().take(2000).collect::<String>()
    );
}

/// `docs/cli.md` lists every valid range as the program checks it.
#[test]
fn the_documentation_lists_every_range() {
    let docs = std::fs::read_to_string(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/cli.md")).unwrap();
    for range in limits::RANGES {
        let row = format!("| {} | {range} |", range.quantity);
        assert!(docs.contains(&row), "docs/cli.md lacks {row}");
    }
    for count in limits::COUNTS {
        let row = format!("| {} | {count} |", count.quantity);
        assert!(docs.contains(&row), "docs/cli.md lacks {row}");
    }
}
