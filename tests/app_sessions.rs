//! The desktop app driven headless (`egui_kittest`, wgpu on Mesa's software
//! Vulkan): sessions, recordings and live
//! streams on the timeline.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use crate::common::app as app_common;

use std::path::Path;

use app_common::{app_harness, settle};
use eframe::egui;
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;
use proprioscope::app::{ProprioscopeApp, open_target};

/// A recorded session (the hidden `record-demo` command: the built-in LWR
/// waving, pushed on link 5), `seconds` long at 20 frames a second.
fn demo_session(name: &str, seconds: f64) -> std::path::PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("app-sessions");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_proprioscope"))
        .args([
            "record-demo",
            "--rate",
            "20",
            "--seconds",
            &seconds.to_string(),
            "--out",
        ])
        .arg(&path)
        .stdout(std::process::Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    path
}

/// A session drawn by `synth` with `args`, named `name` in this test's
/// folder.
fn synth_session(name: &str, args: &[&str]) -> std::path::PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("app-sessions");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_proprioscope"))
        .arg("synth")
        .arg(&path)
        .args(args)
        .stdout(std::process::Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    path
}

fn session_harness(path: &Path) -> Harness<'static, ProprioscopeApp> {
    let mut harness =
        proprioscope::app::headless_harness(open_target(Some(path.to_str().unwrap())).unwrap(), [1400.0, 900.0]);
    settle(&mut harness);
    assert!(harness.state().model.replay.is_some(), "{:?}", harness.state().error);
    harness
}

#[test]
fn pressing_play_advances_the_frame() {
    let path = demo_session("play.session.json", 1.0);
    let mut harness = session_harness(&path);
    assert_eq!(harness.state().model.replay.as_ref().unwrap().frame, 0);
    harness.get_by_label("Play").click();
    // A few frames of the harness (each up to 0.1 s of playback).
    harness.run_steps(3);
    let replay = harness.state().model.replay.clone().unwrap();
    assert!(replay.playing);
    assert!(replay.frame > 0, "still at frame 0");
    // The arm follows the frame.
    assert_eq!(harness.state().model.q, replay.session.frames[replay.frame].q);
    // Space pauses, the right arrow steps one frame.
    harness.key_press(egui::Key::Space);
    harness.run_steps(2);
    let paused = harness.state().model.replay.clone().unwrap();
    assert!(!paused.playing);
    harness.key_press(egui::Key::ArrowRight);
    harness.run_steps(2);
    assert_eq!(harness.state().model.replay.as_ref().unwrap().frame, paused.frame + 1);
}

#[test]
fn dragging_the_timeline_changes_q() {
    let path = demo_session("drag.session.json", 1.0);
    let mut harness = session_harness(&path);
    let q0 = harness.state().model.q.clone();
    let rect = harness
        .get_by_role_and_label(egui::accesskit::Role::Slider, "frame")
        .rect();
    let from = egui::pos2(rect.left() + 2.0, rect.center().y);
    let to = egui::pos2(rect.left() + 0.6 * rect.width(), rect.center().y);
    harness.hover_at(from);
    harness.drag_at(from);
    harness.run_steps(1);
    harness.hover_at(to);
    harness.run_steps(1);
    harness.drop_at(to);
    harness.run_steps(2);
    let app = harness.state();
    let replay = app.model.replay.as_ref().unwrap();
    assert!(replay.frame > 5, "frame {}", replay.frame);
    assert_eq!(app.model.q, replay.session.frames[replay.frame].q);
    assert_ne!(app.model.q, q0);
    // The torques the estimator is given are the frame's.
    let pose = proprioscope::core::robot::kinematics::RobotPose::new(&app.model.robot, &app.model.joint_positions());
    assert_eq!(
        app.model.measured_torques(&pose),
        replay.session.frames[replay.frame].tau
    );
}

#[test]
fn a_session_with_three_bad_frames_lists_them_and_plays_the_rest() {
    let path = demo_session("bad.session.json", 0.5);
    // Frame lines follow the header line: break frames 2, 4 and 7.
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    // Frame 2: its first torque becomes null (a missing value).
    let at = lines[3].find("\"tau\":[").unwrap() + "\"tau\":[".len();
    let comma = at + lines[3][at..].find(',').unwrap();
    lines[3] = format!("{}null{}", &lines[3][..at], &lines[3][comma..]);
    // Frame 4: one torque too many; frame 7: time goes backwards.
    lines[5] = lines[5].replacen("\"tau\":[", "\"tau\":[0.5,", 1);
    lines[8] = lines[8].replacen("\"t\":", "\"t\":-1.0,\"was\":", 1);
    let bad = path.with_file_name("three-bad.session.json");
    std::fs::write(&bad, lines.join("\n")).unwrap();
    let mut harness = session_harness(&bad);
    let replay = harness.state().model.replay.clone().unwrap();
    let problems: Vec<(usize, String)> = replay
        .session
        .problems
        .iter()
        .map(|p| (p.frame, p.field.clone()))
        .collect();
    assert_eq!(
        problems,
        [(2, "tau[0]".to_owned()), (4, "tau".to_owned()), (7, "t".to_owned())]
    );
    assert_eq!(replay.session.frames.len(), 8);
    // Listed in the session panel, by frame and field.
    for p in &replay.session.problems {
        harness.get_by_label_contains(&format!("frame {} (t = ", p.frame));
    }
    harness.get_by_label("Play").click();
    harness.run_steps(30);
    assert!(harness.state().model.replay.as_ref().unwrap().frame > 0);
}

#[test]
fn the_app_records_a_session_that_reads_back_bit_for_bit() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("app-sessions");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("recorded-in-app.session.json");
    let mut harness = app_harness();
    settle(&mut harness);
    harness.state_mut().start_recording(&path);
    let script = [0.1, 0.2, 0.3, -0.4, 0.5];
    for &q0 in &script {
        harness.state_mut().apply(proprioscope::app::Command::SetJoint(0, q0));
        harness.run_steps(2);
    }
    let written = harness.state_mut().stop_recording().unwrap();
    assert!(written >= script.len(), "{written}");
    let session = proprioscope::io::session::Session::read(&path).unwrap();
    assert_eq!(session.frames.len(), written);
    // Every scripted pose is there, in order, with the torques the app
    // measured for it, bit for bit.
    let mut at = 0;
    for &q0 in &script {
        at += session.frames[at..]
            .iter()
            .position(|f| f.q[0].to_bits() == q0.to_bits())
            .unwrap();
        let frame = &session.frames[at];
        let mut model = harness.state().model.clone();
        model.apply(proprioscope::app::Command::SetJoint(0, q0));
        let pose = proprioscope::core::robot::kinematics::RobotPose::new(&model.robot, &model.joint_positions());
        assert_eq!(frame.tau, model.measured_torques(&pose));
        assert!(matches!(frame.truth, proprioscope::io::session::Truth::Contact { .. }));
    }
}

#[test]
fn the_timeline_estimates_equal_the_estimate_command() {
    let path = demo_session("same.session.json", 0.5);
    let out = path.with_file_name("same.jsonl");
    // The defaults the app and the command line share (one configuration).
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_proprioscope"))
        .arg("estimate")
        .arg(&path)
        .args(["--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let cli: Vec<serde_json::Value> = std::fs::read_to_string(&out)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let harness = session_harness(&path);
    let app = harness.state();
    assert_eq!(app.session.estimates.len(), cli.len());
    for (i, (e, c)) in app.session.estimates.iter().zip(&cli).enumerate() {
        let e = e.unwrap();
        assert_eq!(c["link"], app.model.robot.links[e.link].name.as_str(), "frame {i}");
        for (field, ours) in [("point", e.point_world), ("force", e.force_world)] {
            let theirs = c[field].as_array().unwrap();
            for (k, (x, y)) in ours.to_array().iter().zip(theirs).enumerate() {
                assert!((x - y.as_f64().unwrap()).abs() < 1e-12, "frame {i} {field}[{k}]");
            }
        }
    }
}

/// The timeline keeps the height it opens with (a third of the window):
/// its plots fill it to the pixel, and it neither shrinks nor grows frame
/// after frame (it shrank by 6 px a frame to its plots' least height,
/// undoing any resizing).
#[test]
fn the_timeline_keeps_its_height() {
    let path = demo_session("height.session.json", 1.0);
    let mut harness = session_harness(&path);
    let top = |harness: &Harness<'_, ProprioscopeApp>| harness.get_by_label("|<").rect().top();
    let opened = top(&harness);
    // 0.34 of the 900 px window, less the panel's margin above the button.
    assert!(
        (560.0..=620.0).contains(&opened),
        "the timeline's first row at y = {opened}"
    );
    harness.run_steps(60);
    let after = top(&harness);
    assert!(
        (after - opened).abs() < 0.5,
        "the timeline moved from y = {opened} to {after}"
    );
}

/// A replayed session (the demo recording: deterministic frames) against
/// its snapshot: timeline, plots and session panel.
#[test]
fn session_replay_matches_its_snapshot() {
    let options = egui_kittest::SnapshotOptions::new()
        .threshold(2.0)
        .max_failed_pixels(4000);
    let path = demo_session("snapshot.session.json", 1.0);
    let mut harness = session_harness(&path);
    harness.state_mut().apply(proprioscope::app::Command::SetFrame(10));
    settle(&mut harness);
    harness.snapshot_options("session", &options);
}

/// A recording opens smoothed (as `estimate --temporal auto`), every
/// frame with its contact probability; choosing "each frame alone" in the
/// timeline re-estimates the frames alone, without one.
#[test]
fn a_recording_is_smoothed_and_can_be_estimated_frame_by_frame() {
    use proprioscope::core::over_time::sequence::Temporal;
    let path = demo_session("over-time.session.json", 0.5);
    let mut harness = session_harness(&path);
    {
        let app = harness.state();
        assert_eq!(app.model.replay.as_ref().unwrap().over_time, Temporal::Smooth);
        assert!(
            app.session
                .estimates
                .iter()
                .all(|e| e.is_some_and(|e| e.contact_probability.is_some_and(|p| (0.0..=1.0).contains(&p)))),
            "{:?}",
            app.session.estimates
        );
    }
    harness.get_by_label("over time").click();
    harness.run();
    harness.get_by_label("each frame alone").click();
    settle(&mut harness);
    let app = harness.state();
    assert_eq!(app.model.replay.as_ref().unwrap().over_time, Temporal::None);
    assert!(
        app.session
            .estimates
            .iter()
            .all(|e| e.is_some_and(|e| e.contact_probability.is_none())),
        "{:?}",
        app.session.estimates
    );
}

/// Filtered or smoothed, the timeline offers the slide length (as
/// `estimate --slide`); setting it estimates the session again with it
/// (the smoothed places move), out of range it is refused with its range
/// named (the slide stays), and frames estimated alone offer none.
#[test]
fn the_slide_length_is_set_in_the_timeline() {
    use proprioscope::app::Command;
    use proprioscope::core::over_time::sequence::Temporal;
    let path = demo_session("slide.session.json", 1.0);
    let mut harness = session_harness(&path);
    assert!(harness.query_all_by_label("slide").next().is_some());
    let places = |harness: &Harness<'_, ProprioscopeApp>| -> Vec<glam::DVec3> {
        harness
            .state()
            .session
            .estimates
            .iter()
            .map(|e| e.unwrap().point_world)
            .collect()
    };
    let before = places(&harness);
    harness.state_mut().apply(Command::SetSlide(0.05));
    settle(&mut harness);
    let slide = harness.state().model.config.temporal.slide_m_per_sqrt_s;
    assert!((slide - 0.05).abs() < 1e-15);
    let after = places(&harness);
    assert!(
        before.iter().zip(&after).any(|(b, a)| b.distance(*a) > 1e-6),
        "{before:?}\n{after:?}"
    );
    harness.state_mut().apply(Command::SetSlide(5.0));
    let refused = harness.state().model.refused.clone().unwrap_or_default();
    assert!(
        refused.contains("slide") && refused.contains("[0.001, 0.1] m/√s"),
        "{refused}"
    );
    harness.state_mut().apply(Command::SetSlide(f64::NAN));
    let slide = harness.state().model.config.temporal.slide_m_per_sqrt_s;
    assert!((slide - 0.05).abs() < 1e-15, "{slide}");
    harness.state_mut().apply(Command::SetOverTime(Temporal::None));
    settle(&mut harness);
    assert!(harness.query_all_by_label("slide").next().is_none());
}

#[test]
fn session_metrics_export_as_json() {
    let path = demo_session("metrics.session.json", 0.5);
    let mut harness = session_harness(&path);
    let out = path.with_file_name("metrics.json");
    harness.state_mut().export_metrics(&out);
    assert_eq!(harness.state().error, None);
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(json["all"]["frames"], 11);
    assert_eq!(json["by_sensing_joints"][0]["sensing_joints"], 5);
    let median = json["all"]["position_error_median_m"].as_f64().unwrap();
    assert!(median.is_finite() && median >= 0.0, "{json}");
    // How often the 90 % set held the push: every contact frame tells.
    let held = json["all"]["credible90_held"].as_f64().unwrap();
    assert!((0.0..=1.0).contains(&held), "{json}");
}

#[test]
fn changing_sigma_re_estimates_the_session_in_the_background() {
    let path = demo_session("resigma.session.json", 0.5);
    let mut harness = session_harness(&path);
    // From σ 0.1 N·m (twice the recording's noise: every frame a contact).
    harness.state_mut().apply(proprioscope::app::Command::SetSigma(0.1));
    settle(&mut harness);
    let map_probabilities =
        |app: &ProprioscopeApp| -> Vec<f64> { app.session.estimates.iter().map(|e| e.unwrap().probability).collect() };
    let before = map_probabilities(harness.state());
    harness
        .get_by_role_and_label(egui::accesskit::Role::Slider, "σ [N·m]")
        .set_value_accesskit(0.5);
    harness.run_steps(2);
    settle(&mut harness);
    let after = map_probabilities(harness.state());
    assert_eq!(after.len(), before.len());
    // A broader likelihood spreads every frame's posterior.
    for (i, (b, a)) in before.iter().zip(&after).enumerate() {
        assert!(a < b, "frame {i}: MAP probability {b} -> {a}");
    }
}

#[test]
fn sessions_with_no_good_frame_or_the_wrong_robot_do_not_break_the_app() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("app-sessions");
    std::fs::create_dir_all(&dir).unwrap();
    // Every frame bad: it opens, lists them, and the timeline is empty.
    let all_bad = dir.join("all-bad.session.json");
    std::fs::write(
        &all_bad,
        r#"{"format": "contact-session", "version": 1, "robot": "lwr4plus", "frames": [
            {"t": 0.0, "q": [0, 0, 0, 0, 0, 0, 0], "tau": [0, 0, 0, 0, 0, 0, null]},
            {"t": 0.1, "q": [0, 0, 0], "tau": [0, 0, 0, 0, 0, 0, 0]}]}"#,
    )
    .unwrap();
    let mut harness = session_harness(&all_bad);
    let replay = harness.state().model.replay.clone().unwrap();
    assert!(replay.session.frames.is_empty());
    assert_eq!(replay.session.problems.len(), 2);
    harness.key_press(egui::Key::Space);
    harness.key_press(egui::Key::ArrowRight);
    harness.run_steps(3);
    // Three joints of a seven-joint robot: refused, the session stays.
    let wrong = dir.join("three-joints.csv");
    std::fs::write(&wrong, "t,q1,q2,q3,tau1,tau2,tau3\n0.0,0,0,0,0.1,0.2,0.3\n").unwrap();
    harness.state_mut().open_session(&wrong, Some("lwr4plus".to_owned()));
    settle(&mut harness);
    let error = harness.state().error.clone().unwrap();
    assert!(
        error.contains("three-joints.csv") && error.contains("3 joint values"),
        "{error}"
    );
    assert!(
        harness
            .state()
            .model
            .replay
            .as_ref()
            .unwrap()
            .session
            .path
            .ends_with("all-bad.session.json")
    );
}

#[test]
fn stepping_back_to_a_visited_frame_shows_its_estimate_at_once() {
    let path = demo_session("visited.session.json", 0.5);
    let mut harness = session_harness(&path);
    let first = harness.state().outcome.clone().unwrap();
    harness.key_press(egui::Key::ArrowRight);
    harness.run_steps(2);
    settle(&mut harness);
    assert_eq!(harness.state().visited_hits, 0);
    harness.key_press(egui::Key::ArrowLeft);
    harness.run_steps(1);
    let app = harness.state();
    assert_eq!(app.visited_hits, 1);
    assert!(app.is_up_to_date());
    let shown = app.outcome.as_ref().unwrap().update.as_ref().unwrap();
    assert_eq!(shown.posterior, first.update.as_ref().unwrap().posterior);
    // A new σ is a new estimate, not a kept one.
    harness
        .get_by_role_and_label(egui::accesskit::Role::Slider, "σ [N·m]")
        .set_value_accesskit(0.3);
    harness.run_steps(2);
    settle(&mut harness);
    assert_eq!(harness.state().visited_hits, 1);
}

/// A frame whose estimate fails (torques beyond what can be computed at
/// the σ chosen: 1e5 N·m at 1e-4 N·m) is counted and listed: the timeline
/// settles instead of waiting for it forever, and the other frames are
/// estimated.
#[test]
fn a_session_frame_that_cannot_be_estimated_is_counted_and_the_timeline_settles() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("app-sessions");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("one-absurd-frame.session.json");
    std::fs::write(
        &path,
        r#"{"format": "contact-session", "version": 1, "robot": "lwr4plus", "frames": [
            {"t": 0.0, "q": [0, 0, 0, 0, 0, 0, 0], "tau": [0.1, 0, 0, 0, 0, 0, 0]},
            {"t": 0.1, "q": [0, 0, 0, 0, 0, 0, 0], "tau": [1e5, 0, 0, 0, 0, 0, 0]},
            {"t": 0.2, "q": [0, 0, 0, 0, 0, 0, 0], "tau": [0, 0.2, 0, 0, 0, 0, 0]}]}"#,
    )
    .unwrap();
    let mut harness = session_harness(&path);
    harness.state_mut().apply(proprioscope::app::Command::SetSigma(1e-4));
    settle(&mut harness);
    let app = harness.state();
    assert_eq!(app.session_estimated(), 2);
    let failures = app.session_failures();
    assert_eq!(failures.keys().copied().collect::<Vec<_>>(), vec![1]);
    assert!(failures[&1].contains("beyond what can be computed"), "{failures:?}");
}

/// A recording with two arms' joint states leaves the choice to the user:
/// the app asks, opens the recording with the topics chosen, and asks no
/// more when the same file is opened again.
#[test]
fn an_ambiguous_recording_asks_for_its_topics_once() {
    use proprioscope::io::mcap_out::EstimateWriter;
    use proprioscope::io::recording::TopicChoice;
    let json = demo_session("two-arms.session.json", 0.5);
    let session = proprioscope::io::session::Session::read(&json).unwrap();
    let joints = session.joints.clone().unwrap();
    let path = json.with_file_name("two-arms.mcap");
    let mut out = EstimateWriter::create(&path, "lwr_base_link").unwrap();
    let other: Vec<_> = session
        .frames
        .iter()
        .map(|f| proprioscope::io::session::Frame {
            tau: vec![0.0; f.tau.len()],
            ..f.clone()
        })
        .collect();
    out.write_joint_states("/left/joint_states", &joints, &other, 0)
        .unwrap();
    out.write_joint_states("/right/joint_states", &joints, &session.frames, 0)
        .unwrap();
    out.finish().unwrap();

    // A recording names no robot: it opens on the robot the user chose.
    let mut harness = proprioscope::app::headless_harness(open_target(Some("lwr4plus")).unwrap(), [1200.0, 800.0]);
    harness.state_mut().open(path.to_str().unwrap());
    for _ in 0..500 {
        harness.step();
        if harness.state().topics.prompt.is_some() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    let prompt = harness
        .state()
        .topics
        .prompt
        .clone()
        .expect("the app asks for the topics");
    assert!(prompt.message.contains("several"), "{}", prompt.message);
    assert_eq!(prompt.position_topics, ["/left/joint_states", "/right/joint_states"]);
    assert!(harness.state().model.replay.is_none());
    harness.state_mut().topics.prompt.as_mut().unwrap().choice = TopicChoice {
        q_topic: Some("/right/joint_states".into()),
        tau_topic: Some("/right/joint_states".into()),
        tau_field: Some("effort".into()),
    };
    harness.run();
    harness.get_by_label("Open").click();
    settle(&mut harness);
    {
        let app = harness.state();
        assert!(app.topics.prompt.is_none());
        let replay = app.model.replay.as_ref().expect("the recording opened");
        assert_eq!(replay.session.frames.len(), session.frames.len());
        // The right arm's torques, not the left's zeros.
        assert_eq!(replay.session.frames[3].tau, session.frames[3].tau);
    }
    harness.state_mut().close_session();
    harness.state_mut().open(path.to_str().unwrap());
    settle(&mut harness);
    assert!(harness.state().topics.prompt.is_none());
    assert!(harness.state().model.replay.is_some(), "{:?}", harness.state().error);
}

/// Listening live takes the live surface (fewer samples, so that each
/// frame keeps up) where the surface was left at the default, and says
/// so; a surface the user chose stays.
#[test]
fn listening_live_takes_the_live_surface_unless_the_user_chose_one() {
    use proprioscope::app::Command;
    use proprioscope::core::config::estimator::{DEFAULT_SURFACE_POINTS, LIVE_SURFACE_POINTS};
    const { assert!(LIVE_SURFACE_POINTS < DEFAULT_SURFACE_POINTS) };
    let mut harness = app_harness();
    assert_eq!(harness.state().model.config.surface_points, DEFAULT_SURFACE_POINTS);
    harness.state_mut().start_live("127.0.0.1:0");
    assert_eq!(harness.state().model.config.surface_points, LIVE_SURFACE_POINTS);
    harness.state_mut().stop_live();
    let mut harness = app_harness();
    harness.state_mut().apply(Command::SetSurfacePoints(4000));
    harness.state_mut().start_live("127.0.0.1:0");
    assert_eq!(harness.state().model.config.surface_points, 4000);
}

/// A live session: frames sent over TCP fill the timeline and the view
/// follows the newest; after the user steps back it stays there while
/// frames keep coming, until *Follow newest*.
#[test]
fn a_live_session_fills_the_timeline_and_follows_the_newest_frame() {
    use proprioscope::app::Command;
    use std::io::Write as _;
    let json = demo_session("live.session.json", 1.0);
    let session = proprioscope::io::session::Session::read(&json).unwrap();
    let mut harness = app_harness();
    harness.state_mut().start_live("127.0.0.1:0");
    let address = harness.state().live_address().unwrap().to_owned();
    let mut sender = std::net::TcpStream::connect(&address).unwrap();
    let header = serde_json::json!({"format": "contact-session", "version": 1, "joints": session.joints});
    let send = |sender: &mut std::net::TcpStream, frames: &[proprioscope::io::session::Frame]| {
        for f in frames {
            writeln!(sender, "{}", f.to_json()).unwrap();
        }
        sender.flush().unwrap();
    };
    writeln!(sender, "{header}").unwrap();
    send(&mut sender, &session.frames[..5]);
    let wait_for = |harness: &mut Harness<'_, ProprioscopeApp>, frames: usize| {
        for _ in 0..1000 {
            harness.step();
            if harness
                .state()
                .model
                .replay
                .as_ref()
                .is_some_and(|r| r.session.frames.len() == frames)
            {
                return;
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        panic!("{frames} frames did not arrive");
    };
    wait_for(&mut harness, 5);
    assert_eq!(harness.state().model.replay.as_ref().unwrap().frame, 4);
    assert_eq!(harness.state().model.q, session.frames[4].q);
    send(&mut sender, &session.frames[5..8]);
    wait_for(&mut harness, 8);
    assert_eq!(harness.state().model.replay.as_ref().unwrap().frame, 7);
    // Back to frame 2: it stays while frames arrive.
    harness.state_mut().apply(Command::SetFrame(2));
    send(&mut sender, &session.frames[8..12]);
    wait_for(&mut harness, 12);
    assert_eq!(harness.state().model.replay.as_ref().unwrap().frame, 2);
    // Settled before each click: an estimate arriving between the
    // button's place being read and the click moves the rows, and the
    // click misses (seen once on the 2-core VM under the whole suite).
    settle(&mut harness);
    harness.get_by_label("Follow newest").click();
    harness.run_steps(2);
    assert_eq!(harness.state().model.replay.as_ref().unwrap().frame, 11);
    // Stopped, the frames stay as a session and are estimated as a whole.
    settle(&mut harness);
    harness.get_by_label("Stop live").click();
    settle(&mut harness);
    let app = harness.state();
    assert!(app.live_address().is_none());
    assert_eq!(app.model.replay.as_ref().unwrap().session.frames.len(), 12);
}

/// The same estimate frame by frame (place, force, contact probability,
/// verdict, credible radius), the times aside: bit for bit, hence exact
/// comparisons.
#[allow(clippy::float_cmp)]
fn assert_same_estimates(a: &[proprioscope::batch::FrameEstimate], b: &[proprioscope::batch::FrameEstimate]) {
    assert_eq!(a.len(), b.len());
    for (i, (a, b)) in a.iter().zip(b).enumerate() {
        assert_eq!(a.point_world, b.point_world, "frame {i}");
        assert_eq!(a.force_world, b.force_world, "frame {i}");
        assert_eq!(a.contact_probability, b.contact_probability, "frame {i}");
        assert_eq!(a.verdict, b.verdict, "frame {i}");
        assert_eq!(a.credible90_radius_m, b.credible90_radius_m, "frame {i}");
    }
}

/// Live, every frame is filtered as it arrives, with the frames before it
/// (as `estimate --live`): the timeline shows where the frames so far
/// place the contact, and each frame's estimate is
/// the one the whole session gets, filtered, once the stream stops.
#[test]
fn a_live_session_is_filtered_as_its_frames_arrive() {
    use std::io::Write as _;
    let json = demo_session("live-filtered.session.json", 2.0);
    let session = proprioscope::io::session::Session::read(&json).unwrap();
    let frames = session.frames.len();
    let mut harness = app_harness();
    harness.state_mut().start_live("127.0.0.1:0");
    let address = harness.state().live_address().unwrap().to_owned();
    let mut sender = std::net::TcpStream::connect(&address).unwrap();
    let header = serde_json::json!({"format": "contact-session", "version": 1, "joints": session.joints});
    writeln!(sender, "{header}").unwrap();
    for (i, f) in session.frames.iter().enumerate() {
        writeln!(sender, "{}", f.to_json()).unwrap();
        if i % 10 == 9 {
            // In pieces, so that frames arrive while others are filtered.
            sender.flush().unwrap();
            for _ in 0..3 {
                harness.step();
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
        }
    }
    sender.flush().unwrap();
    let wait_filtered = |harness: &mut Harness<'_, ProprioscopeApp>| {
        for _ in 0..6000 {
            harness.step();
            let app = harness.state();
            if app
                .model
                .replay
                .as_ref()
                .is_some_and(|r| r.session.frames.len() == frames)
                && app.session.estimates.len() == frames
                && app.session.estimates.iter().all(Option::is_some)
            {
                return app.session.estimates.iter().flatten().copied().collect::<Vec<_>>();
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        panic!("the live frames were not all filtered: {:?}", harness.state().error);
    };
    let filtered = wait_filtered(&mut harness);
    assert_eq!(
        harness.state().model.replay.as_ref().unwrap().over_time,
        proprioscope::core::over_time::sequence::Temporal::Filter
    );
    harness.run_steps(2);
    // The row above the timeline reads the filtered contact of the frame shown.
    assert!(harness.query_by_label_contains("over time: ").is_some());
    let contacts = filtered.iter().filter(|e| e.contact_probability > Some(0.5)).count();
    assert!(contacts >= frames / 2, "{contacts} of {frames} frames with a contact");
    // Each frame alone: nothing filtered stays; filtered again: the same.
    harness.get_by_label("over time").click();
    harness.run_steps(2);
    harness.get_by_label("each frame alone").click();
    harness.run_steps(3);
    assert!(harness.state().session.estimates.is_empty());
    assert!(harness.query_by_label_contains("over time: ").is_none());
    harness.get_by_label("over time").click();
    harness.run_steps(2);
    harness.get_by_label("filtered (frames before)").click();
    assert_same_estimates(&wait_filtered(&mut harness), &filtered);
    harness.get_by_label("Stop live").click();
    settle(&mut harness);
    let whole: Vec<_> = harness.state().session.estimates.iter().flatten().copied().collect();
    assert_eq!(whole.len(), frames);
    assert_same_estimates(&filtered, &whole);
}

/// A long recording opened as a short one: how long the app takes to show
/// the file, the first frame's estimate, and each of ten frames scrubbed
/// to while the whole session is still being smoothed behind. A
/// measurement (printed), not a check of speed (it leaves before the
/// session is settled): run with the file to open,
/// e.g. `proprioscope synth /tmp/r600.json --seconds 600 --rate 1000 --seed 1`,
/// then `PROPRIOSCOPE_LONG_SESSION=/tmp/r600.json cargo test --release
/// --test app_sessions measure_ -- --ignored --nocapture`.
#[test]
#[ignore = "a measurement: needs PROPRIOSCOPE_LONG_SESSION"]
fn measure_a_long_recording_opened_and_scrubbed() {
    let Some(path) = std::env::var_os("PROPRIOSCOPE_LONG_SESSION") else {
        println!("PROPRIOSCOPE_LONG_SESSION not set: nothing measured");
        return;
    };
    let path = std::path::PathBuf::from(path);
    let mut harness = app_harness();
    settle(&mut harness);
    if proprioscope::io::open::names_no_robot(&path) {
        // A recording opens on the robot chosen: the LWR's (as the synthetic one).
        app_common::open_and_wait(&mut harness, "lwr4plus");
        settle(&mut harness);
    }
    let t0 = std::time::Instant::now();
    harness.state_mut().open(path.to_str().unwrap());
    let wait = |harness: &mut Harness<'_, ProprioscopeApp>, done: &dyn Fn(&ProprioscopeApp) -> bool| {
        let t = std::time::Instant::now();
        while !done(harness.state()) {
            harness.step();
            std::thread::sleep(std::time::Duration::from_millis(1));
            assert!(t.elapsed().as_secs() < 300, "gave up after 300 s");
        }
        t.elapsed().as_secs_f64()
    };
    wait(&mut harness, &|app| app.model.replay.is_some() || app.error.is_some());
    assert!(harness.state().error.is_none(), "{:?}", harness.state().error);
    let shown_after = t0.elapsed().as_secs_f64();
    let preview = harness.state().is_session_preview();
    wait(&mut harness, &|app| app.is_frame_estimated());
    let estimated_after = t0.elapsed().as_secs_f64();
    wait(&mut harness, &|app| !app.is_session_loading() || app.error.is_some());
    assert!(harness.state().error.is_none(), "{:?}", harness.state().error);
    let whole_after = t0.elapsed().as_secs_f64();
    let frames = harness.state().model.replay.as_ref().unwrap().session.frames.len();
    let mut scrubs = Vec::new();
    for k in 1..=10 {
        let frame = frames * k / 11;
        harness.state_mut().apply(proprioscope::app::Command::SetFrame(frame));
        let t = std::time::Instant::now();
        harness.step();
        let step = t.elapsed().as_secs_f64();
        wait(&mut harness, &|app| app.is_frame_estimated());
        scrubs.push((
            step * 1e3,
            t.elapsed().as_secs_f64() * 1e3,
            harness.state().session_estimated(),
        ));
    }
    // The session goes on being smoothed behind; its rate so far.
    let (elapsed, smoothed) = (t0.elapsed().as_secs_f64(), harness.state().session_estimated());
    println!(
        "{frames} frames: the file shown after {shown_after:.2} s (its first frames alone: {preview}), \
         its first frame estimated after {estimated_after:.2} s, the whole file read after {whole_after:.2} s; \
         {smoothed} frames smoothed after {elapsed:.1} s"
    );
    for (step, shown, estimated) in scrubs {
        println!(
            "scrub: the app's step {step:.1} ms, the frame's estimate shown after {shown:.0} ms ({estimated} frames smoothed by then)"
        );
    }
}

/// A long session is shown from its first frames while the rest is read:
/// the frame on screen is estimated alone, the session is not estimated
/// as a whole until it is all there, and the frame chosen meanwhile stays.
#[test]
fn a_long_session_is_shown_from_its_first_frames_while_read() {
    // 12 MB: read in seconds by a debug build, its first MiB in milliseconds.
    let path = synth_session(
        "long.session.json",
        &["--seconds", "30", "--rate", "1000", "--seed", "5"],
    );
    let mut harness = app_harness();
    settle(&mut harness);
    harness.state_mut().open(path.to_str().unwrap());
    let mut previewed = None;
    for _ in 0..20_000 {
        harness.step();
        let app = harness.state();
        if app.is_session_preview() && previewed.is_none() {
            let frames = app.model.replay.as_ref().unwrap().session.frames.len();
            assert!((1000..30_000).contains(&frames), "{frames}");
            assert_eq!(app.session_estimated(), 0);
            previewed = Some(frames);
            harness
                .state_mut()
                .apply(proprioscope::app::Command::SetFrame(frames / 2));
        }
        if !harness.state().is_session_loading() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    let Some(preview_frames) = previewed else {
        panic!("no preview shown; error: {:?}", harness.state().error);
    };
    let app = harness.state();
    assert!(app.error.is_none(), "{:?}", app.error);
    assert!(!app.is_session_preview());
    let replay = app.model.replay.as_ref().unwrap();
    assert_eq!(replay.session.frames.len(), 30_000);
    assert_eq!(replay.frame, preview_frames / 2);
}

/// A sliding press replayed smoothed: the view draws the over-time
/// contact's track over the last second, on its link, ending at the frame's
/// over-time estimate.
#[test]
fn a_sliding_contact_leaves_its_track_over_the_last_second() {
    let path = synth_session(
        "slide.session.json",
        &[
            "--seconds",
            "3",
            "--rate",
            "50",
            "--slide",
            "0.1",
            "--kinetic-friction",
            "0.3,0.6",
            "--links",
            "lwr_5_link",
            "--seed",
            "2",
        ],
    );
    let mut harness = session_harness(&path);
    // A frame whose contact was on its link for the 10 frames before it
    // (the track ends where the estimate leaves the link).
    let estimates = harness.state().session.estimates.clone();
    let frame = (10..estimates.len())
        .find(|&k| {
            let link = estimates[k].map(|e| e.link);
            estimates[k - 10..=k].iter().all(|e| {
                e.is_some_and(|e| {
                    e.verdict != proprioscope::core::estimate::summary::Verdict::NoContact && Some(e.link) == link
                })
            })
        })
        .unwrap();
    harness.state_mut().apply(proprioscope::app::Command::SetFrame(frame));
    harness.run_steps(2);
    settle(&mut harness);
    let app = harness.state();
    let track = app.over_time_track();
    let now = app.session.estimates[frame].unwrap();
    assert!(track.len() > 10 && track.len() <= 51, "{} points", track.len());
    assert!(track.last().unwrap().distance(now.point_world) < 1e-9);
    assert!(track.iter().all(|p| p.distance(now.point_world) < 0.2));
    // Without an over-time estimate there is no track.
    harness.state_mut().apply(proprioscope::app::Command::SetOverTime(
        proprioscope::core::over_time::sequence::Temporal::None,
    ));
    harness.run_steps(2);
    assert!(harness.state().over_time_track().is_empty());
}
