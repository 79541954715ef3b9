//! The `proprioscope` binary live: `estimate --live` on frames over TCP and UDP, from `stream`.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use crate::common;

use common::{THESIS_SESSION, run_out, spawn_live, temp_file};

/// Sends `lines` to `address` once something listens there.
fn send_lines(address: &str, lines: &[&str]) {
    use std::io::Write as _;
    let mut connection = (0..200)
        .find_map(|_| {
            std::net::TcpStream::connect(address).ok().or_else(|| {
                std::thread::sleep(std::time::Duration::from_millis(25));
                None
            })
        })
        .unwrap();
    for line in lines {
        writeln!(connection, "{line}").unwrap();
    }
}

/// `estimate --live`: frames over TCP are estimated as they come (with
/// the frames before them); a line that is not a frame, a frame with
/// missing values and a time going back are reported and skipped; a
/// second connection goes on.
#[test]
fn live_frames_are_estimated_and_bad_lines_skipped() {
    let out = temp_file("live.jsonl", "");
    let live = spawn_live(
        "127.0.0.1:0",
        false,
        &[
            "--live-frames",
            "3",
            "--points",
            "2000",
            "--sigma",
            "0.01",
            "--fmin",
            "0.5",
            "--fmax",
            "3",
            "--out",
            out.to_str().unwrap(),
        ],
    );
    let address = live.live.clone();
    let contact = r#"{"t": 0.0, "q": [0, 0, 0, 0, 0, 0, 0], "tau": [0.09516, -0.53783, 0.09516, 0.01017, 0, 0, 0], "truth": {"link": "lwr_4_link", "point": [0.046, 0.098, 0.692], "force": [-1.37, -0.85, 0.33]}}"#;
    let later = contact.replace(r#""t": 0.0"#, r#""t": 0.01"#);
    send_lines(
        &address,
        &[
            r#"{"format": "contact-session", "version": 1, "robot": "lwr4plus"}"#,
            contact,
            "not json at all",
            r#"{"t": 0.005, "q": [0, 0, 0], "tau": [0, 0, 0, 0, 0, 0, 0]}"#,
            &later,
        ],
    );
    send_lines(&address, &[contact]);
    let (ok, stderr) = live.wait();
    assert!(ok, "{stderr}");
    assert!(
        stderr.contains("skipped line 2") && stderr.contains("skipped line 3"),
        "{stderr}"
    );
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&out)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 3, "{stderr}");
    for line in &lines {
        assert_eq!(line["verdict"], "contact", "{line}");
        assert!(line["contact_probability"].as_f64().unwrap() > 0.5, "{line}");
        assert!(line["truth"]["position_error_m"].as_f64().unwrap() < 0.05, "{line}");
    }
    assert_eq!(lines[2]["frame"], 2);
}

/// `stream` replays a session to a live estimate, frame for frame.
#[test]
fn a_streamed_session_is_estimated_live() {
    streamed_session_is_estimated_live("127.0.0.1:0", "tcp");
}

/// The same over UDP: `stream --to udp://…` sends a datagram a line to
/// `estimate --live udp://…`.
#[test]
fn a_session_streamed_over_udp_is_estimated_live() {
    streamed_session_is_estimated_live("udp://127.0.0.1:0", "udp");
}

/// The thesis' session streamed by `stream` to `estimate --live listen`
/// (files named after `name`): its two frames estimated, a contact then
/// none.
fn streamed_session_is_estimated_live(listen: &str, name: &str) {
    let session = temp_file(&format!("{name}.session.json"), THESIS_SESSION);
    let out = temp_file(&format!("{name}.jsonl"), "");
    let live = spawn_live(
        listen,
        false,
        &[
            "--live-frames",
            "2",
            "--points",
            "2000",
            "--sigma",
            "0.01",
            "--fmin",
            "0.5",
            "--fmax",
            "3",
            "--temporal",
            "none",
            "--out",
            out.to_str().unwrap(),
        ],
    );
    let address = live.live.clone();
    let scheme = listen.split_once("://").map_or("", |(scheme, _)| scheme);
    assert!(address.starts_with(scheme), "{address} from {listen}");
    let (ok, _, err) = run_out(&["stream", session.to_str().unwrap(), "--to", &address, "--rate", "0"]);
    assert!(ok, "{err}");
    let (ok, stderr) = live.wait();
    assert!(ok, "{stderr}");
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&out)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 2);
    assert_eq!(lines[0]["verdict"], "contact");
    assert_eq!(lines[1]["verdict"], "no_contact");
}

/// Live, the surface has fewer samples than for a file unless `--points`
/// says (so that each frame keeps up with the arm) or two contacts are
/// looked for (a file's: the live surface finds half the pairs), and the
/// log says how many.
#[test]
fn live_takes_the_live_surface_unless_points_are_given() {
    use proprioscope::core::config::estimator::{DEFAULT_SURFACE_POINTS, LIVE_SURFACE_POINTS};
    let frame = r#"{"t": 0.0, "q": [0, 0, 0, 0, 0, 0, 0], "tau": [0.09516, -0.53783, 0.09516, 0.01017, 0, 0, 0]}"#;
    for (points, contacts, want) in [
        (None, "1", LIVE_SURFACE_POINTS),
        (Some("1200"), "1", 1200),
        (None, "2", DEFAULT_SURFACE_POINTS),
    ] {
        let out = temp_file(&format!("live-points-{want}.jsonl"), "");
        let mut args = vec![
            "--live-frames",
            "1",
            "--temporal",
            "none",
            "--contacts",
            contacts,
            "--out",
            out.to_str().unwrap(),
        ];
        if let Some(n) = points {
            args.extend(["--points", n]);
        }
        let live = spawn_live("127.0.0.1:0", false, &args);
        let address = live.live.clone();
        send_lines(
            &address,
            &[
                r#"{"format": "contact-session", "version": 1, "robot": "lwr4plus"}"#,
                frame,
            ],
        );
        let (ok, stderr) = live.wait();
        assert!(ok, "{stderr}");
        assert!(stderr.contains(&format!(": {want} surface points on")), "{stderr}");
        assert_eq!(stderr.contains("--points to change"), points.is_none(), "{stderr}");
        assert_eq!(stderr.contains("two contacts need them"), contacts == "2", "{stderr}");
    }
}
