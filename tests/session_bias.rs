//! The torque bias in the app: *take off bias* in the timeline estimates
//! the bias from the session, shows it in a plot of its own, and estimates
//! every frame as `estimate --bias auto` does (`egui_kittest` on Mesa's
//! software Vulkan).

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;
use proprioscope::app::{ProprioscopeApp, open_target};

fn proprioscope(args: &[&str]) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_proprioscope"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Runs frames until every frame of the session has its estimate.
fn settle_session(harness: &mut Harness<'_, ProprioscopeApp>) {
    for _ in 0..3000 {
        harness.step();
        let app = harness.state();
        if app.is_up_to_date() && app.session.estimates.iter().all(Option::is_some) {
            harness.run_steps(2);
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    panic!("the session was not estimated within 30 s");
}

#[test]
fn taking_off_the_bias_estimates_as_the_command_line_does() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("session-bias");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("biased.session.json");
    let path_str = path.to_str().unwrap();
    // Two seconds of presses with every joint offset by up to 0.3 N·m.
    proprioscope(&[
        "synth",
        path_str,
        "--seconds",
        "2",
        "--rate",
        "50",
        "--seed",
        "3",
        "--bias",
        "0.3",
    ]);
    let cli_out = dir.join("biased.jsonl");
    // The defaults the app and the command line share (one
    // configuration: σ learned, the model error taken off after the
    // bias); a recording opens smoothed.
    proprioscope(&[
        "estimate",
        path_str,
        "--bias",
        "auto",
        "--temporal",
        "smooth",
        "--out",
        cli_out.to_str().unwrap(),
    ]);
    let cli: Vec<serde_json::Value> = std::fs::read_to_string(&cli_out)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();

    let mut harness = proprioscope::app::headless_harness(open_target(Some(path_str)).unwrap(), [1400.0, 900.0]);
    settle_session(&mut harness);
    assert!(harness.state().session_bias().is_none());
    // With the bias left on, the frames estimate otherwise (so that the
    // comparison below can fail).
    let differs = harness.state().session.estimates.iter().zip(&cli).any(|(e, c)| {
        let e = e.unwrap();
        match c["point"].as_array() {
            None => e.verdict != proprioscope::core::estimate::summary::Verdict::NoContact,
            Some(p) => (e.point_world.x - p[0].as_f64().unwrap()).abs() > 1e-6,
        }
    });
    assert!(differs, "the bias changes nothing: the test cannot tell");
    harness.get_by_label("take off bias").click();
    harness.run_steps(2);
    settle_session(&mut harness);
    let app = harness.state();
    let replay = app.model.replay.as_ref().unwrap();
    assert!(replay.bias_auto);
    // The bias the app found is the one drawn (within the noise's reach).
    let session = proprioscope::io::session::Session::read(Path::new(path_str)).unwrap();
    let bias = app.session_bias().unwrap();
    assert_eq!(bias.len(), replay.session.frames.len());
    assert!(bias[0].iter().any(|b| b.abs() > 0.05), "{:?}", bias[0]);
    assert_eq!(cli.len(), app.session.estimates.len());
    for (i, (e, c)) in app.session.estimates.iter().zip(&cli).enumerate() {
        let e = e.unwrap();
        // The command line writes no contact as nulls.
        if c["verdict"] == "no_contact" {
            assert_eq!(
                e.verdict,
                proprioscope::core::estimate::summary::Verdict::NoContact,
                "frame {i}"
            );
            continue;
        }
        assert_eq!(c["link"], app.model.robot.links[e.link].name.as_str(), "frame {i}");
        let theirs = c["point"].as_array().unwrap();
        for (k, (x, y)) in e.point_world.to_array().iter().zip(theirs).enumerate() {
            assert!((x - y.as_f64().unwrap()).abs() < 1e-9, "frame {i} point[{k}]");
        }
    }
    assert!(session.frames.len() == cli.len());
    // The plot of the bias is there.
    assert!(harness.query_by_label("estimated torque bias [N·m]").is_some());
}
