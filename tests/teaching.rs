//! The app as a view that reads and a tool that teaches: pushes dragged
//! on the arm, the legend's numbers, the observability map, layouts that
//! keep the 3-D view large, the camera fitted to each robot, files that
//! name no robot (`egui_kittest` on Mesa's software Vulkan).

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use std::path::Path;

use eframe::egui;
use egui_kittest::Harness;
use egui_kittest::kittest::{NodeT as _, Queryable as _};
use proprioscope::app::{ProprioscopeApp, open_target, open_target_with};
use proprioscope::core::robot::kinematics::RobotPose;

fn harness_at(target: Option<&str>, size: [f32; 2]) -> Harness<'static, ProprioscopeApp> {
    let mut harness = proprioscope::app::headless_harness(open_target(target).unwrap(), size);
    proprioscope::app::settle(&mut harness).unwrap();
    harness
}

fn settle(harness: &mut Harness<'_, ProprioscopeApp>) {
    proprioscope::app::settle(harness).unwrap();
}

/// Every mesh vertex of the posed robot projects inside the 3-D view.
fn assert_robot_in_view(app: &ProprioscopeApp, what: &str) {
    let rect = app.view_rect().unwrap();
    let size = glam::Vec2::new(rect.width(), rect.height());
    let pose = RobotPose::new(&app.model.robot, &app.model.joint_positions());
    let (lo, hi) = proprioscope::app::robot_bounds(&app.model.robot, &pose).unwrap();
    let (mut lo_px, mut hi_px) = (glam::Vec2::MAX, glam::Vec2::MIN);
    for (link, l) in app.model.robot.links.iter().enumerate() {
        for p in &l.mesh.positions {
            let w = pose.world_from_link[link].transform_point3(*p).as_vec3();
            let px = app.camera().project(w, size).unwrap();
            assert!(
                px.x >= 0.0 && px.y >= 0.0 && px.x <= size.x && px.y <= size.y,
                "{what}: a vertex at {w} is drawn at {px}, outside the {size} view"
            );
            lo_px = lo_px.min(px);
            hi_px = hi_px.max(px);
        }
    }
    // Framed, not lost in the distance: the robot spans a good part of the view.
    // (along the view's longer side for the robot: a long arm lying flat
    // fills the width, not the height)
    let span = ((hi_px - lo_px) / size).max_element();
    let size_m = (hi - lo).length();
    assert!(
        span > 0.3,
        "{what}: the {size_m:.2} m robot spans {span:.2} of the view"
    );
}

#[test]
fn the_camera_frames_each_built_in_robot() {
    let mut harness = harness_at(None, [1280.0, 720.0]);
    harness.run_steps(2);
    assert_robot_in_view(harness.state(), "default scene");
    for name in proprioscope::core::robot::builtin::BUILTIN_NAMES {
        harness.state_mut().open(name);
        for _ in 0..500 {
            harness.step();
            if !harness.state().is_opening() {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        harness.run_steps(3);
        assert!(harness.state().error.is_none(), "{:?}", harness.state().error);
        assert_robot_in_view(harness.state(), name);
    }
}

#[test]
#[ignore = "needs ../shared"]
fn the_camera_frames_each_shared_robot() {
    for urdf in [
        "../shared/robots/lwr4plus/lwr4plus.urdf",
        "../shared/robots/iiwa14/model.urdf",
        "../shared/robots/panda/urdf/panda.urdf",
    ] {
        if !Path::new(urdf).exists() {
            continue;
        }
        let mut harness = harness_at(Some(urdf), [1280.0, 720.0]);
        harness.run_steps(2);
        assert_robot_in_view(harness.state(), urdf);
    }
}

#[test]
fn a_drag_on_the_arm_sets_the_push_direction_and_magnitude() {
    let mut harness = harness_at(None, [1200.0, 800.0]);
    harness.get_by_label("Clear push").click();
    harness.run_steps(2);
    let pixel = harness.state().pixel_of_link("lwr_5_link").unwrap();
    harness.hover_at(pixel);
    harness.drag_at(pixel);
    // 120 points to the right, in steps, as a hand would.
    for step in 1..=6 {
        harness.hover_at(pixel + egui::vec2(20.0 * step as f32, 0.0));
    }
    harness.drop_at(pixel + egui::vec2(120.0, 0.0));
    harness.run_steps(3);
    let app = harness.state();
    let push = app.model.push.expect("the drag set a push");
    assert_eq!(app.model.robot.links[push.link].name, "lwr_5_link");
    // 0.125 N per point.
    assert!((push.force_newtons - 15.0).abs() < 1.0, "{} N", push.force_newtons);
    let pose = RobotPose::new(&app.model.robot, &app.model.joint_positions());
    let (_, _, force_world) = app.model.push_world(&pose).unwrap();
    // It comes from the right of the screen: it points to the left.
    let right = app.camera().forward().cross(glam::Vec3::Z).normalize().as_dvec3();
    let along = force_world.normalize().dot(right);
    assert!(along < -0.3, "the push points {along:.2} along the screen's right");
    // The camera did not turn while the push was dragged.
    let before = harness_at(None, [1200.0, 800.0]);
    assert!((before.state().camera().yaw - harness.state().camera().yaw).abs() < 1e-6);
}

#[test]
fn a_plain_click_keeps_the_inward_push() {
    let mut harness = harness_at(None, [1200.0, 800.0]);
    let pixel = harness.state().pixel_of_link("lwr_4_link").unwrap();
    harness.hover_at(pixel);
    harness.drag_at(pixel);
    harness.drop_at(pixel);
    harness.run_steps(3);
    let app = harness.state();
    let push = app.model.push.unwrap();
    assert_eq!(app.model.robot.links[push.link].name, "lwr_4_link");
    // The direction is the inward normal of the triangle under the pointer,
    // found here by a ray cast of our own.
    let rect = app.view_rect().unwrap();
    let local = pixel - rect.min;
    let (origin, dir) = app.camera().ray(
        glam::Vec2::new(local.x, local.y),
        glam::Vec2::new(rect.width(), rect.height()),
    );
    let pose = app.model.pose();
    let hit = proprioscope::core::surface::picking::Picker::new(&app.model.robot)
        .pick(&pose, origin.as_dvec3(), dir.as_dvec3(), &[])
        .unwrap();
    let normal_in_link = pose.world_from_link[hit.link]
        .inverse()
        .transform_vector3(hit.inward_normal_world);
    assert!((push.inward_normal_in_link - normal_in_link).length() < 1e-9);
    assert!((push.point_in_link - hit.point_in_link).length() < 1e-9);
}

#[test]
fn a_drag_off_the_arm_turns_the_view() {
    let mut harness = harness_at(None, [1200.0, 800.0]);
    let rect = harness.state().view_rect().unwrap();
    let push_before = harness.state().model.push;
    let yaw = harness.state().camera().yaw;
    // A corner of the view shows the floor, not the arm.
    let corner = rect.left_top() + egui::vec2(30.0, 30.0);
    harness.hover_at(corner);
    harness.drag_at(corner);
    harness.hover_at(corner + egui::vec2(40.0, 0.0));
    harness.drop_at(corner + egui::vec2(60.0, 0.0));
    harness.run_steps(2);
    assert!((harness.state().camera().yaw - yaw).abs() > 0.1);
    assert_eq!(harness.state().model.push, push_before);
}

#[test]
fn the_legend_numbers_follow_the_scale_and_the_layer() {
    let mut harness = harness_at(None, [1280.0, 720.0]);
    harness.run_steps(2);
    let log = harness.state().legend().unwrap().clone();
    assert!(
        log.title.contains("per cm²") && log.title.contains("log"),
        "{}",
        log.title
    );
    let top: f64 = log.ticks[0].1.parse().unwrap();
    assert!((log.ticks[0].0 - 1.0).abs() < 1e-12 && top > 0.0);
    let bottom = log.ticks.last().unwrap();
    assert!(bottom.0.abs() < 1e-12 && bottom.1.contains("below"), "{bottom:?}");
    // The top is the densest sample's probability per cm².
    let app = harness.state();
    let outcome = app.current_outcome().unwrap();
    let update = outcome.update.as_ref().unwrap();
    let surface = &outcome.estimator.surface;
    let densest = (0..surface.len())
        .map(|k| update.posterior.display[k] / (surface.area_m2[k] * 1e4))
        .fold(0.0, f64::max);
    assert!((top - densest).abs() <= 0.01 * densest, "{top} vs {densest}");

    harness.get_by_label("linear").click();
    harness.run_steps(3);
    let linear = harness.state().legend().unwrap().clone();
    assert!(linear.title.contains("linear"));
    assert_eq!(linear.ticks.last().unwrap().1, "0");
    assert_eq!(linear.ticks[0].1, log.ticks[0].1);

    harness.get_by_label("observability").click();
    harness.run_steps(3);
    let obs = harness.state().legend().unwrap().clone();
    assert!(obs.title.contains("posterior width"), "{}", obs.title);
    let labels: Vec<&str> = obs.ticks.iter().map(|(_, l)| l.as_str()).collect();
    assert_eq!(labels, ["1 mm", "1 cm", "10 cm", "1 m"]);
    assert!(obs.ticks[0].0 > obs.ticks[3].0, "1 mm at the top");
}

#[test]
fn the_torque_plot_picks_a_joint_only_under_the_pointer() {
    let mut harness = harness_at(None, [1280.0, 720.0]);
    let rect = harness.state().view_rect().unwrap();
    for x in [0.2, 0.5, 0.8] {
        harness.hover_at(rect.left_top() + egui::vec2(rect.width() * x, rect.height() * 0.5));
        harness.run_steps(2);
        assert_eq!(harness.state().hovered_joint(), None, "pointer over the view at {x}");
    }
}

#[test]
fn with_a_session_open_the_view_keeps_half_the_window_at_1280_by_720() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("teaching");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("layout.session.json");
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_proprioscope"))
        .args(["record-demo", "--rate", "20", "--seconds", "1", "--out"])
        .arg(&path)
        .stdout(std::process::Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    let start = open_target(Some(path.to_str().unwrap())).unwrap();
    let (w, h) = (1280.0, 720.0);
    let mut harness = proprioscope::app::headless_harness(start, [w, h]);
    settle(&mut harness);
    harness.run_steps(3);
    assert!(harness.state().model.replay.is_some());
    let view = harness.state().view_rect().unwrap();
    assert!(
        view.width() >= 0.5 * w && view.height() >= 0.5 * h,
        "the view is {}×{} of {w}×{h}",
        view.width(),
        view.height()
    );
    // Nothing of the panels is drawn under it: the estimator's heading
    // and the torque plot sit to its right.
    let heading = harness.get_by_label("Estimator");
    assert!(heading.rect().left() >= view.right() - 1.0);
    assert_robot_in_view(harness.state(), "session");
    // The side panels fold away from the View menu.
    harness.get_by_label("View").click();
    harness.run_steps(2);
    harness.get_by_label("Estimator panel").click();
    harness.run_steps(3);
    let wider = harness.state().view_rect().unwrap();
    assert!(
        wider.width() > view.width() + 200.0,
        "{} → {}",
        view.width(),
        wider.width()
    );
}

/// In a window narrower than the layout is made for (1000×640), the
/// estimator panel's rows fit its width: every slider, its value and its
/// label lie right of the view and inside the window (they used to be
/// pushed under the view and past the window's edge).
#[test]
fn a_narrow_window_keeps_the_estimator_panel_readable() {
    let (w, h) = (1000.0, 640.0);
    let mut harness = proprioscope::app::headless_harness(open_target(None).unwrap(), [w, h]);
    settle(&mut harness);
    harness.run_steps(3);
    let view = harness.state().view_rect().unwrap();
    for label in [
        "Estimator",
        "σ [N·m]",
        "N (surface points)",
        "friction auto",
        "friction μ: 0.2 over time, 0 per frame",
        "hide below",
        "observability",
        "red-green",
    ] {
        for node in harness.get_all_by_label(label) {
            let r = node.rect();
            assert!(
                r.left() >= view.right() - 1.0 && r.right() <= w + 0.5,
                "{label}: {r:?}, the view ends at {}",
                view.right()
            );
        }
    }
    // With friction auto off, its μ slider takes the row.
    harness.get_by_label("friction auto").click();
    harness.run_steps(3);
    for node in harness.get_all_by_label("friction μ") {
        let r = node.rect();
        assert!(
            r.left() >= view.right() - 1.0 && r.right() <= w + 0.5,
            "friction μ: {r:?}, the view ends at {}",
            view.right()
        );
    }
}

#[test]
fn a_csv_session_needs_a_robot() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("teaching");
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("no-robot.csv");
    std::fs::write(
        &csv,
        "t,q1,q2,q3,q4,q5,q6,q7,tau1,tau2,tau3,tau4,tau5,tau6,tau7\n0,0,0,0,0,0,0,0,0,0,0,0,0,0,0\n",
    )
    .unwrap();
    let csv_str = csv.to_str().unwrap();
    // On the command line: refused, with the reason and the way out.
    let error = open_target(Some(csv_str)).unwrap_err().to_string();
    assert!(error.contains("names no robot") && error.contains("--robot"), "{error}");
    // With a robot named it opens.
    assert!(open_target_with(Some(csv_str), Some("lwr4plus"), &[]).is_ok());
    // In the app on the default robot: refused, the scene kept.
    let mut harness = harness_at(None, [1200.0, 800.0]);
    let push = harness.state().model.push;
    harness.state_mut().open(csv_str);
    harness.run_steps(5);
    let app = harness.state();
    let error = app.error.clone().unwrap_or_default();
    assert!(
        error.contains("names no robot") && error.contains("open its robot first"),
        "{error}"
    );
    assert!(app.model.replay.is_none());
    assert_eq!(app.model.push, push);
    // Once the user has chosen a robot, the session is shown on it.
    let mut harness = harness_at(Some("lwr4plus"), [1200.0, 800.0]);
    harness.state_mut().open(csv_str);
    for _ in 0..500 {
        harness.step();
        if harness.state().model.replay.is_some() || harness.state().error.is_some() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    assert!(harness.state().model.replay.is_some(), "{:?}", harness.state().error);
}

/// The static example has contacts on every link: its metrics by sensing
/// joints once made the side panel wider than the window, under the view.
#[test]
#[ignore = "needs ../shared"]
fn a_session_with_contacts_on_every_link_keeps_the_panels_beside_the_view() {
    let path = "../shared/sessions/lwr4plus_static_example.session.json";
    let mut harness = proprioscope::app::headless_harness(open_target(Some(path)).unwrap(), [1280.0, 720.0]);
    settle(&mut harness);
    for _ in 0..300 {
        harness.step();
        if harness.state().session.estimates.iter().all(Option::is_some) {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    harness.run_steps(3);
    let view = harness.state().view_rect().unwrap();
    assert!(view.width() >= 640.0 && view.height() >= 360.0, "{view:?}");
    let heading = harness.get_by_label("Estimator");
    assert!(
        heading.rect().left() >= view.right() - 1.0,
        "{:?} vs {view:?}",
        heading.rect()
    );
}

/// A number typed into a slider's field counts once, when Enter is
/// pressed: typing N = 20000 does not estimate at 2, 20, 200 and 2000.
#[test]
fn a_typed_number_counts_on_enter_not_at_every_keystroke() {
    let mut harness = harness_at(None, [1280.0, 720.0]);
    let before = harness.state().model.config.surface_points;
    let field = harness
        .get_all_by_label("N (surface points)")
        .find(|n| n.accesskit_node().role() == egui::accesskit::Role::SpinButton)
        .expect("the N field");
    // A click (press and release in place) turns the field into text.
    let at = field.rect().center();
    harness.hover_at(at);
    harness.drag_at(at);
    harness.drop_at(at);
    harness.run_steps(2);
    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
    harness.run_steps(1);
    for ch in ["2", "0", "0", "0", "0"] {
        harness.event(egui::Event::Text(ch.to_owned()));
        harness.run_steps(1);
        assert_eq!(harness.state().model.config.surface_points, before, "after typing {ch}");
    }
    harness.key_press(egui::Key::Enter);
    harness.run_steps(3);
    assert_eq!(harness.state().model.config.surface_points, 20_000);
}

/// Shift while dragging a joint's slider moves it ten times slower.
#[test]
fn shift_drags_a_joint_slider_ten_times_slower() {
    let drag = |shift: bool| -> f64 {
        let mut harness = harness_at(None, [1280.0, 720.0]);
        let slider = harness
            .get_all_by_label("lwr_joint_1")
            .find(|n| n.accesskit_node().role() == egui::accesskit::Role::Slider)
            .expect("joint 1's slider");
        let rect = slider.rect();
        let from = rect.center();
        harness.hover_at(from);
        let modifiers = if shift {
            egui::Modifiers::SHIFT
        } else {
            egui::Modifiers::NONE
        };
        harness.event(egui::Event::ModifiersChanged(modifiers));
        harness.event(egui::Event::PointerButton {
            pos: from,
            button: egui::PointerButton::Primary,
            pressed: true,
            modifiers,
        });
        harness.run_steps(1);
        // A press jumps the slider to the pointer: measure from there.
        let before = harness.state().model.q[0];
        for step in 1..=4 {
            harness.event(egui::Event::PointerMoved(from + egui::vec2(5.0 * step as f32, 0.0)));
            harness.run_steps(1);
        }
        harness.event(egui::Event::PointerButton {
            pos: from + egui::vec2(20.0, 0.0),
            button: egui::PointerButton::Primary,
            pressed: false,
            modifiers,
        });
        harness.event(egui::Event::ModifiersChanged(egui::Modifiers::NONE));
        harness.run_steps(2);
        (harness.state().model.q[0] - before).to_degrees()
    };
    let coarse = drag(false);
    let fine = drag(true);
    assert!(coarse > 1.0, "a 20-point drag moved {coarse}°");
    assert!(fine > 0.0 && fine < 0.3 * coarse, "fine {fine}° against {coarse}°");
}

/// A focused joint slider steps by a thousandth of its range per arrow key.
#[test]
fn the_arrow_keys_step_a_joint_slider_finely() {
    let mut harness = harness_at(None, [1280.0, 720.0]);
    let before = harness.state().model.q[0];
    harness
        .get_all_by_label("lwr_joint_1")
        .find(|n| n.accesskit_node().role() == egui::accesskit::Role::Slider)
        .expect("joint 1's slider")
        .focus();
    harness.run_steps(1);
    harness.key_press(egui::Key::ArrowRight);
    harness.run_steps(1);
    harness.key_press(egui::Key::ArrowRight);
    harness.run_steps(2);
    let app = harness.state();
    let joint = &app.model.robot.joints[app.model.robot.sensed()[0]];
    let limits = joint.limits.unwrap();
    let step = (limits.upper - limits.lower) / 1000.0;
    let moved = app.model.q[0] - before;
    assert!(
        (moved - 2.0 * step).abs() < 1e-9,
        "moved {moved} rad, two steps of {step}"
    );
}
