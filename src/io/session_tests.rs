//! Tests of [`super`]: `session.rs`.

use super::*;

const JSON: &str = r#"{"format": "contact-session", "version": 1, "robot": "lwr4plus", "extra": 1,
      "frames": [
        {"t": 0.0, "q": [0, 0], "tau": [0.1, 0.2], "truth": {"link": "l", "point": [1, 2, 3], "force": [4, 5, 6]}},
        {"t": 0.5, "q": [0, 0], "tau": [0.0, 0.0], "truth": null},
        {"t": 1.0, "q": [0, 0], "tau": [0.0, 0.0]}
      ]}"#;

#[test]
fn json_truth_can_be_a_contact_null_or_absent() {
    let s = Session::parse_json(JSON, Path::new("s.json")).unwrap();
    s.check().unwrap();
    assert_eq!(s.frames.len(), 3);
    assert!(matches!(s.frames[0].truth, Truth::Contact { .. }));
    assert_eq!(s.frames[1].truth, Truth::NoContact);
    assert_eq!(s.frames[2].truth, Truth::Unknown);
}

#[test]
fn json_truth_all_lists_every_contact() {
    let text = r#"{"format": "contact-session", "version": 1, "robot": "r", "frames": [
        {"t": 0.0, "q": [0], "tau": [0.1], "truth": {"link": "a", "point": [1, 2, 3], "force": [4, 5, 6]},
         "truth_all": [{"probe": 1, "link": "a", "point": [1, 2, 3], "force": [4, 5, 6]},
                       {"probe": 2, "link": "b", "point": [0, 0, 1], "force": [0, -1, 0]}]},
        {"t": 0.5, "q": [0], "tau": [0.0], "truth": null, "truth_all": []},
        {"t": 1.0, "q": [0], "tau": [0.0], "truth": {"link": "a", "point": [1, 2, 3], "force": [4, 5, 6]}}
      ]}"#;
    let s = Session::parse_json(text, Path::new("s.json")).unwrap();
    let links = |f: &Frame| f.true_contacts().into_iter().map(|c| c.link).collect::<Vec<_>>();
    assert_eq!(links(&s.frames[0]), ["a", "b"]);
    assert_eq!(
        s.frames[0].truth_all[1].force.map(f64::to_bits),
        [0.0, -1.0, 0.0].map(f64::to_bits)
    );
    assert!(links(&s.frames[1]).is_empty());
    // Without `truth_all`, `truth` is the only contact known.
    assert_eq!(links(&s.frames[2]), ["a"]);
    assert!(s.frames[2].truth_all.is_empty());
    // Written back, read again: the same.
    let again = Session::parse_json(
        &serde_json::json!({"format": "contact-session", "version": 1, "robot": "r",
            "frames": s.frames.iter().map(Frame::to_json).collect::<Vec<_>>()})
        .to_string(),
        Path::new("t.json"),
    )
    .unwrap();
    assert_eq!(again.frames, s.frames);
}

/// A truth far beyond any arm made the errors against it overflow
/// (`estimate` printed inf).
#[test]
fn truths_beyond_reason_are_bad_frames() {
    let text = JSON.replace("[1, 2, 3]", "[1e300, 2, 3]");
    let e = Session::parse_json(&text, Path::new("s.json"))
        .unwrap()
        .check()
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("frame 0") && e.contains("truth") && e.contains("beyond"),
        "{e}"
    );
}

#[test]
fn csv_reads_the_same_frames() {
    let csv = "t,q1,q2,tau1,tau2,link,px,py,pz,fx,fy,fz\n0.0,0,0,0.1,0.2,l,1,2,3,4,5,6\n0.5,0,0,0,0,,,,,,,\n";
    let s = Session::parse_csv(csv, Path::new("s.csv")).unwrap();
    let j = Session::parse_json(JSON, Path::new("s.json")).unwrap();
    assert_eq!(s.frames[..2], j.frames[..2]);
}

/// A CSV with a second contact's columns: both contacts in `truth_all`
/// where `link2` is given, the first alone where it is empty; a row too
/// short for its truth has none known.
#[test]
#[allow(clippy::float_cmp)] // Numbers read from text, compared as written.
fn csv_reads_a_second_contact_into_truth_all() {
    let header = "t,q1,q2,tau1,tau2,link,px,py,pz,fx,fy,fz,link2,px2,py2,pz2,fx2,fy2,fz2";
    let csv = format!(
        "{header}\n0.0,0,0,0.1,0.2,a,1,2,3,4,5,6,b,7,8,9,10,11,12\n0.1,0,0,0.1,0.2,a,1,2,3,4,5,6,,,,,,,\n0.2,0,0,0,0,,,,,,,,,,,,,,\n0.3,0,0,0.5,0.5\n"
    );
    let s = Session::parse_csv(&csv, Path::new("s.csv")).unwrap();
    let links = |f: &Frame| f.true_contacts().into_iter().map(|c| c.link).collect::<Vec<_>>();
    assert_eq!(links(&s.frames[0]), ["a", "b"]);
    assert_eq!(s.frames[0].truth_all[1].point, [7.0, 8.0, 9.0]);
    assert_eq!(s.frames[0].truth_all[1].force, [10.0, 11.0, 12.0]);
    assert_eq!(links(&s.frames[1]), ["a"]);
    assert!(s.frames[1].truth_all.is_empty());
    assert_eq!(s.frames[2].truth, Truth::NoContact);
    assert_eq!(s.frames[3].truth, Truth::Unknown);
    // A second contact's columns named otherwise are refused with the form.
    let bad = csv.replace("link2", "other");
    let e = Session::parse_csv(&bad, Path::new("s.csv")).unwrap_err().to_string();
    assert!(e.contains("link2,px2"), "{e}");
}

#[test]
fn bad_frames_are_named() {
    let text = JSON.replace(r#""t": 0.5"#, r#""t": -0.5"#);
    let e = Session::parse_json(&text, Path::new("s.json"))
        .unwrap()
        .check()
        .unwrap_err()
        .to_string();
    assert!(e.contains("frame 1") && e.contains("backwards"), "{e}");
    let text = JSON.replace(r#""tau": [0.0, 0.0], "truth": null"#, r#""tau": [0.0], "truth": null"#);
    let e = Session::parse_json(&text, Path::new("s.json"))
        .unwrap()
        .check()
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("frame 1") && e.contains("tau") && e.contains("expected 2"),
        "{e}"
    );
    let csv = "t,q1,q2,tau1,tau2\n0.0,0,0,0.1,nan\n";
    let e = Session::parse_csv(csv, Path::new("s.csv"))
        .unwrap()
        .check()
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("frame 0") && e.contains("tau[1]") && e.contains("NaN"),
        "{e}"
    );
    let e = Session::parse_csv("t,q1,tau2\n", Path::new("h.csv"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("h.csv:1") && e.contains("header"), "{e}");
}

fn scripted_frames() -> Vec<Frame> {
    (0..40)
        .map(|i| {
            let x = f64::from(i);
            Frame {
                t: 0.1 * x,
                q: vec![0.1 * x.sin(), -0.3 + 1e-3 * x, std::f64::consts::PI / 3.0],
                tau: vec![0.123_456_789 * x, -2.0 / 3.0, 1e-17 * x],
                truth: match i % 3 {
                    0 => Truth::Unknown,
                    1 => Truth::NoContact,
                    _ => Truth::Contact {
                        link: "link_2".to_owned(),
                        point: [0.1, -0.2 * x, 1.0 / 7.0],
                        force: [3.0, 0.0, -x],
                    },
                },
                // Every sixth frame has two contacts, listed in `truth_all`.
                truth_all: if i % 6 == 5 {
                    vec![
                        ContactTruth {
                            link: "link_2".to_owned(),
                            point: [0.1, -0.2 * x, 1.0 / 7.0],
                            force: [3.0, 0.0, -x],
                        },
                        ContactTruth {
                            link: "link_1".to_owned(),
                            point: [0.0, 0.3, x],
                            force: [-1.0, 2.0, 0.5],
                        },
                    ]
                } else {
                    Vec::new()
                },
            }
        })
        .collect()
}

#[test]
fn recorded_frames_read_back_identical() {
    let dir = std::env::temp_dir().join(format!("proprioscope-rec-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("round-trip.json");
    let joints = vec!["a".to_owned(), "b".to_owned(), "c".to_owned()];
    let mut recorder = Recorder::create(&path, "simple6", &joints).unwrap();
    let frames = scripted_frames();
    for f in &frames {
        recorder.write(f).unwrap();
    }
    assert_eq!(recorder.finish().unwrap(), frames.len());
    let back = Session::read(&path).unwrap();
    assert_eq!(back.frames, frames);
    // Loading reports its progress, rising to 1.
    let seen = std::sync::Mutex::new(Vec::new());
    let (again, problems) =
        Session::read_skipping_bad_frames_with_progress(&path, &|f| seen.lock().unwrap().push(f)).unwrap();
    assert_eq!((again.frames, problems.len()), (frames, 0));
    let seen = seen.into_inner().unwrap();
    assert!(
        seen.windows(2).all(|w| w[0] <= w[1]) && seen.last() == Some(&1.0),
        "{seen:?}"
    );
    assert_eq!(back.robot.as_deref(), Some("simple6"));
    assert_eq!(back.joints.as_ref(), Some(&joints));
}

#[test]
fn a_recording_cut_short_reads_up_to_its_last_whole_frame() {
    let dir = std::env::temp_dir().join(format!("proprioscope-cut-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("cut.json");
    let joints = ["a", "b", "c"].map(str::to_owned);
    let mut recorder = Recorder::create(&path, "simple6", &joints).unwrap();
    let frames = scripted_frames();
    for f in &frames[..10] {
        recorder.write(f).unwrap();
    }
    drop(recorder);
    // Half of an eleventh frame, as a kill mid-write would leave it.
    let mut text = std::fs::read_to_string(&path).unwrap();
    text.push_str(",{\"t\":1.0,\"q\":[0.0,");
    std::fs::write(&path, &text).unwrap();
    assert!(Session::read(&path).is_err());
    let (back, problems) = Session::read_skipping_bad_frames(&path).unwrap();
    assert_eq!(back.frames, frames[..10]);
    assert!(problems.is_empty());
}

#[test]
fn bad_frames_are_skipped_and_reported() {
    let text = r#"{"format": "contact-session", "version": 1, "robot": "lwr4plus",
          "frames": [
            {"t": 0.0, "q": [0, 0], "tau": [0.1, 0.2]},
            {"t": 0.1, "q": [0, 0], "tau": [0.1, null]},
            {"t": 0.2, "q": [0, 0], "tau": [0.1, 0.2, 0.3]},
            {"t": 0.3, "q": [0, 0], "tau": [0.1, 0.2]},
            {"t": 0.25, "q": [0, 0], "tau": [0.1, 0.2]},
            {"t": 0.4, "q": [0], "tau": [0.1, 0.2]},
            {"q": [0, 0], "tau": [0.1, 0.2]},
            {"t": 0.5, "q": [0, 0], "tau": [0.1, 0.2]}
          ]}"#;
    let mut s = Session::parse_json(text, Path::new("s.json")).unwrap();
    let problems = s.remove_bad_frames();
    let named: Vec<(usize, &str)> = problems.iter().map(|p| (p.frame, p.field.as_str())).collect();
    assert_eq!(named, [(1, "tau[1]"), (2, "tau"), (4, "t"), (5, "q"), (6, "t")]);
    assert!(problems[1].message.contains("3 values, expected 2"), "{}", problems[1]);
    assert!(problems[2].message.contains("backwards"), "{}", problems[2]);
    let times: Vec<f64> = s.frames.iter().map(|f| f.t).collect();
    assert_eq!(times, [0.0, 0.3, 0.5]);
    // The same in CSV: a word, a missing and an extra value.
    let csv = "t,q1,q2,tau1,tau2\n0.0,0,0,0.1,0.2\n0.1,0,0,0.1,x\n0.2,0,0,0.1\n0.3,0,0,0.1,0.2,0.3\n0.4,0,0,0,0\n";
    let mut s = Session::parse_csv(csv, Path::new("s.csv")).unwrap();
    let problems = s.remove_bad_frames();
    let named: Vec<(usize, &str)> = problems.iter().map(|p| (p.frame, p.field.as_str())).collect();
    assert_eq!(named, [(1, "tau[1]"), (2, "tau"), (3, "tau")]);
    assert_eq!(s.frames.len(), 2);
}

#[test]
fn live_lines_are_read_one_by_one_and_bad_ones_reported() {
    let mut r = LiveReader::new(None);
    assert!(matches!(
        r.line(r#"{"format": "contact-session", "version": 1, "robot": "lwr4plus", "joints": ["a", "b"]}"#),
        LiveLine::Header { robot: Some(_), .. }
    ));
    assert!(matches!(
        r.line(r#"{"t": 0.0, "q": [0, 1], "tau": [0.1, 0.2]}"#),
        LiveLine::Frame(_)
    ));
    // Too few values, time backwards, not JSON, NaN: reported by line and field.
    let LiveLine::Bad(p) = r.line(r#"{"t": 0.1, "q": [0], "tau": [0.1, 0.2]}"#) else {
        panic!("short q accepted")
    };
    assert_eq!((p.frame, p.field.as_str()), (2, "q"));
    assert!(matches!(
        r.line(r#"{"t": -1.0, "q": [0, 1], "tau": [0, 0]}"#),
        LiveLine::Bad(_)
    ));
    assert!(matches!(r.line("{\"t\": 0.2, \"q\": [0, 1"), LiveLine::Bad(_)));
    assert!(matches!(
        r.line(r#"{"t": 0.2, "q": [0, null], "tau": [0, 0]}"#),
        LiveLine::Bad(_)
    ));
    assert!(matches!(
        r.line(r#"{"t": 0.3, "q": [0, 1], "tau": [0, 0], "truth": null}"#),
        LiveLine::Frame(_)
    ));
    // A new connection may start its clock again.
    r.restart();
    assert!(matches!(
        r.line(r#"{"t": 0.0, "q": [0, 1], "tau": [0, 0]}"#),
        LiveLine::Frame(_)
    ));
}

/// The frames split out and parsed in parallel read every text as the
/// whole parse does: a good session, a frame that is not a frame, and a
/// frame whose wrong value comes before its syntax error (found by the
/// fuzz target `session_json`: the frame's own parse stopped at the value
/// and took it for a bad frame, where the whole text is not JSON).
#[test]
fn frames_split_out_read_as_the_whole_text() {
    let path = Path::new("s.json");
    let head = r#"{"format":"contact-session","version":1,"robot":"lwr4plus","frames":["#;
    for frames in [
        r#"{"t":0,"q":[1],"tau":[2]},{"t":1,"q":[1],"tau":[2],"truth":null}"#,
        r#"{"t":0,"q":[1],"tau":[2]},"not a frame",{"t":1,"q":[1],"tau":[2]}"#,
        r#"{"t":0,"q":[1],"tau":[2],"truth":{"link":"a","point":1,-2]}}"#,
        r#"{"t":0,"q":[1],"tau":[2]} {"t":1}"#,
    ] {
        let text = format!("{head}{frames}]}}");
        let split = Session::parse_json(&text, path);
        let whole = Session::parse_json_whole(&text, path);
        assert_eq!(format!("{split:?}"), format!("{whole:?}"), "{frames}");
    }
    let bad = format!(
        "{head}{}]}}",
        r#"{"t":0,"q":[1],"tau":[2],"truth":{"link":"a","point":1,-2]}}"#
    );
    let Err(SessionError::Parse { line: 1, message, .. }) = Session::parse_json(&bad, path) else {
        panic!("a text that is not JSON read");
    };
    assert!(message.contains("key must be a string"), "{message}");
}

/// A session's text cut at every place gives its first frames: none
/// before the first frame ends, then one more with each frame's end.
#[test]
fn a_text_cut_anywhere_gives_the_first_frames() {
    let path = Path::new("s.json");
    let whole = Session::parse_json(JSON, path).unwrap();
    let mut seen = Vec::new();
    for cut in (0..=JSON.len()).filter(|&c| JSON.is_char_boundary(c)) {
        let Some(start) = Session::parse_json_start(&JSON[..cut], path) else {
            assert!(
                seen.is_empty() || cut == JSON.len(),
                "cut at {cut}: nothing after {seen:?}"
            );
            continue;
        };
        let n = start.frames.len();
        assert_eq!(start.frames[..], whole.frames[..n], "cut at {cut}");
        assert_eq!(start.robot, whole.robot);
        if seen.last() != Some(&n) {
            seen.push(n);
        }
    }
    assert_eq!(seen, vec![1, 2, 3]);
}
