//! Two pushes in the app: Shift+click adds a second push whose torques
//! add to the first's, the estimator looks for two contacts, and the two
//! shipped two-contact scenes say what their torques can and cannot tell.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use crate::common;
use crate::common::app as app_common;

use app_common::{app_harness, open_and_wait, settle};
use eframe::egui;
use egui_kittest::kittest::Queryable as _;
use proprioscope::app::heat::HeatLayer;
use proprioscope::core::robot::kinematics::RobotPose;
use proprioscope::core::robot::torque::joint_torques;

fn scene(name: &str) -> String {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(format!("{name}.json"))
        .display()
        .to_string()
}

/// A click with Shift held, at `pos`.
fn shift_click(harness: &egui_kittest::Harness<'_, proprioscope::app::ProprioscopeApp>, pos: egui::Pos2) {
    let shift = egui::Modifiers::SHIFT;
    harness.event(egui::Event::ModifiersChanged(shift));
    harness.event(egui::Event::PointerMoved(pos));
    for pressed in [true, false] {
        harness.event(egui::Event::PointerButton {
            pos,
            button: egui::PointerButton::Primary,
            pressed,
            modifiers: shift,
        });
    }
    harness.event(egui::Event::ModifiersChanged(egui::Modifiers::NONE));
    harness.event(egui::Event::PointerGone);
}

#[test]
fn shift_click_adds_a_second_push_and_the_torques_are_the_sum() {
    let mut harness = app_harness();
    settle(&mut harness);
    let first = harness.state().model.push.unwrap();
    let pixel = harness.state().pixel_of_link("lwr_5_link").unwrap();
    shift_click(&harness, pixel);
    harness.run_steps(3);
    settle(&mut harness);
    let app = harness.state();
    assert_eq!(app.model.push, Some(first), "the first push stays");
    let second = app.model.second_push.unwrap();
    assert_eq!(app.model.robot.links[second.link].name, "lwr_5_link");
    assert_eq!(app.model.config.contacts_at_once, 2);
    assert_eq!(app.model.view.layer, HeatLayer::Contacts);
    let pose = RobotPose::new(&app.model.robot, &app.model.joint_positions());
    let one = |p: proprioscope::app::Push| {
        let w = pose.world_from_link[p.link];
        joint_torques(
            &app.model.robot,
            &pose,
            p.link,
            w.transform_point3(p.point_in_link),
            w.transform_vector3(p.inward_normal_in_link) * p.force_newtons,
        )
    };
    let (a, b) = (one(first), one(second));
    for ((sum, x), y) in app.model.applied_torques(&pose).iter().zip(&a).zip(&b) {
        assert!((sum - x - y).abs() < 1e-12);
    }
    // The estimate carries the two-contact account.
    let outcome = app.outcome.clone().unwrap();
    assert!(
        matches!(outcome.pair, Some(Ok(_))),
        "{:?}",
        outcome.pair.map(Result::err)
    );
    harness.get_by_label("Clear second push").click();
    harness.run_steps(2);
    assert!(harness.state().model.second_push.is_none());
    assert_eq!(harness.state().model.push, Some(first));
}

#[test]
fn the_two_contact_scene_finds_both_pushes() {
    let mut harness = app_harness();
    open_and_wait(&mut harness, &scene("lwr-two-contacts"));
    settle(&mut harness);
    let app = harness.state();
    let pose = app.model.pose();
    let pushes = [
        app.model.push_world(&pose).unwrap().1,
        app.model.second_push_world(&pose).unwrap().1,
    ];
    let pair = app.outcome.as_ref().unwrap().pair.clone().unwrap().unwrap();
    assert!(pair.has_two(), "P(two) {}", pair.probability_two);
    for truth in pushes {
        let nearest = pair
            .contacts
            .iter()
            .map(|c| c.point_world.distance(truth))
            .fold(f64::INFINITY, f64::min);
        assert!(nearest < 0.03, "{:.0} mm", nearest * 1e3);
    }
    // Two arrows for the estimate, two for the pushes; the panel says two.
    harness.get_by_label_contains("P(two) = 1.00");
    harness.get_by_label_contains("the evidence calls two");
}

/// Two parallel pushes on one link have the torques of one push at their
/// centre of force: one contact is reported there, not two.
#[test]
fn the_two_as_one_scene_reports_one_contact_at_the_centre_of_force() {
    let mut harness = app_harness();
    open_and_wait(&mut harness, &scene("lwr-two-as-one"));
    settle(&mut harness);
    let app = harness.state();
    let pose = app.model.pose();
    let (_, a, fa) = app.model.push_world(&pose).unwrap();
    let (_, b, fb) = app.model.second_push_world(&pose).unwrap();
    let centre = (a * fa.length() + b * fb.length()) / (fa.length() + fb.length());
    let outcome = app.outcome.as_ref().unwrap();
    let single = &outcome.update.as_ref().unwrap().summary.map;
    assert!(
        single.point_world.distance(centre) < 0.01,
        "{:.0} mm from the centre of force",
        single.point_world.distance(centre) * 1e3
    );
    assert!(
        (single.force_newtons - (fa.length() + fb.length())).abs() < 1.0,
        "{}",
        single.force_newtons
    );
    let pair = outcome.pair.clone().unwrap().unwrap();
    assert!(!pair.has_two(), "P(two) {}", pair.probability_two);
    harness.get_by_label_contains("one contact");
}

/// A session replayed with two contacts looked for: once its frames are
/// smoothed, the pass over the second contacts marks the frames called
/// two, as `estimate --contacts 2` does (the same pairs, to the
/// micrometre), the timeline plots the probability of two and says two
/// at a frame where both press, and the view draws both arrows there.
#[test]
fn a_session_shows_the_second_contacts_over_time() {
    use proprioscope::app::Command;
    use proprioscope::core::over_time::sequence::Temporal;
    let session = common::temp_file("app-two-pushes.json", &common::two_push_session());
    let out = session.with_extension("jsonl");
    let (ok, _, err) = common::run_out(&[
        "estimate",
        session.to_str().unwrap(),
        "--contacts",
        "2",
        "--temporal",
        "smooth",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let cli = common::json_lines(&out);
    let mut harness = app_harness();
    open_and_wait(&mut harness, session.to_str().unwrap());
    settle(&mut harness);
    assert_eq!(
        harness.state().model.replay.as_ref().unwrap().over_time,
        Temporal::Smooth
    );
    let mut config = harness.state().model.config.clone();
    config.contacts_at_once = 2;
    harness.state_mut().apply(Command::SetConfig(config));
    settle(&mut harness);
    let app = harness.state();
    let estimates = &app.session.estimates;
    assert_eq!(estimates.len(), cli.len());
    let mut called = 0;
    for (i, (e, c)) in estimates.iter().zip(&cli).enumerate() {
        let second = e.unwrap().second.filter(|s| s.called);
        let theirs = c["contacts"].as_array().unwrap();
        assert_eq!(second.is_some(), theirs.len() == 2, "frame {i}");
        let Some(second) = second else { continue };
        called += 1;
        for ((_, point, _), c) in second.contacts.iter().zip(theirs) {
            let p = c["point"].as_array().unwrap();
            for (x, y) in point.to_array().iter().zip(p) {
                assert!((x - y.as_f64().unwrap()).abs() < 1e-6, "frame {i}");
            }
        }
    }
    // Measured: 29 frames, as the command line (docs/validation.md).
    assert!(called >= 25, "{called} frames called two");
    // Frame 80 (0.8 s): both press.
    harness.state_mut().apply(Command::SetFrame(80));
    settle(&mut harness);
    harness.get_by_label_contains("over time: two contacts");
    let app = harness.state();
    let over_time = app
        .markers(&app.model.pose())
        .into_iter()
        .filter(|m| m.role == proprioscope::app::overlay::MarkerRole::OverTime)
        .count();
    assert_eq!(over_time, 2);
}
