//! Live sessions: `estimate --live ADDR` reads frames as they arrive over
//! TCP or UDP, and `stream SESSION --to ADDR` replays a recording as such
//! a source (demos, tests).

use std::io::Write as _;
use std::net::{TcpStream, UdpSocket};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, bail};
use proprioscope::batch::pairs::LivePairs;
use proprioscope::batch::{FrameEstimate, frame_outcome, session_robot};
use proprioscope::core::config::limits;
use proprioscope::core::estimate::estimator::{Estimator, Update};
use proprioscope::core::over_time::sequence::{SequenceError, StreamFilter, Temporal};
use proprioscope::core::over_time::temporal::TemporalModel;
use proprioscope::io::foxglove::painter::PairDrawn;
use proprioscope::io::foxglove::serve::FoxgloveServer;
use proprioscope::io::foxglove::{ArmScene, FoxglovePainter, frame_messages, opening};
use proprioscope::io::live::{LiveEvent, LiveSource};
use proprioscope::io::session::Session;

use super::TemporalArg;
use super::estimate::EstimateArgs;
use super::estimate_out::json_line;
use super::output::SlideVelocity;

/// Options of `stream`.
#[derive(Debug, clap::Args)]
pub struct StreamArgs {
    /// The recording to send: a session file (JSON, CSV) or a robot
    /// recording (`.mcap`, ROS 1 `.bag`); the receiver needs --robot when
    /// the file names none.
    pub session: PathBuf,
    /// Topics of a robot recording.
    #[command(flatten)]
    pub topics: super::TopicArgs,
    /// Where to send it: a TCP address something listens on (e.g.
    /// `estimate --live` or `view --live`), or `udp://host:port` for a
    /// datagram a line.
    #[arg(long)]
    pub to: String,
    /// Playback speed: 1 is real time by the frames' `t`, 0 as fast as
    /// the connection takes (valid: 0, or (0, 1000]).
    #[arg(long, default_value_t = 1.0, value_parser = stream_rate)]
    pub rate: f64,
    /// How long to keep trying to connect, s (valid: [0, 3600] s).
    #[arg(long, default_value_t = 10.0, value_parser = super::within(&limits::WAIT_SECONDS))]
    pub wait: f64,
}

/// `stream --rate`: 0 (as fast as the connection takes), or a speed
/// within [`limits::SPEED`].
fn stream_rate(text: &str) -> Result<f64, String> {
    let value = super::finite(text)?;
    if value == 0.0 {
        Ok(0.0)
    } else {
        limits::SPEED
            .check(value)
            .map_err(|e| format!("{e} (or 0: as fast as the connection takes)"))
    }
}

/// Where `stream` sends: a TCP connection, or UDP datagrams (a line each).
enum Outlet {
    Tcp(TcpStream),
    Udp(UdpSocket),
}

impl Outlet {
    /// Connects to `to` (`udp://host:port`, or `[tcp://]host:port`,
    /// retried for `wait_secs`).
    fn open(to: &str, wait_secs: f64) -> Result<Self> {
        if let Some(address) = to.strip_prefix("udp://") {
            let socket = UdpSocket::bind("0.0.0.0:0").context("opening a UDP socket")?;
            socket.connect(address).with_context(|| format!("sending to {to}"))?;
            return Ok(Self::Udp(socket));
        }
        let address = to.strip_prefix("tcp://").unwrap_or(to);
        let deadline = Instant::now() + Duration::from_secs_f64(wait_secs.clamp(0.0, 3600.0));
        loop {
            match TcpStream::connect(address) {
                Ok(c) => return Ok(Self::Tcp(c)),
                Err(e) if Instant::now() >= deadline => {
                    return Err(e).with_context(|| format!("connecting to {to}"));
                }
                Err(_) => std::thread::sleep(Duration::from_millis(50)),
            }
        }
    }

    fn send(&mut self, line: &str) -> std::io::Result<()> {
        match self {
            Self::Tcp(c) => writeln!(c, "{line}"),
            Self::Udp(s) => s.send(line.as_bytes()).map(|_| ()),
        }
    }
}

/// Sends a session as a live source: the header line, then a frame a line
/// at the pace of its times.
pub fn stream(args: &StreamArgs) -> Result<()> {
    if args.rate < 0.0 {
        bail!("--rate {}: must be ≥ 0", args.rate);
    }
    let (session, problems) = super::open_session(&args.session, &args.topics)?;
    for p in &problems {
        log::warn!("{}: skipped {p}", args.session.display());
    }
    let mut connection = Outlet::open(&args.to, args.wait)?;
    // A robot file named relative to the session means nothing to the
    // receiver: send where it is.
    let robot = session.robot.as_ref().map(|r| {
        let beside = session.path.parent().map(|dir| dir.join(r));
        match beside {
            Some(path) if path.is_file() => std::fs::canonicalize(&path).unwrap_or(path).display().to_string(),
            _ => r.clone(),
        }
    });
    let header = serde_json::json!({
        "format": "contact-session",
        "version": 1,
        "robot": robot,
        "joints": session.joints,
    });
    connection.send(&header.to_string()).context("sending the header")?;
    let started = Instant::now();
    let first_t = session.frames.first().map_or(0.0, |f| f.t);
    for frame in &session.frames {
        if args.rate > 0.0 {
            let due = (frame.t - first_t) / args.rate;
            let now = started.elapsed().as_secs_f64();
            if due > now {
                std::thread::sleep(Duration::from_secs_f64((due - now).min(3600.0)));
            }
        }
        connection
            .send(&frame.to_json().to_string())
            .context("sending a frame")?;
    }
    log::info!(
        "{}: sent {} frames to {}",
        args.session.display(),
        session.frames.len(),
        args.to
    );
    Ok(())
}

/// What a live estimate keeps between frames.
struct Live {
    robot: proprioscope::core::robot::model::Robot,
    estimator: Estimator,
    model: Option<TemporalModel>,
    /// The belief and friction gate carried between frames.
    filter: StreamFilter,
    /// With `--contacts 2`: the second contact followed over the frames.
    pairs: Option<LivePairs>,
    /// With --serve: the arm's scene and what Foxglove is sent a frame.
    foxglove: Option<(ArmScene, FoxglovePainter)>,
}

impl Live {
    /// Forgets the frames so far: a new stream starts.
    fn start_over(&mut self) {
        self.filter = StreamFilter::default();
        if let Some(pairs) = self.pairs.as_mut() {
            pairs.reset();
        }
    }
}

/// `estimate --live ADDR`.
pub fn run(args: &EstimateArgs, address: &str) -> Result<()> {
    let source = LiveSource::listen(address, || {})?;
    log::info!("listening on {}", source.address);
    let mut server = match &args.serve {
        Some(addr) => {
            let server = FoxgloveServer::start(addr, "proprioscope estimate --live")?;
            log::info!("{}", server.open_hint());
            Some(server)
        }
        None => None,
    };
    let mut slide = SlideVelocity::default();
    let mut out: Box<dyn std::io::Write> = match &args.out {
        Some(path) => Box::new(std::io::BufWriter::new(
            std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?,
        )),
        None => Box::new(std::io::stdout().lock()),
    };
    let temporal = match args.temporal.temporal {
        TemporalArg::None => Temporal::None,
        // Live, only the frames before can be used.
        TemporalArg::Auto | TemporalArg::Filter => Temporal::Filter,
        TemporalArg::Smooth => {
            log::info!("live, each frame is filtered (smoothing needs the frames after it)");
            Temporal::Filter
        }
    };
    let mut robot_name: Option<String> = args.robot.clone();
    let mut live: Option<Live> = None;
    let mut done = 0usize;
    let wanted = args.live_frames.unwrap_or(usize::MAX);
    // Drops are said at most once a second, and in all at the end.
    let mut said_drops = (0u64, Instant::now());
    let mut say_drops = |now: bool| {
        let dropped = source.dropped_frames();
        if dropped > said_drops.0 && (now || said_drops.1.elapsed().as_secs_f64() >= 1.0) {
            log::warn!(
                "{dropped} frames dropped so far: the estimator falls behind the stream (it holds {} events at most; fewer --points, or --temporal none, keep up)",
                proprioscope::io::live::QUEUE_EVENTS
            );
            said_drops = (dropped, Instant::now());
        }
    };
    while done < wanted {
        let Ok(event) = source.events.recv() else {
            break;
        };
        match event {
            LiveEvent::Connected(from) => {
                log::info!("{from}: connected");
                // A new sender starts a new recording: nothing carries over.
                if let Some(l) = live.as_mut() {
                    l.start_over();
                }
            }
            LiveEvent::NewSender { from, previous } => {
                log::info!("{from}: a new sender after {previous} went quiet: a new stream segment");
                if let Some(l) = live.as_mut() {
                    l.start_over();
                }
            }
            LiveEvent::Header { robot, .. } => {
                if robot_name.is_none() {
                    robot_name = robot;
                }
            }
            LiveEvent::Bad(why) => log::warn!("{why}"),
            LiveEvent::Gap { from_t, to_t } => log::info!("no frame from t = {from_t} to {to_t} s"),
            LiveEvent::Closed(why) => log::info!("{why} after {done} frames in all"),
            LiveEvent::Frame(frame) => {
                if live.is_none() {
                    let started = start(args, robot_name.as_deref(), temporal)?;
                    if let (Some(server), Some((scene, _))) = (server.as_mut(), started.foxglove.as_ref()) {
                        server.set_opening(opening(scene, seconds_ns(frame.t)))?;
                    }
                    live = Some(started);
                }
                let Some(l) = live.as_mut() else { continue };
                match estimate_frame(l, done, &frame, temporal) {
                    Ok((mut value, update, positions, pair)) => {
                        if let (Some(server), Some((scene, painter))) = (server.as_mut(), l.foxglove.as_mut()) {
                            painter.set_pair(pair);
                            let drawn = painter.frame(&l.estimator, &update, &frame, &positions, seconds_ns(frame.t));
                            server.publish(&frame_messages(scene, &drawn))?;
                        }
                        slide.mark(&mut value);
                        writeln!(out, "{value}").context("writing an estimate")?;
                        out.flush().context("writing an estimate")?;
                        done += 1;
                    }
                    Err(e) => log::warn!("frame at t = {}: {e:#}", frame.t),
                }
                say_drops(false);
            }
        }
    }
    say_drops(true);
    Ok(())
}

/// The robot and estimator, made on the first frame.
fn start(args: &EstimateArgs, robot: Option<&str>, temporal: Temporal) -> Result<Live> {
    let Some(robot_name) = robot else {
        bail!("the stream names no robot: give one with --robot");
    };
    let empty = Session {
        path: PathBuf::from("live"),
        robot: Some(robot_name.to_owned()),
        joints: None,
        frames: Vec::new(),
    };
    let robot = session_robot(&empty, None, &args.package_paths, &args.estimator.links)?;
    let config = args.estimator.live_config(&args.temporal)?;
    let estimator = args.estimator.estimator(&robot, &config, temporal)?;
    log::info!(
        "{robot_name}: {} surface points on {} links{}",
        estimator.surface.len(),
        estimator.links.len(),
        match (args.estimator.points, config.contacts_at_once >= 2) {
            (Some(_), _) => "",
            (None, false) => " (fewer than for a file, so that a frame keeps up live; --points to change)",
            (None, true) => " (as for a file: two contacts need them; --points to change)",
        }
    );
    let model = match temporal {
        Temporal::None => None,
        _ => Some(config.temporal_model(&estimator.surface, estimator.uses_patches())?),
    };
    // A second contact is followed with the frames before it whatever
    // --temporal says of the first: a stream has no frames after.
    let pairs = (config.contacts_at_once >= 2).then(|| LivePairs::new(config.pair, config.second_contact_chain()));
    let foxglove = args.serve.is_some().then(|| {
        let painter = FoxglovePainter::new(&robot, &estimator, temporal != Temporal::None, args.tf_hz);
        (ArmScene::new(&robot), painter)
    });
    Ok(Live {
        robot,
        estimator,
        model,
        filter: StreamFilter::default(),
        pairs,
        foxglove,
    })
}

/// A frame's time as nanoseconds.
fn seconds_ns(t: f64) -> i64 {
    (t * 1e9).round() as i64
}

/// One frame's estimate as a JSON line (with the contact probability when
/// filtered), the estimate, the joint positions in the robot's order, and
/// both contacts (point and push, world frame) where two are called.
fn estimate_frame(
    live: &mut Live,
    number: usize,
    frame: &proprioscope::io::session::Frame,
    temporal: Temporal,
) -> Result<(serde_json::Value, Update, Vec<f64>, Option<PairDrawn>)> {
    let positions = live.robot.joint_positions(&frame.q, &[])?;
    let t0 = Instant::now();
    let update = match (temporal, live.model.as_ref()) {
        (Temporal::None, _) | (_, None) => live.estimator.update(&live.robot, &positions, &frame.tau)?,
        (_, Some(model)) => live
            .filter
            .update(
                &live.estimator,
                model,
                &live.robot,
                (number, frame.t),
                &positions,
                &frame.tau,
            )
            // The caller names the frame by its time already.
            .map_err(|e| match e {
                SequenceError::Frame { source, .. } => anyhow::Error::from(source),
                SequenceError::Temporal(source) => anyhow::Error::from(source),
            })?,
    };
    let single_ms = t0.elapsed().as_secs_f64() * 1e3;
    let searched = match live.pairs.as_mut() {
        Some(pairs) => pairs
            .push(&live.estimator, &live.robot, (frame, &positions), &update)
            .context("the second contact's search")?,
        None => None,
    };
    let pair = searched.as_ref().filter(|p| p.has_two());
    // The frame's whole cost, its second contact's search included.
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    let outcome = frame_outcome(&live.robot, &FrameEstimate::of(&update, single_ms), &frame.truth);
    let mut line = json_line(
        &live.estimator,
        &live.robot,
        (number, frame),
        &update,
        ms,
        outcome.as_ref(),
    );
    if let Some(found) = &searched {
        line["two_contacts"] = super::estimate::pair_verdict_json(found);
    }
    if let Some(pair) = pair {
        line["contacts"] = super::estimate::pair_contacts_json(&live.robot, pair, line["contact_probability"].as_f64());
    }
    let drawn = pair.map(|p| p.pair.contacts.each_ref().map(|c| (c.point_world, c.force_world)));
    Ok((line, update, positions, drawn))
}
