//! Helpers shared by the integration tests: running the binary, temporary
//! folders, and the JSON lines an estimate writes.

// Not every test file uses every helper.
#![allow(dead_code, clippy::unwrap_used)]

pub mod app;

use std::path::PathBuf;
use std::process::Command;

/// What a run of the binary gave: success, stdout, stderr.
pub struct Ran {
    /// Exit status 0.
    pub ok: bool,
    /// Standard output.
    pub out: String,
    /// Standard error.
    pub err: String,
}

/// The JSON lines of an `estimate --out` file, each parsed.
pub fn json_lines(path: &std::path::Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// Runs `proprioscope args…` in the repository root with `env` set.
pub fn run_with_env(args: &[&str], env: &[(&str, &str)]) -> Ran {
    let mut command = Command::new(env!("CARGO_BIN_EXE_proprioscope"));
    command.args(args).current_dir(env!("CARGO_MANIFEST_DIR"));
    command.env_remove("RUST_LOG");
    for (k, v) in env {
        command.env(k, v);
    }
    let out = command.output().unwrap();
    Ran {
        ok: out.status.success(),
        out: String::from_utf8_lossy(&out.stdout).into_owned(),
        err: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

/// Runs `proprioscope args…` in the repository root.
pub fn run(args: &[&str]) -> Ran {
    run_with_env(args, &[])
}

/// [`run`] as a tuple: success, stdout, stderr.
pub fn run_out(args: &[&str]) -> (bool, String, String) {
    let ran = run(args);
    (ran.ok, ran.out, ran.err)
}

/// `text` written to `name` in this run's folder of small inputs.
pub fn temp_file(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("proprioscope-estimate-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// Thesis Table 3.4 row 3 (N·m) on the built-in LWR, then a frame without contact.
pub const THESIS_SESSION: &str = r#"{"format": "contact-session", "version": 1, "robot": "lwr4plus",
  "frames": [
    {"t": 0.0, "q": [0, 0, 0, 0, 0, 0, 0], "tau": [0.09516, -0.53783, 0.09516, 0.01017, 0, 0, 0],
     "truth": {"link": "lwr_4_link", "point": [0.046, 0.098, 0.692], "force": [-1.37, -0.85, 0.33]}},
    {"t": 0.1, "q": [0, 0, 0, 0, 0, 0, 0], "tau": [0.001, -0.002, 0, 0.001, 0, 0, 0], "truth": null}
  ]}"#;

/// A fresh folder under the system's temporary folder.
pub fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("proprioscope-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The repository's `../shared`.
pub fn shared() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared")
}

/// Where a JSON value holds a number that is not one: `null` inside an
/// array, or a `null` field outside `nullable` (dotted paths); the first
/// such path.
pub fn null_number(value: &serde_json::Value, nullable: &[&str], path: &str) -> Option<String> {
    match value {
        serde_json::Value::Array(items) => items.iter().enumerate().find_map(|(i, v)| {
            if v.is_null() {
                Some(format!("{path}[{i}]"))
            } else {
                null_number(v, nullable, &format!("{path}[{i}]"))
            }
        }),
        serde_json::Value::Object(fields) => fields.iter().find_map(|(k, v)| {
            let at = if path.is_empty() {
                k.clone()
            } else {
                format!("{path}.{k}")
            };
            if v.is_null() {
                (!nullable.contains(&at.as_str())).then_some(at)
            } else {
                null_number(v, nullable, &at)
            }
        }),
        _ => None,
    }
}

/// `(detected %, false alarms %, median position error mm)` from an
/// `estimate` run's summary (its `detection:` line and its `| all |` row).
pub fn estimate_figures(out: &str) -> (f64, f64, f64) {
    let line = out.lines().find(|l| l.starts_with("detection:")).unwrap();
    let percents: Vec<f64> = line
        .split('(')
        .skip(1)
        .map(|p| p.split(' ').next().unwrap().parse().unwrap())
        .collect();
    (percents[0], percents[1], all_row(out)[2])
}

/// The number that follows `key` on the first line of `out` starting
/// with `prefix` (read up to the next space), e.g. the link 5 figure of
/// `each contact's median error … lwr_5_link 10.2 / 6.8 mm`.
pub fn figure_after(out: &str, prefix: &str, key: &str) -> f64 {
    let line = out
        .lines()
        .find(|l| l.starts_with(prefix))
        .unwrap_or_else(|| panic!("no line starting with {prefix:?} in:\n{out}"));
    line.split(key)
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|x| x.parse().ok())
        .unwrap_or_else(|| panic!("no figure after {key:?} in {line}"))
}

/// The numbers of an `estimate` run's `| all |` row, from its median
/// position error on: `[median mm, p90 mm, median N, p90 N, …]`; a cell
/// read up to its first space (`69 %`), NaN where that is no number.
pub fn all_row(out: &str) -> Vec<f64> {
    let row = out.lines().find(|l| l.contains("| all |")).unwrap();
    row.split('|')
        .skip(3)
        .map(|cell| {
            cell.trim()
                .split(' ')
                .next()
                .and_then(|v| v.parse().ok())
                .unwrap_or(f64::NAN)
        })
        .collect()
}

/// A running `proprioscope estimate --live …` on a port the system chose,
/// with the addresses it printed. Each test's process binds port 0 itself:
/// a port found free by the test and let go can be taken by a test running
/// beside it before the process binds it.
pub struct LiveEstimate {
    /// The process.
    pub child: std::process::Child,
    /// Where it takes frames (`HOST:PORT`, or `udp://HOST:PORT`).
    pub live: String,
    /// Where its Foxglove server listens (`HOST:PORT`), with `--serve`.
    pub serve: Option<String>,
    /// Its standard error, read to the end on a thread so that it never
    /// blocks on a full pipe.
    stderr: std::thread::JoinHandle<String>,
}

/// Starts `proprioscope estimate --live LIVE args…` (with `--serve
/// 127.0.0.1:0` when `serve`) and waits for the lines that say where it
/// listens.
pub fn spawn_live(live: &str, serve: bool, args: &[&str]) -> LiveEstimate {
    use std::io::BufRead as _;
    let mut command = Command::new(env!("CARGO_BIN_EXE_proprioscope"));
    command
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env_remove("RUST_LOG")
        .args(["estimate", "--live", live]);
    if serve {
        command.args(["--serve", "127.0.0.1:0"]);
    }
    let mut child = command.args(args).stderr(std::process::Stdio::piped()).spawn().unwrap();
    let mut reader = std::io::BufReader::new(child.stderr.take().unwrap());
    let (mut seen, mut live, mut served) = (String::new(), None, None);
    while live.is_none() || (serve && served.is_none()) {
        let mut line = String::new();
        if reader.read_line(&mut line).unwrap() == 0 {
            let _ = child.wait();
            panic!("estimate --live ended before it said where it listens:\n{seen}");
        }
        if let Some(address) = line.trim().strip_prefix("listening on ") {
            live = Some(address.to_owned());
        }
        if let Some((_, address)) = line.trim().split_once("ws://") {
            served = Some(address.to_owned());
        }
        seen.push_str(&line);
    }
    let stderr = std::thread::spawn(move || {
        let mut rest = String::new();
        let _ = std::io::Read::read_to_string(&mut reader, &mut rest);
        seen + &rest
    });
    LiveEstimate {
        child,
        live: live.unwrap(),
        serve: served,
        stderr,
    }
}

impl LiveEstimate {
    /// Waits for the process to end: whether it succeeded, and its stderr.
    pub fn wait(mut self) -> (bool, String) {
        let status = self.child.wait().unwrap();
        (status.success(), self.stderr.join().unwrap())
    }

    /// Ends the process: its stderr.
    pub fn kill(mut self) -> String {
        let _ = self.child.kill();
        self.wait().1
    }
}

/// A session on the built-in LWR held still at `q`: push A (link 5)
/// alone from 0.2 s, B (link 7) joins from 0.6 s, A lets go at 1.0 s, B
/// at 1.4 s; 100 frames a second, noise σ = 0.05 N·m (seed 3), every true
/// contact in `truth_all`.
pub fn two_push_session() -> String {
    use proprioscope::core::numerics::rng::Rng;
    use proprioscope::core::robot::builtin;
    use proprioscope::core::robot::kinematics::RobotPose;
    use proprioscope::core::robot::torque::joint_torques;
    use proprioscope::core::surface::sampling::{Surface, SurfaceRequest};
    let robot = builtin::lwr4plus_generated().unwrap();
    let links = robot.default_candidate_links();
    // The pushes stand on another seed's samples than the estimator's.
    let places = Surface::sample(
        &robot,
        &SurfaceRequest {
            links,
            total_points: 400,
            seed: 77,
        },
    )
    .unwrap();
    let q = [1.2, 0.3, 0.8, -1.6, -1.0, -0.5, 0.9];
    let pose = RobotPose::new(&robot, &robot.joint_positions(&q, &[]).unwrap());
    let on = |name: &str, nth: usize| {
        let link = robot.link_id(name).unwrap();
        (0..places.len()).filter(|&k| places.link[k] == link).nth(nth).unwrap()
    };
    let pushes = [
        (on("lwr_5_link", 2), 25.0, 0.2, 1.0),
        (on("lwr_7_link", 2), 20.0, 0.6, 1.4),
    ];
    let mut rng = Rng::new(3);
    let frames: Vec<serde_json::Value> = (0..160)
        .map(|i| {
            let t = 0.01 * f64::from(i);
            let mut tau = [0.0; 7];
            let mut truth_all = Vec::new();
            for &(k, f, on, off) in &pushes {
                if t < on || t >= off {
                    continue;
                }
                let link = places.link[k];
                let point = pose.point_to_world(link, places.point_in_link[k]);
                let normal = pose.world_from_link[link].transform_vector3(places.inward_normal_in_link[k]);
                for (x, u) in tau.iter_mut().zip(joint_torques(&robot, &pose, link, point, normal)) {
                    *x += f * u;
                }
                truth_all.push(serde_json::json!({
                    "link": robot.links[link].name,
                    "point": point.to_array(),
                    "force": (normal * f).to_array(),
                }));
            }
            let tau: Vec<f64> = tau.iter().map(|x| x + 0.05 * rng.normal()).collect();
            let truth = truth_all.first().cloned().unwrap_or(serde_json::Value::Null);
            serde_json::json!({"t": t, "q": q, "tau": tau, "truth": truth, "truth_all": truth_all})
        })
        .collect();
    serde_json::json!({"format": "contact-session", "version": 1, "robot": "lwr4plus", "frames": frames}).to_string()
}

/// `synth PATH --seed SEED --links LINK --slide 0.1 --slide-min 0.02
/// --kinetic-friction 0.3,0.6`: a generated session whose presses on
/// `link` slide at 2–10 cm/s with kinetic friction (the sliding sessions
/// of `docs/validation.md`, *Sliding contacts*).
pub fn synth_slide(path: &std::path::Path, link: &str, seed: &str) {
    synth_slide_with(path, link, seed, &[]);
}

/// [`synth_slide`] with `more` options after its own (`--avoid-covered`,
/// say).
pub fn synth_slide_with(path: &std::path::Path, link: &str, seed: &str, more: &[&str]) {
    let mut args = vec![
        "synth",
        path.to_str().unwrap_or_default(),
        "--seed",
        seed,
        "--links",
        link,
        "--slide",
        "0.1",
        "--slide-min",
        "0.02",
        "--kinetic-friction",
        "0.3,0.6",
    ];
    args.extend_from_slice(more);
    let (ok, _, err) = run_out(&args);
    assert!(ok, "{err}");
}
