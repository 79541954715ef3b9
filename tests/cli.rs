//! The `proprioscope` binary: `torques` on scenes and on command-line pushes.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use std::path::Path;
use std::process::Command;

fn run(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_proprioscope"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn torques_json_has_exactly_the_documented_shape() {
    let (ok, out, err) = run(&["torques", "scenes/lwr-collision-3.json", "--json"]);
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
    let (ok, out, err) = run(&[
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
    let (ok, _, err) = run(&[
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
    let (ok, _, err) = run(&[
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
    let (ok, _, err) = run(&[
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
    let (ok, _, err) = run(&["torques", "scenes/no-such-scene.json"]);
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
    let (ok, out, err) = run(&[
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
