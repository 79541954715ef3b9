//! The `proprioscope` binary: `torques` on scenes and on command-line
//! pushes, `estimate` on sessions.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{THESIS_SESSION, run_out, temp_file};

#[test]
fn torques_json_has_exactly_the_documented_shape() {
    let (ok, out, err) = run_out(&["torques", "scenes/lwr-collision-3.json", "--json"]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let obj = v.as_object().unwrap();
    assert_eq!(obj.keys().collect::<Vec<_>>(), vec!["joints"]);
    let joints = v["joints"].as_array().unwrap();
    assert_eq!(joints.len(), 7);
    for j in joints {
        let mut keys: Vec<_> = j.as_object().unwrap().keys().cloned().collect();
        keys.sort();
        assert_eq!(keys, vec!["name", "torque"]);
    }
    assert_eq!(joints[0]["name"], "lwr_joint_1");
    // Table 3.4 row 3 in N·m.
    let tau: Vec<f64> = joints.iter().map(|j| j["torque"].as_f64().unwrap()).collect();
    for (t, e) in tau.iter().zip([0.095, -0.536, 0.095, 0.010, 0.0, 0.0, 0.0]) {
        assert!((t - e).abs() <= 0.003, "{tau:?}");
    }
}

#[test]
fn torques_from_arguments_in_ncm_names_the_silent_joints() {
    let (ok, out, err) = run_out(&[
        "torques",
        "--robot",
        "lwr4plus",
        "--q",
        "0,0,0,0,0,0,0",
        "--link",
        "lwr_4_link",
        "--point",
        "0.046,0.098,0.692",
        "--force",
        "-1.37,-0.85,0.33",
        "--ncm",
    ]);
    assert!(ok, "{err}");
    assert!(
        out.contains("N·cm") && out.contains("9.5160") && out.contains("-53.78"),
        "{out}"
    );
    assert!(
        out.contains("Sense nothing") && out.contains("lwr_joint_5, lwr_joint_6, lwr_joint_7"),
        "{out}"
    );
}

#[test]
fn bad_arguments_fail_with_a_message() {
    let (ok, _, err) = run_out(&[
        "torques",
        "--robot",
        "lwr4plus",
        "--q",
        "0,0",
        "--link",
        "lwr_4_link",
        "--point",
        "0,0,1",
        "--force",
        "1,0,0",
    ]);
    assert!(!ok && err.contains("expected 7") && err.contains("got 2"), "{err}");
    let (ok, _, err) = run_out(&[
        "torques",
        "--robot",
        "lwr4plus",
        "--link",
        "lwr_9_link",
        "--point",
        "0,0,1",
        "--force",
        "1,0,0",
    ]);
    assert!(!ok && err.contains("lwr_9_link"), "{err}");
    let (ok, _, err) = run_out(&[
        "torques",
        "--robot",
        "lwr4plus",
        "--link",
        "lwr_4_link",
        "--point",
        "0,zero,1",
        "--force",
        "1,0,0",
    ]);
    assert!(!ok && err.contains("zero"), "{err}");
    let (ok, _, err) = run_out(&["torques", "scenes/no-such-scene.json"]);
    assert!(!ok && err.contains("no-such-scene.json"), "{err}");
}

/// One Panda oracle row through the command line.
#[test]
#[ignore = "needs ../shared"]
fn torques_on_a_urdf_from_the_command_line_match_the_oracle() {
    let shared = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared");
    let text = std::fs::read_to_string(shared.join("oracle/panda_static.json")).unwrap();
    let oracle: serde_json::Value = serde_json::from_str(&text).unwrap();
    let row = &oracle["rows"][100];
    let list = |v: &serde_json::Value| {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap().to_string())
            .collect::<Vec<_>>()
            .join(",")
    };
    let (ok, out, err) = run_out(&[
        "torques",
        "--robot",
        "../shared/robots/panda/urdf/panda.urdf",
        "--q",
        &list(&row["q"]),
        "--link",
        row["link"].as_str().unwrap(),
        "--point",
        &list(&row["point_world"]),
        "--force",
        &list(&row["F_world"]),
        "--json",
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    for (ours, theirs) in v["joints"]
        .as_array()
        .unwrap()
        .iter()
        .zip(row["tau"].as_array().unwrap())
    {
        // point_world is rounded to 10 digits in the oracle.
        assert!(
            (ours["torque"].as_f64().unwrap() - theirs.as_f64().unwrap()).abs() < 1e-7,
            "{out}"
        );
    }
}

#[test]
fn estimate_writes_one_json_line_per_frame_and_a_summary() {
    let session = temp_file("thesis.session.json", THESIS_SESSION);
    let out = session.with_extension("jsonl");
    let (ok, stdout, stderr) = run_out(&[
        "estimate",
        session.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--points",
        "3000",
        "--sigma",
        "0.01",
        "--fmin",
        "0.5",
        "--fmax",
        "3",
    ]);
    assert!(ok, "{stderr}");
    assert!(
        stdout.contains("2 frames") && stdout.contains("update time"),
        "{stdout}"
    );
    assert!(stdout.contains("median pos. error"), "{stdout}");
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&out)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 2);
    let first = &lines[0];
    for key in [
        "t",
        "link",
        "point",
        "force",
        "probability",
        "credible90_points",
        "update_ms",
        "verdict",
    ] {
        assert!(first.get(key).is_some(), "missing {key}: {first}");
    }
    assert_eq!(first["verdict"], "contact");
    // A recording is smoothed: its frames' parts interleave, none told.
    assert!(first["update_parts_ms"].is_null(), "{first}");
    assert!(first["truth"]["position_error_m"].as_f64().unwrap() < 0.05, "{first}");
    // Whether the 90 % set holds the push, per frame and in the report.
    assert!(first["truth"]["in_credible90"].is_boolean(), "{first}");
    assert!(stdout.contains("90 % set holds the push"), "{stdout}");
    // The links' shares of the posterior: at least 1 % each, most
    // probable first, adding up to at most 1, the contact's link among them.
    let links = first["links"].as_array().unwrap();
    let shares: Vec<f64> = links.iter().map(|l| l["probability"].as_f64().unwrap()).collect();
    assert!(!shares.is_empty() && shares.iter().all(|&p| p >= 0.01), "{first}");
    assert!(shares.windows(2).all(|w| w[0] >= w[1]), "{first}");
    assert!(shares.iter().sum::<f64>() <= 1.0 + 1e-9, "{first}");
    assert!(links.iter().any(|l| l["link"] == first["link"]), "{first}");
    assert_eq!(lines[1]["verdict"], "no_contact");
    assert!(lines[1]["point"].is_null());
    assert!(lines[1]["links"].is_null());
}

/// `--temporal filter|smooth`: the same JSON lines plus each frame's
/// contact probability, and the detection record; a bad rate is refused
/// by name.
#[test]
fn estimate_over_time_adds_the_contact_probability() {
    let session = temp_file("thesis-temporal.session.json", THESIS_SESSION);
    for temporal in ["filter", "smooth"] {
        let out = session.with_extension(format!("{temporal}.jsonl"));
        let (ok, stdout, stderr) = run_out(&[
            "estimate",
            session.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--points",
            "3000",
            "--sigma",
            "0.01",
            "--fmin",
            "0.5",
            "--fmax",
            "3",
            "--temporal",
            temporal,
        ]);
        assert!(ok, "{stderr}");
        assert!(stdout.contains("detection: 1/1 contact frames"), "{stdout}");
        let lines: Vec<serde_json::Value> = std::fs::read_to_string(&out)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert_eq!(lines.len(), 2);
        assert_eq!(lines[0]["verdict"], "contact", "{temporal}: {}", lines[0]);
        assert!(lines[0]["contact_probability"].as_f64().unwrap() > 0.5, "{}", lines[0]);
        assert!(
            lines[0]["truth"]["position_error_m"].as_f64().unwrap() < 0.05,
            "{}",
            lines[0]
        );
        assert_eq!(lines[1]["verdict"], "no_contact", "{temporal}: {}", lines[1]);
        assert!(lines[1]["contact_probability"].as_f64().unwrap() < 0.5, "{}", lines[1]);
    }
    let (ok, _, err) = run_out(&[
        "estimate",
        session.to_str().unwrap(),
        "--temporal",
        "smooth",
        "--release-rate=-1",
    ]);
    assert!(
        !ok && err.contains("--release-rate") && err.contains("[0, 1000] 1/s"),
        "{err}"
    );
}

/// `synth` writes a session with truth that `estimate` reads; with
/// `--bias auto` the estimated offsets are printed per joint.
#[test]
fn a_synthetic_session_round_trips_through_estimate_with_its_bias() {
    let dir = std::env::temp_dir().join(format!("proprioscope-synth-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let session = dir.join("synth.session.json");
    let (ok, _, err) = run_out(&[
        "synth",
        session.to_str().unwrap(),
        "--seconds",
        "2",
        "--rate",
        "50",
        "--seed",
        "4",
        "--bias",
        "0.3",
        "--links",
        "lwr_5_link,lwr_6_link",
    ]);
    assert!(ok, "{err}");
    let (ok, out, err) = run_out(&[
        "estimate",
        session.to_str().unwrap(),
        "--bias",
        "auto",
        "--points",
        "1000",
    ]);
    assert!(ok, "{err}");
    assert!(
        out.contains("bias (estimated, N·m") && out.contains("lwr_joint_7"),
        "{out}"
    );
    assert!(out.contains("median pos. error"), "{out}");
    // Windows shorter than the session: a drifting offset, first → last.
    let (ok, out, err) = run_out(&[
        "estimate",
        session.to_str().unwrap(),
        "--bias",
        "auto",
        "--bias-window",
        "0.5",
        "--points",
        "1000",
    ]);
    assert!(ok, "{err}");
    assert!(out.contains(" → "), "{out}");
    let (ok, _, err) = run_out(&[
        "estimate",
        session.to_str().unwrap(),
        "--bias",
        "auto",
        "--bias-window=-1",
    ]);
    assert!(!ok && err.contains("bias window"), "{err}");
    let (ok, _, err) = run_out(&["synth", session.to_str().unwrap(), "--links", "no_such_link"]);
    assert!(!ok && err.contains("no_such_link"), "{err}");
    // Friction: the summary table as before, a bad μ refused by name.
    let (ok, out, err) = run_out(&[
        "estimate",
        session.to_str().unwrap(),
        "--friction",
        "0.15",
        "--points",
        "1000",
    ]);
    assert!(ok && out.contains("median force error"), "{err}");
    let (ok, _, err) = run_out(&[
        "estimate",
        session.to_str().unwrap(),
        "--friction=-1",
        "--points",
        "1000",
    ]);
    assert!(!ok && err.contains("friction"), "{err}");
    // The default, `auto`: said on stderr where it takes friction (over
    // time); a word that is neither a number nor `auto` is refused.
    let (ok, _, err) = run_out(&[
        "estimate",
        session.to_str().unwrap(),
        "--temporal",
        "smooth",
        "--friction",
        "auto",
        "--points",
        "1000",
    ]);
    assert!(ok && err.contains("--friction auto: μ = 0.2"), "{err}");
    let (ok, _, err) = run_out(&["estimate", session.to_str().unwrap(), "--friction", "lots"]);
    assert!(!ok && err.contains("auto"), "{err}");
}

#[test]
fn a_session_going_back_in_time_is_refused_naming_the_frame() {
    let text = THESIS_SESSION.replace(r#""t": 0.1"#, r#""t": -0.1"#);
    let session = temp_file("backwards.session.json", &text);
    let (ok, _, stderr) = run_out(&["estimate", session.to_str().unwrap()]);
    assert!(
        !ok && stderr.contains("frame 1") && stderr.contains("backwards"),
        "{stderr}"
    );
}

#[test]
fn skip_bad_frames_estimates_the_rest_with_their_file_numbers() {
    // Frame 1 goes back in time; a third frame repeats frame 0 later.
    let text = THESIS_SESSION.replace(r#""t": 0.1"#, r#""t": -0.1"#).replace(
        r#""truth": null}
  ]"#,
        r#""truth": null},
    {"t": 0.2, "q": [0, 0, 0, 0, 0, 0, 0], "tau": [0.09516, -0.53783, 0.09516, 0.01017, 0, 0, 0]}
  ]"#,
    );
    let session = temp_file("skip.session.json", &text);
    let out = session.with_extension("jsonl");
    let (ok, _, stderr) = run_out(&[
        "estimate",
        session.to_str().unwrap(),
        "--skip-bad-frames",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    assert!(
        stderr.contains("skipped frame 1") && stderr.contains("backwards"),
        "{stderr}"
    );
    let frames: Vec<u64> = std::fs::read_to_string(&out)
        .unwrap()
        .lines()
        .map(|l| {
            serde_json::from_str::<serde_json::Value>(l).unwrap()["frame"]
                .as_u64()
                .unwrap()
        })
        .collect();
    assert_eq!(frames, [0, 2]);
}

/// The JSON and CSV forms of the example session give the same estimates.
#[test]
#[ignore = "needs ../shared"]
fn json_and_csv_sessions_give_the_same_estimates() {
    let dir = std::env::temp_dir().join(format!("proprioscope-estimate-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (json_out, csv_out) = (dir.join("json.jsonl"), dir.join("csv.jsonl"));
    let (ok, _, stderr) = run_out(&[
        "estimate",
        "../shared/sessions/lwr4plus_static_example.session.json",
        "--out",
        json_out.to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    let (ok, _, stderr) = run_out(&[
        "estimate",
        "../shared/sessions/lwr4plus_static_example.csv",
        "--robot",
        "../shared/robots/lwr4plus/lwr4plus.urdf",
        "--out",
        csv_out.to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    let strip = |path: &PathBuf| -> Vec<serde_json::Value> {
        std::fs::read_to_string(path)
            .unwrap()
            .lines()
            .map(|l| {
                let mut v: serde_json::Value = serde_json::from_str(l).unwrap();
                let fields = v.as_object_mut().unwrap();
                fields.remove("update_ms");
                fields.remove("update_parts_ms");
                v
            })
            .collect()
    };
    let (a, b) = (strip(&json_out), strip(&csv_out));
    assert_eq!(a.len(), 40);
    assert_eq!(a, b);
}

#[test]
fn a_screenshot_of_a_session_that_cannot_be_read_fails_naming_it() {
    let missing = std::env::temp_dir().join("proprioscope-no-such-session.csv");
    let out = std::env::temp_dir().join("proprioscope-no-such-session.png");
    let (ok, _, stderr) = run_out(&["screenshot", missing.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(!ok && stderr.contains("proprioscope-no-such-session.csv"), "{stderr}");
    assert!(!out.exists());
}

/// Non-finite numbers, absurd counts and pushes too large to compute are
/// errors naming the value (they printed NaN torques, `inf` and `null`).
#[test]
fn non_finite_and_out_of_range_inputs_are_named_errors() {
    let (ok, _, err) = run_out(&["torques", "--robot", "lwr4plus", "--q", "inf,0,0,0,0,0,0"]);
    assert!(!ok && err.contains("'inf' is not a finite number"), "{err}");
    let (ok, _, err) = run_out(&[
        "torques",
        "--robot",
        "lwr4plus",
        "--link",
        "lwr_4_link",
        "--point",
        "0,0,0.6",
        "--force",
        "NaN,0,0",
    ]);
    assert!(!ok && err.contains("not a finite number"), "{err}");
    let (ok, _, err) = run_out(&["estimate", "scenes/lwr-collision-1.json", "--sigma", "NaN"]);
    assert!(!ok && err.contains("not a finite number"), "{err}");
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli-limits");
    std::fs::create_dir_all(&dir).unwrap();
    let session = dir.join("s.json");
    std::fs::write(
        &session,
        r#"{"format":"contact-session","version":1,"robot":"lwr4plus","frames":[{"t":0,"q":[0,0,0,0,0,0,0],"tau":[1e5,0,0,0,0,0,0]}]}"#,
    )
    .unwrap();
    let (ok, _, err) = run_out(&["estimate", session.to_str().unwrap(), "--particles", "1000000000"]);
    assert!(
        !ok && err.contains("--particles") && err.contains("1000000000") && err.contains("1 to 10000000"),
        "{err}"
    );
    let (ok, _, err) = run_out(&["estimate", session.to_str().unwrap(), "--points", "2000000"]);
    assert!(!ok && err.contains("--points") && err.contains("1 to 1000000"), "{err}");
    // Each within its range, together beyond what a frame may hold: 1e5 N·m at σ 1e-4.
    let (ok, _, err) = run_out(&[
        "estimate",
        session.to_str().unwrap(),
        "--points",
        "300",
        "--sigma",
        "1e-4",
    ]);
    assert!(!ok && err.contains("beyond what can be computed"), "{err}");
}

/// `robot-info … | head -1`: the reader goes away; the program ends
/// quietly instead of panicking on the broken pipe.
#[test]
fn a_closed_output_pipe_ends_the_program_quietly() {
    use std::io::Read as _;
    let mut child = Command::new(env!("CARGO_BIN_EXE_proprioscope"))
        .args(["robot-info", "lwr4plus"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let status = child.wait().unwrap();
    let mut err = String::new();
    child.stderr.take().unwrap().read_to_string(&mut err).unwrap();
    assert!(status.success() && !err.contains("panicked"), "{status} {err}");
}

/// A URDF named by a relative path from its own folder finds its
/// `package://` meshes (the search started from an empty folder name).
#[test]
fn package_uris_resolve_for_a_urdf_named_from_its_own_folder() {
    let root = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli-package");
    let _ = std::fs::remove_dir_all(&root);
    std::fs::create_dir_all(root.join("my_robot/urdf")).unwrap();
    std::fs::create_dir_all(root.join("my_robot/meshes")).unwrap();
    std::fs::write(
        root.join("my_robot/meshes/body.obj"),
        "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0 0 0.1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    )
    .unwrap();
    std::fs::write(
        root.join("my_robot/urdf/r.urdf"),
        r#"<robot name="r"><link name="base"/><link name="body"><visual><geometry><mesh filename="package://my_robot/meshes/body.obj"/></geometry></visual></link>
        <joint name="j" type="continuous"><parent link="base"/><child link="body"/><axis xyz="0 0 1"/></joint></robot>"#,
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_proprioscope"))
        .args(["robot-info", "r.urdf"])
        .current_dir(root.join("my_robot/urdf"))
        .output()
        .unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(out.status.success(), "{stderr}");
    assert!(stdout.contains("body"), "{stdout}");
}

/// Every robot recording of the link-4 press estimates as its JSON
/// session does (same links, points to 1e-9), and `topics` says which
/// topics make the frames.
#[test]
#[ignore = "needs ../shared"]
fn recordings_estimate_as_their_sessions_do() {
    let urdf = "../shared/robots/lwr4plus/lwr4plus.urdf";
    let estimate = |file: &str, out: &Path| {
        let (ok, _, err) = run_out(&[
            "estimate",
            file,
            "--robot",
            urdf,
            "--temporal",
            "filter",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(ok, "{file}: {err}");
        let text = std::fs::read_to_string(out).unwrap();
        text.lines()
            .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
            .collect::<Vec<_>>()
    };
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
    let reference = estimate(
        "../shared/sessions/lwr4plus_dyn_example_link4.session.json",
        &dir.join("rec-json.jsonl"),
    );
    assert_eq!(reference.len(), 300);
    for layout in ["plain.mcap", "franka.mcap", "kuka.mcap", "plain.bag"] {
        let file = format!("../shared/recordings/lwr4plus_dyn_example_link4_{layout}");
        let lines = estimate(&file, &dir.join(format!("rec-{layout}.jsonl")));
        assert_eq!(lines.len(), reference.len(), "{layout}");
        for (a, b) in lines.iter().zip(&reference) {
            assert_eq!(a["link"], b["link"], "{layout} frame {}", a["frame"]);
            assert_eq!(a["frame"], b["frame"]);
            let (p, q) = (&a["point"], &b["point"]);
            for i in 0..3 {
                if let (Some(x), Some(y)) = (p[i].as_f64(), q[i].as_f64()) {
                    assert!((x - y).abs() < 1e-9, "{layout} frame {}: {p} vs {q}", a["frame"]);
                }
            }
            let (t, u) = (&a["truth"], &b["truth"]);
            assert_eq!(t["link"], u["link"], "{layout}");
            if let (Some(x), Some(y)) = (t["position_error_m"].as_f64(), u["position_error_m"].as_f64()) {
                assert!((x - y).abs() < 1e-9, "{layout}: {t} vs {u}");
            }
        }
    }
    let (ok, out, err) = run_out(&["topics", "../shared/recordings/lwr4plus_dyn_example_link4_kuka.mcap"]);
    assert!(ok, "{err}");
    assert!(
        out.contains("/lbr/state") && out.contains("lbr_fri_idl/LBRState"),
        "{out}"
    );
    assert!(
        out.contains("frames from: --q-topic /joint_states --tau-topic /lbr/state --tau-field external_torque"),
        "{out}"
    );
    // A field that is not there is refused, naming the fields that are.
    let (ok, _, err) = run_out(&[
        "estimate",
        "../shared/recordings/lwr4plus_dyn_example_link4_kuka.mcap",
        "--robot",
        urdf,
        "--tau-field",
        "tau_ext",
    ]);
    assert!(!ok && err.contains("tau_ext"), "{err}");
}

/// `estimate --out est.mcap` writes the session's frames and the
/// estimates; our own reader gets both back: the same frames, and each
/// contact as the JSON lines give it.
#[test]
fn estimates_out_as_mcap_read_back_as_they_were_written() {
    use proprioscope::io::recording::{self, TopicChoice};
    use proprioscope::io::rosmsg::Value;
    let dir = std::env::temp_dir().join(format!("proprioscope-mcap-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let session = dir.join("synth.session.json");
    let path = |name: &str| dir.join(name).to_str().unwrap().to_owned();
    let (ok, _, err) = run_out(&[
        "synth",
        &path("synth.session.json"),
        "--seconds",
        "1",
        "--rate",
        "50",
        "--seed",
        "2",
    ]);
    assert!(ok, "{err}");
    let common = ["--points", "1000", "--temporal", "filter"];
    let (ok, _, err) = run_out(
        &[
            &["estimate", &path("synth.session.json"), "--out", &path("est.jsonl")],
            &common[..],
        ]
        .concat(),
    );
    assert!(ok, "{err}");
    let (ok, _, err) = run_out(
        &[
            &["estimate", &path("synth.session.json"), "--out", &path("est.mcap")],
            &common[..],
        ]
        .concat(),
    );
    assert!(ok, "{err}");
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(dir.join("est.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let mcap = dir.join("est.mcap");
    let bytes = std::fs::read(&mcap).unwrap();
    // The frames, read back as a recording, are the session's.
    let read = recording::read_session(&mcap, &bytes, &TopicChoice::default(), &|_| {}).unwrap();
    let original = proprioscope::io::session::Session::read(&session).unwrap();
    assert_eq!(read.session.frames.len(), original.frames.len());
    for (a, b) in read.session.frames.iter().zip(&original.frames) {
        assert!((a.t - b.t).abs() < 1e-9 && a.q == b.q && a.tau == b.tau && a.truth == b.truth);
    }
    // The contact points, in frame order, are the JSON lines' points.
    let index = recording::index(&mcap, &bytes).unwrap();
    let topic = |name: &str| index.topics.iter().find(|t| t.topic == name).unwrap();
    let contacts: Vec<&serde_json::Value> = lines.iter().filter(|l| !l["point"].is_null()).collect();
    assert!(!contacts.is_empty());
    assert_eq!(topic("/proprioscope/contact_point").count, contacts.len());
    assert_eq!(topic("/proprioscope/contact_probability").count, lines.len());
    // The credible set is drawn with the arrows, at their rate.
    let regions = topic("/proprioscope/region").count;
    assert_eq!(regions, topic("/proprioscope/arrows").count);
    assert!((1..=lines.len()).contains(&regions), "{regions} of {}", lines.len());
    let first = topic("/proprioscope/contact_point").first.clone().unwrap();
    for (i, axis) in ["x", "y", "z"].iter().enumerate() {
        let got = first.get(&format!("point.{axis}")).and_then(Value::as_f64).unwrap();
        assert!((got - contacts[0]["point"][i].as_f64().unwrap()).abs() < 1e-12);
    }
    let wrench = topic("/proprioscope/contact").first.clone().unwrap();
    assert_eq!(
        wrench.get("header.frame_id"),
        Some(&Value::Str(contacts[0]["link"].as_str().unwrap().into()))
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A bad input is reported by its message, also where the user keeps
/// `RUST_BACKTRACE` set: no stack trace of the program under it.
#[test]
fn errors_are_reported_without_a_stack_trace() {
    let out = Command::new(env!("CARGO_BIN_EXE_proprioscope"))
        .args(["estimate", "no-such-dir/missing.session.json"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("RUST_BACKTRACE", "1")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.starts_with("Error: no-such-dir/missing.session.json: cannot read the session"),
        "{err}"
    );
    assert!(!err.contains("backtrace") && !err.contains("proprioscope::"), "{err}");
}

/// A CSV session names no robot: `screenshot` (as `view`) refuses without
/// `--robot`, saying so.
#[test]
fn a_csv_session_without_a_robot_is_refused_with_the_reason() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("csv-robot");
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("s.csv");
    std::fs::write(
        &csv,
        "t,q1,q2,q3,q4,q5,q6,q7,tau1,tau2,tau3,tau4,tau5,tau6,tau7\n0,0,0,0,0,0,0,0,0,0,0,0,0,0,0\n",
    )
    .unwrap();
    let out = dir.join("s.png");
    let (ok, _, err) = run_out(&["screenshot", csv.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(
        !ok && err.contains("names no robot") && err.contains("--robot"),
        "{err}"
    );
    assert!(!out.exists());
}

/// `estimate` scores the paths of presses that slide (its `slides:`
/// line) and says nothing of them where every press holds.
#[test]
fn estimate_scores_slides_paths_only_where_presses_slide() {
    let dir = std::env::temp_dir().join(format!("proprioscope-slides-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let synth = |name: &str, slide: &[&str]| {
        let path = dir.join(name);
        let mut args = vec!["synth", path.to_str().unwrap(), "--seconds", "4", "--rate", "50"];
        args.extend(["--seed", "1", "--links", "lwr_6_link"]);
        args.extend(slide);
        let (ok, _, err) = run_out(&args);
        assert!(ok, "{err}");
        let (ok, out, err) = run_out(&[
            "estimate",
            path.to_str().unwrap(),
            "--points",
            "1000",
            "--temporal",
            "smooth",
        ]);
        assert!(ok, "{err}");
        out
    };
    let out = synth(
        "slides.json",
        &["--slide", "0.1", "--slide-min", "0.05", "--kinetic-friction", "0.3,0.6"],
    );
    let line = out
        .lines()
        .find(|l| l.starts_with("slides: "))
        .unwrap_or_else(|| panic!("{out}"));
    let median = common::figure_after(&out, "slides: ", "median ");
    // Three presses slide 5–10 cm/s; the estimate follows them within a
    // few times their length (`docs/validation.md`, *Sliding contacts*).
    assert!(
        line.contains("3 of 3 presses") && median > 0.5 && median < 5.0,
        "{line}"
    );
    let out = synth("held.json", &[]);
    assert!(!out.contains("slides:"), "{out}");
    std::fs::remove_dir_all(&dir).ok();
}

/// `synth --press-secs LO,HI` draws each press that long (ramps
/// included), so slides as long as a real one can be drawn; an interval
/// the wrong way round is refused by name.
#[test]
fn synth_draws_presses_as_long_as_asked() {
    let session = temp_file("press-secs.session.json", "");
    let path = session.to_str().unwrap();
    let args = ["synth", path, "--seconds", "12", "--rate", "50", "--seed", "2"];
    let (ok, _, err) = run_out(&[&args[..], &["--links", "lwr_6_link", "--press-secs", "2,2.5"]].concat());
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(&session).unwrap();
    let frames = serde_json::from_str::<serde_json::Value>(&text).unwrap()["frames"].clone();
    let frames = frames.as_array().unwrap();
    // Each run of frames with a true contact, as (first, last) frame times.
    let mut runs: Vec<(f64, f64)> = Vec::new();
    let mut pressed_before = false;
    for f in frames {
        let t = f["t"].as_f64().unwrap();
        let pressed = !f["truth"].is_null();
        match (pressed, pressed_before, runs.last_mut()) {
            (true, true, Some(run)) => run.1 = t,
            (true, _, _) => runs.push((t, t)),
            _ => {}
        }
        pressed_before = pressed;
    }
    let end = frames.last().unwrap()["t"].as_f64().unwrap();
    let whole: Vec<f64> = runs.iter().filter(|r| r.1 < end).map(|r| r.1 - r.0).collect();
    assert!(whole.len() >= 2, "{runs:?}");
    // A press's first and last frames may fall inside its ramps with no
    // push yet: up to a frame less at either end.
    assert!(whole.iter().all(|&d| (1.9..=2.5).contains(&d)), "{runs:?}");
    let (ok, _, err) = run_out(&[&args[..], &["--press-secs", "2,1"]].concat());
    assert!(!ok && err.contains("--press-secs") && err.contains("LO ≤ HI"), "{err}");
}
