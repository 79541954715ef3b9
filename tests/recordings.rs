//! Robot recordings (ROS 2 MCAP, ROS 1 bags) read as sessions: every file
//! of `../shared/recordings` gives back the JSON session it was written
//! from (q and τ to 1e-9, the same truth), and the same estimates.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use proprioscope::io::recording::{self, Mapping, StampSource, TopicChoice};
use proprioscope::io::session::{Session, Truth};

fn shared() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared")
}

const LAYOUTS: [(&str, &str, &str, &str); 4] = [
    ("plain.mcap", "/joint_states", "/joint_states", "effort"),
    (
        "franka.mcap",
        "/joint_states",
        "/franka_robot_state_broadcaster/external_joint_torques",
        "effort",
    ),
    ("kuka.mcap", "/joint_states", "/lbr/state", "external_torque"),
    ("plain.bag", "/joint_states", "/joint_states", "effort"),
];

fn compare(recording: &Path, session: &Path, expected: &Mapping) {
    let bytes = recording::read_bytes(recording).unwrap();
    let read = recording::read_session(recording, &bytes, &TopicChoice::default(), &|_| {}).unwrap();
    assert_eq!(&read.mapping, expected, "{}", recording.display());
    assert!(read.problems.is_empty(), "{:?}", read.problems);
    assert!(read.notes.is_empty(), "{:?}", read.notes);
    assert!(
        matches!(read.stamps, StampSource::Fields { .. }),
        "{}: {}",
        recording.display(),
        read.stamps
    );
    let json = Session::read(session).unwrap();
    let got = read.session;
    assert_eq!(got.frames.len(), json.frames.len(), "{}", recording.display());
    // The recording's joint order may differ from the session's: compare by name.
    let got_names = got.joints.clone().unwrap();
    let json_names = json.joints.clone().unwrap();
    let slot: Vec<usize> = json_names
        .iter()
        .map(|n| got_names.iter().position(|g| g == n).unwrap())
        .collect();
    for (k, (a, b)) in got.frames.iter().zip(&json.frames).enumerate() {
        let what = format!("{} frame {k}", recording.display());
        assert!((a.t - b.t).abs() < 1e-9, "{what}: t {} vs {}", a.t, b.t);
        for (j, &s) in slot.iter().enumerate() {
            assert!(
                (a.q[s] - b.q[j]).abs() < 1e-9,
                "{what}: q[{j}] {} vs {}",
                a.q[s],
                b.q[j]
            );
            assert!(
                (a.tau[s] - b.tau[j]).abs() < 1e-9,
                "{what}: tau[{j}] {} vs {}",
                a.tau[s],
                b.tau[j]
            );
        }
        match (&a.truth, &b.truth) {
            (Truth::NoContact, Truth::NoContact) => {}
            (
                Truth::Contact { link, point, force },
                Truth::Contact {
                    link: l,
                    point: p,
                    force: f,
                },
            ) => {
                assert_eq!(link, l, "{what}");
                for i in 0..3 {
                    assert!(
                        (point[i] - p[i]).abs() < 1e-12 && (force[i] - f[i]).abs() < 1e-9,
                        "{what}"
                    );
                }
            }
            other => panic!("{what}: truth {other:?}"),
        }
    }
}

#[test]
#[ignore = "needs ../shared"]
fn every_recording_gives_back_its_session() {
    for session in ["lwr4plus_static_example", "lwr4plus_dyn_example_link4"] {
        let json = shared().join("sessions").join(format!("{session}.session.json"));
        for (suffix, q, tau, field) in LAYOUTS {
            let path = shared().join("recordings").join(format!("{session}_{suffix}"));
            let expected = Mapping {
                q_topic: q.to_owned(),
                tau_topic: tau.to_owned(),
                tau_field: field.to_owned(),
            };
            compare(&path, &json, &expected);
        }
    }
}

#[test]
#[ignore = "needs ../shared"]
fn topics_are_listed_with_types_counts_and_rates() {
    let path = shared().join("recordings/lwr4plus_dyn_example_link4_franka.mcap");
    let bytes = recording::read_bytes(&path).unwrap();
    let index = recording::index(&path, &bytes).unwrap();
    let listed: Vec<(&str, &str, usize)> = index
        .topics
        .iter()
        .map(|t| (t.topic.as_str(), t.message_type.as_str(), t.count))
        .collect();
    assert_eq!(
        listed,
        [
            ("/contact/truth", "geometry_msgs/WrenchStamped", 144),
            ("/contact/truth_point", "geometry_msgs/PointStamped", 144),
            (
                "/franka_robot_state_broadcaster/external_joint_torques",
                "sensor_msgs/JointState",
                300
            ),
            ("/joint_states", "sensor_msgs/JointState", 1496),
        ]
    );
    let rate = index.topics[3].rate_hz().unwrap();
    assert!((rate - 1000.0).abs() < 10.0, "{rate}");
    // The measured effort is refused when named, never taken by default.
    let measured = TopicChoice {
        tau_topic: Some("/joint_states".into()),
        ..TopicChoice::default()
    };
    assert_eq!(index.mapping(&measured).unwrap().tau_field, "effort");
    let wrong = TopicChoice {
        tau_topic: Some("/joint_states".into()),
        tau_field: Some("torque".into()),
        ..TopicChoice::default()
    };
    let message = index.mapping(&wrong).unwrap_err().to_string();
    assert!(
        message.contains("--tau-field") && message.contains("position, effort"),
        "{message}"
    );
}

/// A recording's start, read as such, gives its first frames as the whole
/// read does (the app's preview of a long recording).
#[test]
#[ignore = "needs ../shared"]
fn a_recording_cut_short_gives_its_first_frames() {
    for name in [
        "lwr4plus_dyn_example_link4_franka.mcap",
        "lwr4plus_dyn_example_link4_kuka.mcap",
        "lwr4plus_dyn_example_link4_plain.mcap",
    ] {
        let path = shared().join("recordings").join(name);
        let choice = TopicChoice::default();
        let (whole, _) = Session::open(&path, &choice, &|_| {}).unwrap();
        let len = usize::try_from(std::fs::metadata(&path).unwrap().len()).unwrap();
        let (start, _) = Session::open_start(&path, &choice, len / 2).unwrap();
        let n = start.frames.len();
        assert!(
            (whole.frames.len() / 4..whole.frames.len() * 3 / 4).contains(&n),
            "{name}: {n} of {}",
            whole.frames.len()
        );
        // The last frame's pair may lie beyond the cut.
        assert_eq!(start.frames[..n - 1], whole.frames[..n - 1], "{name}");
        assert_eq!(start.joints, whole.joints, "{name}");
        assert!(Session::open_start(&path, &choice, len).is_none(), "{name}");
    }
    // The bag's messages are in one chunk (92 % of the file, the index
    // after it): cut in it, no frame; cut after it, every frame. Read
    // whole, a bag cut short is an error.
    let bag = shared().join("recordings/lwr4plus_dyn_example_link4_plain.bag");
    let choice = TopicChoice::default();
    let (whole, _) = Session::open(&bag, &choice, &|_| {}).unwrap();
    let len = usize::try_from(std::fs::metadata(&bag).unwrap().len()).unwrap();
    assert!(Session::open_start(&bag, &choice, len / 2).is_none());
    let (start, _) = Session::open_start(&bag, &choice, len * 95 / 100).unwrap();
    assert_eq!(start.frames, whole.frames);
    let bytes = std::fs::read(&bag).unwrap();
    let cut = &bytes[..len * 95 / 100];
    assert!(recording::read_session(&bag, cut, &choice, &|_| {}).is_err());
    assert!(recording::read_session_start(&bag, cut, &choice).is_ok());
}
