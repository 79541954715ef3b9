//! Recording sessions: crash safety of the recorder, and recorded sessions
//! read back by the `estimate` command.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use std::io::BufRead as _;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use proprioscope::io::session::Session;

fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("session-tests");
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn a_recorder_killed_mid_session_loses_at_most_its_last_second() {
    let path = scratch("killed.session.json");
    // At 10 frames a second, a write buffer that was not flushed would hold
    // more than a second of frames (this test then fails).
    let rate = 10.0;
    let mut child = Command::new(env!("CARGO_BIN_EXE_proprioscope"))
        .args(["record-demo", "--rate", "10", "--out"])
        .arg(&path)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    // The first frame is on disk when the recorder says so.
    let mut line = String::new();
    std::io::BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    assert!(line.starts_with("recording"), "{line}");
    let started = Instant::now();
    std::thread::sleep(Duration::from_secs(3));
    // SIGKILL: no destructor, no closing bracket.
    child.kill().unwrap();
    let killed_after = started.elapsed().as_secs_f64();
    child.wait().unwrap();
    assert!(Session::read(&path).is_err(), "a killed recording is not closed JSON");
    let (session, problems) = Session::read_skipping_bad_frames(&path).unwrap();
    assert!(problems.is_empty(), "{problems:?}");
    // Every frame up to one second before the kill is there, in order.
    let last_t = session.frames.last().unwrap().t;
    assert!(
        last_t >= killed_after - 1.0,
        "last frame at {last_t} s, killed at {killed_after} s"
    );
    for (i, frame) in session.frames.iter().enumerate() {
        assert!((frame.t - i as f64 / rate).abs() < 1e-9, "frame {i} at {}", frame.t);
        assert_eq!(frame.q.len(), 7);
    }
}

#[test]
fn estimate_reads_a_recorded_session() {
    let path = scratch("demo.session.json");
    let status = Command::new(env!("CARGO_BIN_EXE_proprioscope"))
        .args(["record-demo", "--rate", "20", "--seconds", "0.5", "--out"])
        .arg(&path)
        .stdout(Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    let out = scratch("demo.jsonl");
    let output = Command::new(env!("CARGO_BIN_EXE_proprioscope"))
        .arg("estimate")
        .arg(&path)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let lines = std::fs::read_to_string(&out).unwrap();
    let frames: Vec<serde_json::Value> = lines.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(frames.len(), 11);
    // The demo pushes link 5 with 12 N: most frames find it there, and the
    // recorded truth gives the errors.
    let on_link_5 = frames.iter().filter(|f| f["link"] == "lwr_5_link").count();
    assert!(on_link_5 >= 6, "{on_link_5} of 11 frames on lwr_5_link");
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(stdout.contains("median pos. error"), "{stdout}");
}

/// A session of `seconds` at 1 kHz drawn by `synth`.
fn synth_session(name: &str, seconds: &str) -> PathBuf {
    let path = scratch(name);
    let status = Command::new(env!("CARGO_BIN_EXE_proprioscope"))
        .arg("synth")
        .arg(&path)
        .args(["--seconds", seconds, "--rate", "1000", "--seed", "4"])
        .stdout(Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    path
}

/// `load_session` on `path`, with the previews it gave.
fn load_with_previews(path: &std::path::Path) -> (proprioscope::batch::Loaded, Vec<proprioscope::batch::Loaded>) {
    let previews = std::sync::Mutex::new(Vec::new());
    let loaded = proprioscope::batch::load_session(
        path,
        None,
        &[],
        &proprioscope::io::recording::TopicChoice::default(),
        &|_| {},
        &|p| previews.lock().unwrap().push(p),
    )
    .unwrap();
    (loaded, previews.into_inner().unwrap())
}

#[test]
fn a_long_session_gives_its_first_frames_while_the_rest_is_read() {
    let path = synth_session("long.session.json", "8");
    assert!(std::fs::metadata(&path).unwrap().len() > 2 * proprioscope::batch::PREVIEW_BYTES as u64);
    let ((whole, robot, spec), previews) = load_with_previews(&path);
    let [(first, first_robot, first_spec)] = previews.as_slice() else {
        panic!("{} previews", previews.len());
    };
    // The frames that fit in the bytes read, the same as the whole read's.
    assert!(first.frames.len() > 1000, "{}", first.frames.len());
    assert!(first.frames.len() < whole.frames.len() / 2);
    assert_eq!(first.frames[..], whole.frames[..first.frames.len()]);
    assert_eq!(first.file_frames[..], whole.file_frames[..first.frames.len()]);
    assert_eq!((first_robot, first_spec), (&robot, &spec));
    // A short session is read whole at once.
    let short = synth_session("short.session.json", "1");
    assert!(std::fs::metadata(&short).unwrap().len() < proprioscope::batch::PREVIEW_BYTES as u64);
    let ((whole, _, _), previews) = load_with_previews(&short);
    assert!(previews.is_empty());
    assert_eq!(whole.frames.len(), 1000);
}
