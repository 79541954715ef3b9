//! What Foxglove is given: `estimate --out est.mcap` read back (every
//! frame's transforms, the arm, the URDF, the heatmap, the arrows and the
//! numbers), and the live WebSocket server answering a client on loopback.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use crate::common;

use std::collections::{BTreeMap, BTreeSet};
use std::net::TcpStream;
use std::time::{Duration, Instant};

use foxglove::Decode as _;
use foxglove::messages::{FrameTransforms, SceneUpdate};
use proprioscope::io::builtin::load_robot;
use proprioscope::io::foxglove::serve::FoxgloveServer;
use proprioscope::io::foxglove::{ArmScene, FoxgloveFrame, FrameNumbers, TRANSFORMS_TOPIC, frame_messages, opening};
use proprioscope::io::urdf::{UrdfOptions, read_urdf};

/// A MCAP's messages: per topic, (log time, bytes), in file order.
type Topics = BTreeMap<String, Vec<(u64, Vec<u8>)>>;

/// The messages of an MCAP file's bytes.
fn messages_by_topic(bytes: &[u8]) -> Topics {
    let mut out: Topics = BTreeMap::new();
    for message in mcap::MessageStream::new(bytes).unwrap() {
        let message = message.unwrap();
        out.entry(message.channel.topic.clone())
            .or_default()
            .push((message.log_time, message.data.into_owned()));
    }
    out
}

/// A synthetic session of presses on link 4, 1.5 s at 200 Hz, in its own
/// folder `name`, estimated to `est.mcap` there with `extra` options: the
/// folder, the MCAP and the frames' count.
fn synth_and_estimate(name: &str, extra: &[&str]) -> (std::path::PathBuf, std::path::PathBuf, usize) {
    let dir = std::env::temp_dir().join(format!("proprioscope-foxglove-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (session, out) = (dir.join("s.json"), dir.join("est.mcap"));
    let (s, p) = (session.to_str().unwrap(), out.to_str().unwrap());
    let synth = [
        "synth",
        s,
        "--seconds",
        "1.5",
        "--rate",
        "200",
        "--seed",
        "2",
        "--links",
        "lwr_4_link",
    ];
    let (ok, _, err) = common::run_out(&synth);
    assert!(ok, "{err}");
    let mut args = vec!["estimate", s, "--out", p];
    args.extend(extra);
    let (ok, _, err) = common::run_out(&args);
    assert!(ok, "{err}");
    let frames = std::fs::read_to_string(&session).unwrap().matches("\"tau\"").count();
    (dir, out, frames)
}

/// [`synth_and_estimate`]'s MCAP, its messages by topic, and the frames' count.
fn estimated(name: &str, extra: &[&str]) -> (Topics, usize) {
    let (dir, out, frames) = synth_and_estimate(name, extra);
    let bytes = std::fs::read(&out).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    (messages_by_topic(&bytes), frames)
}

#[test]
fn every_frame_moves_every_link_and_the_arm_is_there_once() {
    let (topics, frames) = estimated("tf", &["--tf-hz", "0"]);
    let robot = load_robot("lwr4plus", std::path::Path::new("."), &UrdfOptions::default()).unwrap();
    let children: BTreeSet<&str> = robot
        .links
        .iter()
        .enumerate()
        .filter(|(k, _)| *k != robot.root)
        .map(|(_, l)| l.name.as_str())
        .collect();
    let states: Vec<u64> = topics["/joint_states"].iter().map(|(t, _)| *t).collect();
    let transforms = &topics[TRANSFORMS_TOPIC];
    assert_eq!(states.len(), frames);
    assert_eq!(transforms.len(), frames, "a transform message a frame");
    for ((t, data), state_t) in transforms.iter().zip(&states) {
        assert_eq!(t, state_t, "at the frame's time");
        let tf = FrameTransforms::decode(data.as_slice()).unwrap();
        let got: BTreeSet<&str> = tf.transforms.iter().map(|t| t.child_frame_id.as_str()).collect();
        assert_eq!(got, children, "every link at {t}");
    }
    // The arm once, a link a mesh, each following its frame.
    let arm = &topics["/proprioscope/arm"];
    assert_eq!(arm.len(), 1);
    let arm = SceneUpdate::decode(arm[0].1.as_slice()).unwrap();
    let with_mesh = robot.links.iter().filter(|l| !l.mesh.triangles.is_empty()).count();
    assert_eq!(arm.entities.len(), with_mesh);
    assert!(arm.entities.iter().all(
        |e| e.frame_locked && children.contains(e.frame_id.as_str()) || e.frame_id == robot.links[robot.root].name
    ));
    // The URDF reads back as the robot's joints.
    let description = &topics["/robot_description"];
    let data = &description[0].1;
    let length = u32::from_le_bytes(data[4..8].try_into().unwrap()) as usize;
    let text = std::str::from_utf8(&data[8..8 + length - 1]).unwrap();
    let back = read_urdf(text, std::path::Path::new("robot_description"), &UrdfOptions::default()).unwrap();
    assert_eq!(back.joints.len(), robot.joints.len());
}

#[test]
fn the_file_alone_draws_the_arm_with_its_heat_and_arrows() {
    let (dir, out, _) = synth_and_estimate("preview", &[]);
    let (o, png) = (out.to_str().unwrap(), dir.join("p.png"));
    let bytes = std::fs::read(&out).unwrap();
    // Some time with heat and arrows: the last heatmap that paints.
    let heat_times: Vec<u64> = messages_by_topic(&bytes)["/proprioscope/heatmap"]
        .iter()
        .filter(|(_, d)| !SceneUpdate::decode(d.as_slice()).unwrap().entities.is_empty())
        .map(|(t, _)| *t)
        .collect();
    let first = mcap::MessageStream::new(&bytes)
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .log_time;
    let at = (heat_times.last().unwrap() - first) as f64 * 1e-9;
    let scene = proprioscope::app::mcap_preview::McapScene::read(&bytes, at).unwrap();
    let robot = load_robot("lwr4plus", std::path::Path::new("."), &UrdfOptions::default()).unwrap();
    let arm_triangles: usize = robot.links.iter().map(|l| l.mesh.triangles.len()).sum();
    let (triangles, lines) = scene.counts();
    assert!(
        triangles > arm_triangles,
        "the arm and its heat: {triangles} of {arm_triangles}"
    );
    assert!(lines > 0);
    assert!(scene.caption().contains("8 link meshes"), "{}", scene.caption());
    let (ok, _, err) = common::run_out(&[
        "preview-mcap",
        o,
        "--at",
        &at.to_string(),
        "--out",
        png.to_str().unwrap(),
        "--width",
        "320",
        "--height",
        "240",
    ]);
    assert!(ok, "{err}");
    assert!(png.is_file());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_heatmap_arrows_and_numbers_follow_the_estimate() {
    let (topics, frames) = estimated("scene", &[]);
    // 200 Hz frames, transforms at most 100 a second: every other frame.
    let transforms = topics[TRANSFORMS_TOPIC].len();
    assert!(
        (frames / 2..=frames / 2 + 1).contains(&transforms),
        "{transforms} of {frames}"
    );
    // The numbers every frame, the verdict one of three.
    let numbers = &topics["/proprioscope/numbers"];
    assert_eq!(numbers.len(), frames);
    let verdicts: Vec<u8> = numbers.iter().map(|(_, d)| d[20]).collect();
    assert!(verdicts.iter().all(|v| *v <= 2) && verdicts.contains(&1) && verdicts.contains(&0));
    // Heatmaps: painted where a contact is called, in 8-bit colours, at
    // most 15 a second plus the changes of verdict.
    let heat = &topics["/proprioscope/heatmap"];
    let changes = verdicts.windows(2).filter(|w| (w[0] == 0) != (w[1] == 0)).count();
    assert!(heat.len() <= frames * 15 / 200 + changes + 1, "{} heatmaps", heat.len());
    let mut painted = 0;
    for (_, data) in heat {
        let update = SceneUpdate::decode(data.as_slice()).unwrap();
        assert_eq!(update.deletions.len(), 1, "each heatmap replaces the last");
        for entity in &update.entities {
            let t = &entity.triangles[0];
            assert_eq!(t.points.len(), t.colors.len());
            assert!(t.indices.iter().all(|&i| (i as usize) < t.points.len()));
            for c in &t.colors {
                for x in [c.r, c.g, c.b] {
                    assert!(
                        ((x * 255.0) as f32 - (x * 255.0).round() as f32).abs() < 1e-3,
                        "{x} is not 8-bit"
                    );
                }
            }
            painted += t.points.len();
        }
    }
    assert!(painted > 0, "some heat is painted");
    // Arrows: the true contact's (magenta) wherever one presses, and the
    // estimate's at the place `/proprioscope/contact_point` gives.
    let arrows = &topics["/proprioscope/arrows"];
    assert!(!arrows.is_empty());
    let roles: BTreeSet<String> = arrows
        .iter()
        .flat_map(|(_, d)| SceneUpdate::decode(d.as_slice()).unwrap().entities)
        .flat_map(|e| e.metadata.into_iter().map(|kv| kv.value))
        .collect();
    assert!(
        roles.contains("true contact") && roles.contains("over time"),
        "{roles:?}"
    );
}

/// The bytes of one WebSocket message, waiting at most `within`.
fn next_message(socket: &mut tungstenite::WebSocket<TcpStream>, within: Duration) -> Option<tungstenite::Message> {
    let deadline = Instant::now() + within;
    while Instant::now() < deadline {
        match socket.read() {
            Ok(m) => return Some(m),
            Err(tungstenite::Error::Io(e))
                if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {}
            // The server went away: the caller's own check says what is missing.
            Err(tungstenite::Error::ConnectionClosed | tungstenite::Error::AlreadyClosed) => return None,
            Err(e) => panic!("{e}"),
        }
    }
    None
}

#[test]
fn a_client_on_loopback_subscribes_and_receives_the_arm_s_transforms() {
    let robot = load_robot("lwr4plus", std::path::Path::new("."), &UrdfOptions::default()).unwrap();
    let scene = ArmScene::new(&robot);
    let mut server = FoxgloveServer::start("127.0.0.1:0", "test").unwrap();
    server.set_opening(opening(&scene, 0)).unwrap();
    let address = server.address();

    let stream = TcpStream::connect(address).unwrap();
    stream.set_read_timeout(Some(Duration::from_millis(100))).unwrap();
    let mut request = tungstenite::client::IntoClientRequest::into_client_request(format!("ws://{address}")).unwrap();
    request
        .headers_mut()
        .insert("Sec-WebSocket-Protocol", "foxglove.sdk.v1".parse().unwrap());
    let (mut socket, _) = tungstenite::client(request, stream).unwrap();

    // The server says who it is and what it has; publish until the
    // transforms' channel is advertised.
    let q = vec![0.1; robot.joints.len()];
    let frame = |k: i64| FoxgloveFrame {
        stamp_ns: 1_000_000 * k,
        joint_positions: Some(q.clone()),
        numbers: FrameNumbers {
            contact_probability: 0.5,
            force_newtons: 1.0,
            verdict: 1,
            position_error_m: f64::NAN,
            force_error_newtons: f64::NAN,
        },
        heat: None,
        arrows: None,
    };
    let mut channel = None;
    let mut k = 0;
    let deadline = Instant::now() + Duration::from_secs(20);
    while channel.is_none() && Instant::now() < deadline {
        server.publish(&frame_messages(&scene, &frame(k))).unwrap();
        k += 1;
        if let Some(tungstenite::Message::Text(text)) = next_message(&mut socket, Duration::from_millis(200)) {
            let json: serde_json::Value = serde_json::from_str(&text).unwrap();
            if json["op"] == "advertise" {
                channel = json["channels"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .find(|c| c["topic"] == TRANSFORMS_TOPIC)
                    .map(|c| c["id"].as_u64().unwrap());
            }
        }
    }
    let channel = channel.expect("the transforms' channel is advertised");
    let subscribe = serde_json::json!({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": channel}]});
    socket
        .send(tungstenite::Message::Text(subscribe.to_string().into()))
        .unwrap();

    // Frames published from now on arrive as message data on subscription 7.
    let mut received = 0;
    let deadline = Instant::now() + Duration::from_secs(20);
    while received < 3 && Instant::now() < deadline {
        server.publish(&frame_messages(&scene, &frame(k))).unwrap();
        k += 1;
        let message = next_message(&mut socket, Duration::from_millis(100));
        if let Some(tungstenite::Message::Text(text)) = &message
            && refused(text)
        {
            socket
                .send(tungstenite::Message::Text(subscribe.to_string().into()))
                .unwrap();
        }
        if let Some(tungstenite::Message::Binary(data)) = message {
            assert_eq!(data[0], 1, "message data");
            assert_eq!(u32::from_le_bytes(data[1..5].try_into().unwrap()), 7);
            let tf = FrameTransforms::decode(&data[13..]).unwrap();
            assert_eq!(tf.transforms.len(), robot.joints.len());
            received += 1;
        }
    }
    assert_eq!(received, 3, "three frames' transforms received");
    assert_eq!(server.clients(), 1);
}

/// A subscription to a channel the server has not advertised is refused
/// with the status that [`refused`] reads (the tests that subscribe send
/// theirs again on it).
#[test]
fn a_subscription_to_an_unknown_channel_is_refused_with_a_status() {
    let server = FoxgloveServer::start("127.0.0.1:0", "test").unwrap();
    let mut socket = foxglove_client(&server.address().to_string());
    let subscribe = serde_json::json!({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": 9999}]});
    socket
        .send(tungstenite::Message::Text(subscribe.to_string().into()))
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut texts = Vec::new();
    while Instant::now() < deadline {
        if let Some(tungstenite::Message::Text(text)) = next_message(&mut socket, Duration::from_millis(100)) {
            if refused(&text) {
                return;
            }
            texts.push(text.to_string());
        }
    }
    panic!("no refusal among {texts:?}");
}

/// Whether a text message from the server refuses a subscription to a
/// channel it does not know. The server sends a channel's advertisement
/// before it records the channel as advertised to the client, so a
/// subscription that arrives in between is refused: a client sends it
/// again.
fn refused(text: &str) -> bool {
    let json: serde_json::Value = serde_json::from_str(text).unwrap();
    json["op"] == "status"
        && json["message"]
            .as_str()
            .is_some_and(|m| m.starts_with("Unknown channel"))
}

/// A WebSocket client of the Foxglove server at `address` (retried while
/// it starts).
fn foxglove_client(address: &str) -> tungstenite::WebSocket<TcpStream> {
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        if let Ok(stream) = TcpStream::connect(address) {
            stream.set_read_timeout(Some(Duration::from_millis(50))).unwrap();
            let mut request =
                tungstenite::client::IntoClientRequest::into_client_request(format!("ws://{address}")).unwrap();
            request
                .headers_mut()
                .insert("Sec-WebSocket-Protocol", "foxglove.sdk.v1".parse().unwrap());
            return tungstenite::client(request, stream).unwrap().0;
        }
        assert!(Instant::now() < deadline, "no Foxglove server on {address}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// `estimate --live … --serve`: a viewer subscribed to the numbers gets
/// each frame's as the frames arrive.
#[test]
fn a_live_estimate_is_served_to_a_foxglove_client() {
    use std::io::Write as _;
    let frames = 400;
    let out = std::env::temp_dir().join(format!("proprioscope-served-{}.jsonl", std::process::id()));
    let child = common::spawn_live(
        "127.0.0.1:0",
        true,
        &[
            "--live-frames",
            &frames.to_string(),
            "--points",
            "1000",
            "--sigma",
            "0.01",
            "--temporal",
            "none",
            "--out",
            out.to_str().unwrap(),
        ],
    );
    let (live, serve) = (child.live.clone(), child.serve.clone().unwrap());
    let mut socket = foxglove_client(&serve);
    let mut sender = (0..200)
        .find_map(|_| {
            TcpStream::connect(&live).ok().or_else(|| {
                std::thread::sleep(Duration::from_millis(25));
                None
            })
        })
        .unwrap();
    writeln!(
        sender,
        r#"{{"format": "contact-session", "version": 1, "robot": "lwr4plus"}}"#
    )
    .unwrap();
    let frame = |k: usize| {
        format!(
            r#"{{"t": {}, "q": [0, 0, 0, 0, 0, 0, 0], "tau": [0.09516, -0.53783, 0.09516, 0.01017, 0, 0, 0]}}"#,
            0.01 * k as f64
        )
    };
    let (mut sent, mut received) = (0, 0);
    // The numbers' channel once advertised, and subscriptions sent to it
    // since the last refusal.
    let (mut numbers_channel, mut subscriptions) = (None::<serde_json::Value>, 0);
    while sent < frames {
        if writeln!(sender, "{}", frame(sent)).is_err() {
            break; // the estimate ended: its stderr says why
        }
        sent += 1;
        while let Some(message) = next_message(&mut socket, Duration::from_millis(20)) {
            match message {
                tungstenite::Message::Text(text) => {
                    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
                    let numbers = json["channels"]
                        .as_array()
                        .and_then(|c| c.iter().find(|c| c["topic"] == "/proprioscope/numbers"));
                    if let Some(channel) = numbers.filter(|_| numbers_channel.is_none()) {
                        numbers_channel = Some(channel["id"].clone());
                    } else if refused(&text) {
                        subscriptions = 0;
                    }
                    if let Some(channel) = numbers_channel.as_ref().filter(|_| subscriptions == 0) {
                        let subscribe =
                            serde_json::json!({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": channel}]});
                        socket
                            .send(tungstenite::Message::Text(subscribe.to_string().into()))
                            .unwrap();
                        subscriptions += 1;
                    }
                }
                tungstenite::Message::Binary(data) if data[0] == 1 => {
                    // The numbers: a contact called on the thesis' push.
                    assert_eq!(data[13..17], [0, 1, 0, 0], "CDR");
                    assert_eq!(data[13 + 20], 1, "verdict: contact");
                    received += 1;
                }
                _ => {}
            }
        }
        if received >= 3 {
            break;
        }
    }
    drop(sender);
    let stderr = child.kill();
    assert!(
        received >= 3,
        "{received} frames' numbers received of {sent} sent\n{stderr}"
    );
}

/// With `--contacts 2`, a frame called two shows both contacts' arrows.
#[test]
fn a_frame_called_two_shows_both_arrows() {
    let dir = std::env::temp_dir().join(format!("proprioscope-foxglove-{}-two", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (session, out) = (dir.join("s.json"), dir.join("est.mcap"));
    let (s, o) = (session.to_str().unwrap(), out.to_str().unwrap());
    let synth = [
        "synth",
        s,
        "--seconds",
        "4",
        "--rate",
        "100",
        "--seed",
        "1",
        "--contacts",
        "2",
    ];
    let (ok, _, err) = common::run_out(&synth);
    assert!(ok, "{err}");
    let (ok, _, err) = common::run_out(&["estimate", s, "--contacts", "2", "--out", o]);
    assert!(ok, "{err}");
    let topics = messages_by_topic(&std::fs::read(&out).unwrap());
    let pairs = topics["/proprioscope/second_contact"].len();
    let with_two = topics["/proprioscope/arrows"]
        .iter()
        .filter(|(_, d)| {
            let update = SceneUpdate::decode(d.as_slice()).unwrap();
            let roles: Vec<String> = update
                .entities
                .into_iter()
                .flat_map(|e| e.metadata.into_iter().map(|kv| kv.value))
                .collect();
            roles.iter().filter(|r| *r == "estimate").count() == 2
        })
        .count();
    assert!(pairs > 0, "the session has frames called two");
    assert_eq!(with_two, pairs, "every frame called two draws both");
    std::fs::remove_dir_all(&dir).unwrap();
}
