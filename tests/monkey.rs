//! The monkey test: thousands of seeded random actions on the app (menu
//! items, shipped scenes, robot switches, clicks, drags and wheel turns in
//! the 3-D view, sliders and drag values, checkboxes, keys, sessions opened, played,
//! scrubbed and closed, recordings started and stopped, a robot recording
//! that asks for its topics, a live stream listened to and fed, numbers
//! and text typed into the panels' fields: 0, 1e-300, 1e308, negative,
//! `NaN`, words), with the model's invariants checked after each (every
//! setting within its valid range, every estimate finite).
//! `MONKEY_ACTIONS` sets how many (2000 by default), `MONKEY_SEED` the seed.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use eframe::egui;
use egui::accesskit::Role;
use egui_kittest::Harness;
use egui_kittest::kittest::{NodeT as _, Queryable as _};
use proprioscope::app::{ProprioscopeApp, open_target};
use proprioscope::core::numerics::rng::Rng;

/// A small session of the built-in LWR: a few frames, one of them bad.
fn session_file(dir: &Path) -> PathBuf {
    let path = dir.join("monkey.session.json");
    let frame = |t: f64, tau: &str| format!(r#"{{"t": {t}, "q": [0.1, 0.5, 0, -1, 0, 0.4, 0], "tau": [{tau}]}}"#);
    let frames = [
        frame(0.0, "0.5, -1.2, 0.1, 0.3, 0, 0, 0"),
        frame(0.1, "0.02, 0.01, -0.03, 0, 0.01, 0, 0"),
        frame(0.2, "0.4, -1.0, 0.2, 0.25, 0.1, 0, 0"),
        frame(0.3, "0, 0, 0, 0, 0, 0, null"),
        frame(0.4, "1e70, 0, 0, 0, 0, 0, 0"),
        frame(0.5, "1e5, 0, 0, 0, 0, 0, 0"),
    ];
    std::fs::write(
        &path,
        format!(
            r#"{{"format": "contact-session", "version": 1, "robot": "lwr4plus", "frames": [{}]}}"#,
            frames.join(",")
        ),
    )
    .unwrap();
    path
}

/// An MCAP recording of the session's frames on two arms' topics: opening
/// it asks which topics make the frames.
fn ambiguous_recording(dir: &Path, session: &Path) -> PathBuf {
    use proprioscope::io::mcap_out::EstimateWriter;
    let (session, _) = proprioscope::io::session::Session::read_skipping_bad_frames(session).unwrap();
    let joints: Vec<String> = (1..=7).map(|i| format!("lwr_joint_{i}")).collect();
    let path = dir.join("monkey-two-arms.mcap");
    let mut out = EstimateWriter::create(&path, "lwr_base_link").unwrap();
    out.write_joint_states("/left/joint_states", &joints, &session.frames, 0)
        .unwrap();
    out.write_joint_states("/right/joint_states", &joints, &session.frames, 0)
        .unwrap();
    out.finish().unwrap();
    path
}

/// Labels of the widgets of a role, in tree order.
fn labels(harness: &Harness<'_, ProprioscopeApp>, role: Role) -> Vec<String> {
    harness
        .query_all_by_role(role)
        .map(|n| n.accesskit_node().label().unwrap_or_default())
        .collect()
}

/// Clicks the `index`-th widget of `role`.
fn click_nth(harness: &Harness<'_, ProprioscopeApp>, role: Role, index: usize) {
    if let Some(node) = harness.query_all_by_role(role).nth(index) {
        node.click();
    }
}

/// What the monkey keeps between actions.
struct Monkey {
    scenes: Vec<PathBuf>,
    session: PathBuf,
    dir: PathBuf,
    recording: bool,
    /// A recording that leaves its topics to the user.
    ambiguous: PathBuf,
    /// The sender of a live stream the app listens to, the frames sent,
    /// and the address (the app may listen elsewhere since).
    live: Option<(std::net::TcpStream, usize, String)>,
}

/// One random action; what it was, for the failure message.
#[allow(clippy::too_many_lines)] // One arm per kind of action: reads as one table.
fn act(harness: &mut Harness<'_, ProprioscopeApp>, rng: &mut Rng, m: &mut Monkey) -> String {
    let action = rng.below(21);
    let view = harness.state().view_rect();
    let random_pos = |rng: &mut Rng| {
        view.map_or(egui::pos2(600.0, 300.0), |r| {
            egui::pos2(
                rng.uniform_in(f64::from(r.min.x), f64::from(r.max.x)) as f32,
                rng.uniform_in(f64::from(r.min.y), f64::from(r.max.y)) as f32,
            )
        })
    };
    match action {
        0 | 1 => {
            // Any button except those that open a file dialog.
            let buttons = labels(harness, Role::Button);
            let usable: Vec<usize> = (0..buttons.len()).filter(|&i| !buttons[i].ends_with('…')).collect();
            if usable.is_empty() {
                "no button".to_owned()
            } else {
                let i = usable[rng.below(usable.len())];
                click_nth(harness, Role::Button, i);
                format!("button '{}'", buttons[i])
            }
        }
        2 => {
            let boxes = labels(harness, Role::CheckBox);
            if boxes.is_empty() {
                "no checkbox".to_owned()
            } else {
                let i = rng.below(boxes.len());
                click_nth(harness, Role::CheckBox, i);
                format!("checkbox '{}'", boxes[i])
            }
        }
        3 | 4 => {
            // Sliders and drag values (a drag value is a spin button).
            let role = if rng.below(3) == 0 {
                Role::SpinButton
            } else {
                Role::Slider
            };
            let sliders = labels(harness, role);
            if sliders.is_empty() {
                "no slider".to_owned()
            } else {
                let i = rng.below(sliders.len());
                // Values across and beyond any slider's range.
                let value = match rng.below(4) {
                    0 => rng.uniform_in(-1.0, 1.0),
                    1 => rng.uniform_in(-400.0, 400.0),
                    2 => rng.uniform_in(0.0, 100_000.0),
                    _ => 0.0,
                };
                if let Some(node) = harness.query_all_by_role(role).nth(i) {
                    node.set_value_accesskit(value);
                }
                format!("{role:?} '{}' to {value}", sliders[i])
            }
        }
        5 => {
            let p = random_pos(rng);
            harness.hover_at(p);
            harness.drag_at(p);
            harness.drop_at(p);
            format!("click at {p:?}")
        }
        6 => {
            // Shift+click: a second push where it lands on the arm.
            let p = random_pos(rng);
            let shift = egui::Modifiers::SHIFT;
            harness.event(egui::Event::ModifiersChanged(shift));
            harness.hover_at(p);
            for pressed in [true, false] {
                harness.event(egui::Event::PointerButton {
                    pos: p,
                    button: egui::PointerButton::Primary,
                    pressed,
                    modifiers: shift,
                });
            }
            harness.event(egui::Event::ModifiersChanged(egui::Modifiers::NONE));
            format!("shift+click at {p:?}")
        }
        7 => {
            let (a, b) = (random_pos(rng), random_pos(rng));
            harness.drag_at(a);
            harness.hover_at(b);
            harness.drop_at(b);
            format!("drag {a:?} to {b:?}")
        }
        8 => {
            let keys = [
                egui::Key::Space,
                egui::Key::ArrowLeft,
                egui::Key::ArrowRight,
                egui::Key::R,
                egui::Key::Escape,
                egui::Key::Enter,
            ];
            let key = keys[rng.below(keys.len())];
            harness.key_press(key);
            format!("key {key:?}")
        }
        9 => {
            let scene = &m.scenes[rng.below(m.scenes.len())];
            harness.state_mut().open(scene.to_str().unwrap());
            format!("open {}", scene.display())
        }
        10 => {
            let robot = ["simple6", "lwr4plus"][rng.below(2)];
            harness.state_mut().open(robot);
            format!("robot {robot}")
        }
        11 => {
            harness.state_mut().open_session(&m.session, None);
            "open session".to_owned()
        }
        12 => {
            harness.state_mut().close_session();
            "close session".to_owned()
        }
        13 => {
            if m.recording {
                harness.state_mut().stop_recording();
            } else {
                harness
                    .state_mut()
                    .start_recording(&m.dir.join("monkey-recording.json"));
            }
            m.recording = !m.recording;
            format!("recording {}", m.recording)
        }
        15 => {
            harness.state_mut().open_session(&m.ambiguous, None);
            "open a recording with two arms' topics".to_owned()
        }
        16 => {
            // Listen (or listen again after Stop live), then feed frames:
            // some of another robot's width when the robot was switched.
            use std::io::Write as _;
            let listening = harness.state().live_address().map(str::to_owned);
            if let Some((sender, sent, _)) = m.live.as_mut().filter(|l| Some(&l.2) == listening.as_ref()) {
                let n = 1 + rng.below(5);
                for _ in 0..n {
                    let t = 0.01 * *sent as f64;
                    let tau = if rng.below(4) == 0 {
                        "[1, 2]"
                    } else {
                        "[0.4, -1.0, 0.2, 0.25, 0.1, 0, 0]"
                    };
                    let _ = writeln!(
                        sender,
                        r#"{{"t": {t}, "q": [0.1, 0.5, 0, -1, 0, 0.4, 0], "tau": {tau}}}"#
                    );
                    *sent += 1;
                }
                let _ = sender.flush();
                format!("{n} live frames")
            } else {
                harness.state_mut().start_live("127.0.0.1:0");
                let address = harness.state().live_address().map(str::to_owned);
                m.live = address.and_then(|a| std::net::TcpStream::connect(&a).ok().map(|c| (c, 0, a)));
                "listen live".to_owned()
            }
        }
        18 => {
            // A drag in the view: from the arm it sets a push, elsewhere it orbits.
            let (from, to) = (random_pos(rng), random_pos(rng));
            harness.hover_at(from);
            harness.drag_at(from);
            harness.hover_at(from + (to - from) * 0.5);
            harness.run_steps(1);
            harness.drop_at(to);
            format!("drag {from:?} to {to:?}")
        }
        19 => {
            let radios = labels(harness, Role::RadioButton);
            if radios.is_empty() {
                "no radio button".to_owned()
            } else {
                let i = rng.below(radios.len());
                click_nth(harness, Role::RadioButton, i);
                format!("radio '{}'", radios[i])
            }
        }
        20 => {
            // Typed into a field: a drag value (or a slider's number)
            // clicked into text editing, then a value typed and Enter.
            let fields = labels(harness, Role::SpinButton);
            if fields.is_empty() {
                "no field".to_owned()
            } else {
                let i = rng.below(fields.len());
                let typed = [
                    "0", "1e-300", "1e308", "-1e308", "-3", "-0.5", "NaN", "inf", "abc", "", "7", "0.2", "1e4",
                ];
                let text = typed[rng.below(typed.len())];
                if let Some(node) = harness.query_all_by_role(Role::SpinButton).nth(i) {
                    node.click();
                }
                harness.run_steps(1);
                harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
                harness.event(egui::Event::Text(text.to_owned()));
                harness.key_press(egui::Key::Enter);
                format!("typed '{text}' into '{}'", fields[i])
            }
        }
        14 => {
            let p = random_pos(rng);
            harness.hover_at(p);
            harness.event(egui::Event::MouseWheel {
                unit: egui::MouseWheelUnit::Line,
                delta: egui::vec2(0.0, rng.uniform_in(-5.0, 5.0) as f32),
                phase: egui::TouchPhase::Move,
                source: egui::MouseWheelSource::Wheel,
                modifiers: egui::Modifiers::NONE,
            });
            format!("wheel at {p:?}")
        }
        _ => {
            // A menu opened, then an item in it clicked.
            let menus = ["Scenes", "Session", "View", "Robot"];
            let menu = menus[rng.below(menus.len())];
            if let Some(node) = harness.query_all_by_label(menu).next() {
                node.click();
            }
            harness.run_steps(1);
            let buttons = labels(harness, Role::Button);
            let usable: Vec<usize> = (0..buttons.len()).filter(|&i| !buttons[i].ends_with('…')).collect();
            if let Some(&i) = usable.get(rng.below(usable.len().max(1))) {
                click_nth(harness, Role::Button, i);
            }
            format!("menu {menu}")
        }
    }
}

#[test]
fn thousands_of_random_actions_keep_the_app_whole() {
    let actions: usize = std::env::var("MONKEY_ACTIONS").map_or(2000, |v| v.parse().unwrap());
    let seed: u64 = std::env::var("MONKEY_SEED").map_or(1, |v| v.parse().unwrap());
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("monkey");
    std::fs::create_dir_all(&dir).unwrap();
    let mut monkey = Monkey {
        scenes: std::fs::read_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect(),
        session: session_file(&dir),
        ambiguous: ambiguous_recording(&dir, &session_file(&dir)),
        dir,
        recording: false,
        live: None,
    };
    let mut harness = proprioscope::app::headless_harness(open_target(None).unwrap(), [1280.0, 720.0]);
    harness.run_steps(2);
    let mut rng = Rng::new(seed);
    for step in 0..actions {
        let what = act(&mut harness, &mut rng, &mut monkey);
        harness.run_steps(1 + rng.below(3));
        if let Err(e) = harness.state().check_invariants() {
            panic!("step {step} ({what}): {e}");
        }
    }
    if monkey.recording {
        harness.state_mut().stop_recording();
    }
    // The app still estimates after all that.
    harness.state_mut().open("lwr4plus");
    proprioscope::app::settle(&mut harness).unwrap();
    harness.state().check_invariants().unwrap();
}
