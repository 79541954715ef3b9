//! `proprioscope estimate SESSION`: estimates every frame of a recorded session.

use std::io::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context as _, Result};
use glam::DVec3;
use indicatif::{ProgressBar, ProgressStyle};
use proprioscope::batch::pairs::{FramePair, PairScore, PairsOver, SingleSeen, TimedPairs, session_pairs_timed};
use proprioscope::batch::{FrameEstimate, frame_outcome, session_robot, truth_in_link};
use proprioscope::core::config::estimator::{EstimatorConfig, Friction};
use proprioscope::core::config::limits;
use proprioscope::core::estimate::estimator::Estimator;
use proprioscope::core::estimate::estimator::Update;
use proprioscope::core::estimate::summary::Verdict;
use proprioscope::core::eval::metrics::{
    FrameOutcome, Metrics, detection, metrics, metrics_by_sensing_joints, percentile,
};
use proprioscope::core::eval::slides::{MIN_SLIDE_M, SlidePath, SlideTracker};

use super::press_gaps::{report_gaps, session_gaps};
use proprioscope::core::over_time::bias::{estimate_drifting_bias, without_drifting_bias};
use proprioscope::core::over_time::frame::SequenceFrame;
use proprioscope::core::over_time::sequence::{Temporal, automatic_temporal, estimate_sequence};
use proprioscope::core::over_time::temporal::is_continuous_recording;
use proprioscope::core::robot::model::Robot;
use proprioscope::io::foxglove::{Arrow, ArrowRole};
use proprioscope::io::mcap_out::EstimateMessage;
use proprioscope::io::recording::is_recording;
use proprioscope::io::session::{Session, Truth, kept_frame_numbers};

use super::estimate_out::{Out, json_line};
use super::{EstimatorArgs, TemporalArg, TemporalArgs, TopicArgs, option_error};

/// Options of `estimate`.
#[derive(Debug, clap::Args)]
pub struct EstimateArgs {
    /// A session file (`.json`, or `.csv` with --robot), a robot recording
    /// (`.mcap`, ROS 1 `.bag`, with --robot); or use --live.
    #[arg(required_unless_present = "live")]
    pub session: Option<PathBuf>,
    /// Read frames as they arrive instead: listen on this TCP address
    /// (e.g. `127.0.0.1:7878`; or `udp://127.0.0.1:7878` for datagrams of
    /// one or more lines) for JSON lines in the session format (an
    /// optional header line, then a frame a line; see `stream`), and
    /// estimate each with the frames before it (`--temporal none` for
    /// each alone). Needs --robot unless the header names it.
    #[arg(long, conflicts_with = "session")]
    pub live: Option<String>,
    /// With --live: stop after this many frames (default: run until
    /// killed; a closed connection waits for the next; at least 1).
    #[arg(long, requires = "live", value_parser = super::counted(&limits::LIVE_FRAMES))]
    pub live_frames: Option<usize>,
    /// With --live: also publish each estimate to Foxglove over its
    /// WebSocket protocol on this address (default 127.0.0.1:8765,
    /// loopback); open it in Foxglove with Open connection → Foxglove
    /// WebSocket → `ws://ADDR`.
    #[arg(long, requires = "live", num_args = 0..=1, default_missing_value = proprioscope::io::foxglove::serve::DEFAULT_SERVE_ADDR)]
    pub serve: Option<String>,
    /// With an MCAP --out or --serve: the most Foxglove transforms a
    /// second of the recording, Hz (every frame at this rate or slower; 0:
    /// every frame).
    #[arg(long, default_value_t = proprioscope::io::foxglove::TRANSFORMS_HZ, value_parser = super::within(&limits::TRANSFORMS_HZ))]
    pub tf_hz: f64,
    /// The robot (built-in name or URDF), overriding the session's.
    #[arg(long)]
    pub robot: Option<String>,
    /// Extra folder for `package://` URIs (repeatable).
    #[arg(long = "package-path")]
    pub package_paths: Vec<PathBuf>,
    /// Write one JSON line per frame here; or, for a `.mcap` file, the
    /// input's topics (a session's frames as `/joint_states` and truth)
    /// with the estimates (`/proprioscope/…`: the contact as
    /// `WrenchStamped` and `PointStamped`, its probability, the 90 %
    /// credible region as a `PointCloud2`), for Foxglove or `RViz`.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Skip frames with a missing or non-finite value, a wrong number of
    /// values or a time going backwards (each reported on stderr) instead
    /// of stopping at the first; a recording cut short is read up to its
    /// last whole frame. Output frames keep their numbers in the file.
    #[arg(long)]
    pub skip_bad_frames: bool,
    /// Torque bias: `none`, or `auto` to estimate each joint's offset from
    /// the session (the mode of its readings: what it reads with nothing
    /// touching) and take it off every frame.
    #[arg(long, value_enum, default_value = "none")]
    pub bias: BiasArg,
    /// With `--bias auto`, the offset may drift: it is estimated over
    /// windows of this many seconds, half a window apart, and interpolated
    /// (a session no longer than one window gets one offset). Valid:
    /// [0.1, 86400] s.
    #[arg(long, default_value_t = 30.0, value_parser = super::within(&limits::BIAS_WINDOW))]
    pub bias_window: f64,
    /// A calibration saved by `calibrate` (the same robot's model error,
    /// learned from another recording): taken off every frame's torques,
    /// with its σ where `--sigma auto`.
    #[arg(long)]
    pub calibration: Option<PathBuf>,
    /// Where the session has truth: fit each true press again from the
    /// estimate's places and from the true ones, and print both fits'
    /// costs and errors (a press the search lost costs far less from the
    /// truth).
    #[arg(long)]
    pub press_gaps: bool,
    /// Topics of a recording.
    #[command(flatten)]
    pub topics: TopicArgs,
    /// Estimator options.
    #[command(flatten)]
    pub estimator: EstimatorArgs,
    /// Temporal model.
    #[command(flatten)]
    pub temporal: TemporalArgs,
}

/// `--bias`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BiasArg {
    /// Torques as measured.
    None,
    /// Each joint's offset estimated from the session and taken off.
    Auto,
}

/// The session, strictly or skipping bad frames; with each kept frame's
/// number in the file, and a recording's clock reading at `t = 0`.
fn read_session(args: &EstimateArgs, path: &std::path::Path) -> Result<(Session, Vec<usize>, Option<i64>)> {
    // A recording's torque messages outside the joint states' span are
    // normal (the robot's topics start apart): skipped and said.
    Ok(if args.skip_bad_frames || is_recording(path) {
        let (session, problems, origin) = super::open_session_with_origin(path, &args.topics)?;
        for p in &problems {
            log::warn!("{}: skipped {p}", path.display());
        }
        let kept = kept_frame_numbers(session.frames.len(), &problems);
        (session, kept, origin)
    } else {
        let session = Session::read(path)?;
        let all: Vec<usize> = (0..session.frames.len()).collect();
        (session, all, None)
    })
}

/// Every frame's joint positions, in the robot's order.
fn joint_positions(robot: &Robot, session: &Session, file_frames: &[usize]) -> Result<Vec<Vec<f64>>> {
    session
        .frames
        .iter()
        .zip(file_frames)
        .map(|(frame, i)| {
            robot
                .joint_positions(&frame.q, &[])
                .with_context(|| format!("{}: frame {i} (t = {})", session.path.display(), frame.t))
        })
        .collect()
}

/// Every frame's torques, with `--bias auto` less the estimated bias
/// (printed).
fn debiased_torques(args: &EstimateArgs, robot: &Robot, session: &Session, sigma: &[f64]) -> Result<Vec<Vec<f64>>> {
    let refs: Vec<&[f64]> = session.frames.iter().map(|f| f.tau.as_slice()).collect();
    if args.bias == BiasArg::None {
        return Ok(refs.iter().map(|t| t.to_vec()).collect());
    }
    let times: Vec<f64> = session.frames.iter().map(|f| f.t).collect();
    let bias = estimate_drifting_bias(&times, &refs, sigma, args.bias_window)
        .with_context(|| format!("--bias auto on {}", session.path.display()))?;
    let (Some(first), Some(last)) = (bias.first(), bias.last()) else {
        return Ok(Vec::new());
    };
    let named: Vec<String> = robot
        .sensed_names()
        .iter()
        .zip(first.iter().zip(last))
        .map(|(name, (a, b))| {
            if (a - b).abs() < 5e-5 {
                format!("{name} {a:+.4}")
            } else {
                format!("{name} {a:+.4} → {b:+.4}")
            }
        })
        .collect();
    outln!(
        "bias (estimated, N·m, first → last frame when it drifts; taken off every frame): {}",
        named.join(", ")
    );
    Ok(without_drifting_bias(&refs, &bias))
}

/// Every frame's torques as the estimator takes them (less the bias with
/// `--bias auto`, less the model error a calibration learned or was
/// given) and σ (learned with `--sigma auto`, else `sigma`).
fn frame_torques(
    args: &EstimateArgs,
    robot: &Robot,
    session: &Session,
    sigma: &[f64],
    config: &EstimatorConfig,
    temporal: Temporal,
) -> Result<(Vec<Vec<f64>>, Vec<f64>)> {
    let taus = debiased_torques(args, robot, session, sigma)?;
    let times: Vec<f64> = session.frames.iter().map(|f| f.t).collect();
    super::calibrate::torques_and_sigma(
        robot,
        session,
        taus,
        sigma.to_vec(),
        &config.torques,
        (temporal, is_continuous_recording(&times, &config.temporal)),
        args.calibration.as_deref(),
    )
}

/// `--temporal`, with `auto` decided for this session (and said on stderr).
fn chosen_temporal(args: &EstimateArgs, session: &Session) -> Temporal {
    if args.temporal.temporal != TemporalArg::Auto {
        return args.temporal.temporal.into();
    }
    let times: Vec<f64> = session.frames.iter().map(|f| f.t).collect();
    let (chosen, why) = automatic_temporal(&times, &args.temporal.settings());
    log::info!("--temporal auto: {why} (choose with --temporal none|filter|smooth)");
    chosen
}

/// Runs the command on a session file (`--live` is
/// [`super::live::run`]'s).
pub fn run(args: &EstimateArgs) -> Result<()> {
    let Some(path) = args.session.as_deref() else {
        anyhow::bail!("give a session file or --live ADDR");
    };
    run_session(args, path)
}

/// The friction μ of `config` for frames combined by `temporal` (`auto`
/// said on stderr where it takes friction).
fn friction_for(config: &EstimatorConfig, joints: usize, temporal: Temporal) -> Result<f64> {
    let mu = config
        .settings(joints, temporal)
        .map_err(|e| option_error(&e))?
        .friction;
    if config.friction == Friction::Auto && mu > 0.0 {
        log::info!("--friction auto: μ = {mu} over time (choose with --friction μ; 0: frictionless)");
    }
    Ok(mu)
}

/// Estimates the session file at `path`.
#[allow(clippy::too_many_lines)] // One pass over the frames and its report, read top to bottom.
fn run_session(args: &EstimateArgs, path: &std::path::Path) -> Result<()> {
    let (session, file_frames, origin_ns) = read_session(args, path)?;
    let robot = session_robot(
        &session,
        args.robot.as_deref(),
        &args.package_paths,
        &args.estimator.links,
    )?;
    let config = args.estimator.config(&args.temporal)?;
    let started = Instant::now();
    // Frames alone until it is known how they are combined (below).
    let mut estimator = args.estimator.estimator(&robot, &config, Temporal::None)?;
    log::info!(
        "{}: {} frames; {} surface points on {} links, sampled in {:.0} ms",
        path.display(),
        session.frames.len(),
        estimator.surface.len(),
        estimator.links.len(),
        started.elapsed().as_secs_f64() * 1e3
    );
    let mut out = match &args.out {
        Some(out_path) => Some(Out::create(out_path, path, &session, &robot, origin_ns)?),
        None => None,
    };
    let temporal = chosen_temporal(args, &session);
    estimator.settings.friction = friction_for(&config, robot.sensed().len(), temporal)?;
    let model = match temporal {
        Temporal::None => None,
        Temporal::Filter | Temporal::Smooth => Some(
            config
                .temporal_model(&estimator.surface, estimator.uses_patches())
                .context("--temporal")?,
        ),
    };
    let positions = joint_positions(&robot, &session, &file_frames)?;
    if let Some(out) = out.as_mut() {
        let first_ns = session.frames.first().map_or(0, |f| (f.t * 1e9).round() as i64);
        out.draw_for_foxglove(
            &robot,
            &estimator,
            (temporal != Temporal::None, args.tf_hz),
            origin_ns.unwrap_or(0).saturating_add(first_ns),
        )?;
    }
    let (taus, sigma) = frame_torques(args, &robot, &session, &estimator.settings.sigma, &config, temporal)?;
    estimator.settings.sigma = sigma;
    let sequence = frame_sequence(&session, &positions, &taus);
    let bar = ProgressBar::new(session.frames.len() as u64);
    bar.set_style(ProgressStyle::with_template(
        "{bar:40} {pos}/{len} frames, {per_sec}, eta {eta}",
    )?);
    let mut outcomes = Vec::new();
    let mut times_ms = Vec::new();
    let mut verdicts = [0usize; 3];
    let mut called = Vec::with_capacity(session.frames.len());
    let mut slides = SlideTracker::default();
    let mut press_places = Vec::new();
    let mut written: Result<()> = Ok(());
    let two_contacts = config.contacts_at_once >= 2;
    let (mut singles, mut pending, mut messages) = (Vec::new(), Vec::new(), Vec::new());
    // Each frame's single contact (world point), scored where one presses.
    let mut single_points = Vec::new();
    args.estimator.with_threads(|| {
        estimate_sequence(
            &estimator,
            &robot,
            model.as_ref(),
            temporal,
            &sequence,
            |n, update, ms| {
                let (Some(frame), Some(&i)) = (session.frames.get(n), file_frames.get(n)) else {
                    return;
                };
                times_ms.push(ms);
                verdicts[match update.summary.verdict {
                    Verdict::Contact => 0,
                    Verdict::NoContact => 1,
                    Verdict::PoorFit => 2,
                }] += 1;
                called.push(update.summary.verdict != Verdict::NoContact);
                let (true_place, estimated_place) = slide_places(&robot, &update, &frame.truth);
                slides.push(frame.t, true_place, estimated_place);
                if args.press_gaps {
                    press_places.push((true_place, estimated_place));
                }
                let outcome = frame_outcome(
                    &robot,
                    &FrameEstimate::of_frame(&robot, &estimator.surface, &update, ms, &frame.truth),
                    &frame.truth,
                );
                outcomes.extend(outcome);
                if two_contacts {
                    // The frame's output waits for the session's second contacts.
                    singles.push(SingleSeen::of(&update));
                    single_points
                        .push((update.summary.verdict != Verdict::NoContact).then_some(update.summary.map.point_world));
                    if let Some(w) = out.as_mut().filter(|o| o.is_mcap()) {
                        let q = positions.get(n).map_or(&[][..], Vec::as_slice);
                        messages.push(w.message(&estimator, &robot, (frame, q), &update, origin_ns.unwrap_or(0)));
                    } else {
                        pending.push(json_line(&estimator, &robot, (i, frame), &update, ms, outcome.as_ref()));
                    }
                } else if let (Some(w), Ok(())) = (out.as_mut(), &written) {
                    let q = positions.get(n).map_or(&[][..], Vec::as_slice);
                    written = w.write(
                        &estimator,
                        &robot,
                        (i, frame, q),
                        &update,
                        ms,
                        outcome.as_ref(),
                        origin_ns,
                    );
                }
                bar.inc(1);
            },
        )
        .with_context(|| session.path.display().to_string())
    })??;
    written?;
    bar.finish_and_clear();
    if two_contacts {
        let (pairs, search_ms) = args
            .estimator
            .with_threads(|| second_contacts(&estimator, &robot, &config, temporal, &sequence, &singles))?
            .map_err(|(n, e)| anyhow::anyhow!("{}: frame {n}: {e}", session.path.display()))?;
        // A frame's update under the two-contact model includes its
        // search, as live.
        for (n, search) in search_ms.iter().enumerate() {
            if let Some(ms) = times_ms.get_mut(n) {
                *ms += search;
            }
            if let Some(line) = pending.get_mut(n)
                && let Some(update_ms) = line.get("update_ms").and_then(serde_json::Value::as_f64)
            {
                line["update_ms"] = serde_json::json!(update_ms + search);
            }
        }
        let weights = estimator.settings.weights();
        write_with_second_contacts(
            (&robot, (&weights, estimator.settings.friction > 0.0)),
            &session,
            (&pairs, &single_points),
            (&mut pending, &mut messages),
            out.as_mut(),
        )?;
    }
    if let Some(out) = out {
        out.finish()?;
    }
    report(&session, &verdicts, &times_ms, &called)?;
    if !outcomes.is_empty() {
        print_metrics(&outcomes)?;
    }
    report_slides(&robot, &slides.finish())?;
    if args.press_gaps {
        let gaps = args.estimator.with_threads(|| {
            session_gaps(
                &estimator,
                &robot,
                &sequence,
                &press_places,
                config.temporal.slide_m_per_sqrt_s,
            )
        })?;
        report_gaps(&robot, &gaps, estimator.settings.friction)?;
    }
    Ok(())
}

/// A frame's true contact (its link, and its place in that link's frame)
/// and the estimated place in the same frame where the frame is called a
/// contact on that link: what a slide's paths are measured from.
fn slide_places(robot: &Robot, update: &Update, truth: &Truth) -> (Option<(usize, DVec3)>, Option<DVec3>) {
    let Some((link, true_place)) = truth_in_link(robot, &update.pose, truth) else {
        return (None, None);
    };
    let map = &update.summary.map;
    let estimated = if update.summary.verdict != Verdict::NoContact && map.link == link {
        let world_from_link = update.pose.world_from_link.get(link);
        world_from_link.map(|w| w.inverse().transform_point3(map.point_world))
    } else {
        None
    };
    (Some((link, true_place)), estimated)
}

/// The presses that slid: how long their estimated paths were against
/// the true ones (`docs/validation.md`, *Sliding contacts*); each press's
/// at debug level (`RUST_LOG=proprioscope=debug`).
fn report_slides(robot: &Robot, paths: &[SlidePath]) -> Result<()> {
    let ratios: Vec<f64> = paths
        .iter()
        .filter_map(SlidePath::relative_error)
        .map(|e| 1.0 + e)
        .collect();
    if ratios.is_empty() {
        return Ok(());
    }
    for (n, path) in paths.iter().enumerate().filter(|(_, p)| p.slid()) {
        log::debug!(
            "press {n}: {}, {} frames, true path {:.1} mm, estimated {:.1} mm",
            robot.links.get(path.link).map_or("?", |l| l.name.as_str()),
            path.frames,
            path.true_length_m * 1e3,
            path.estimated_length_m * 1e3
        );
    }
    let within = ratios.iter().filter(|&&r| (r - 1.0).abs() <= 0.2).count();
    outln!(
        "slides: {} of {} presses slid {:.0} cm or more; estimated path / true path: median {:.2} (p10 {:.2}, p90 {:.2}), within 20 % in {within} of {}",
        ratios.len(),
        paths.len(),
        MIN_SLIDE_M * 100.0,
        percentile(&ratios, 0.5),
        percentile(&ratios, 0.1),
        percentile(&ratios, 0.9),
        ratios.len()
    );
    Ok(())
}

/// The session's second contacts ([`session_pairs_timed`]), the frames
/// taken together as the single contacts are: each alone, filtered (each
/// from the frames before, as live) or smoothed, the chain with the
/// temporal model's onset and release rates; with each frame's search
/// time, ms.
fn second_contacts(
    estimator: &Estimator,
    robot: &Robot,
    config: &EstimatorConfig,
    temporal: Temporal,
    sequence: &[SequenceFrame<'_>],
    singles: &[Option<SingleSeen>],
) -> Result<TimedPairs, (usize, proprioscope::core::estimate::settings::EstimateError)> {
    let over = PairsOver::of(temporal, config.second_contact_chain());
    session_pairs_timed(estimator, robot, sequence, singles, &config.pair, over, || true).map(Option::unwrap_or_default)
}

/// The session's frames as the sequence takes them.
fn frame_sequence<'a>(session: &Session, positions: &'a [Vec<f64>], taus: &'a [Vec<f64>]) -> Vec<SequenceFrame<'a>> {
    session
        .frames
        .iter()
        .zip(positions)
        .zip(taus)
        .map(|((frame, joint_positions), tau)| SequenceFrame {
            t_secs: frame.t,
            joint_positions,
            tau,
        })
        .collect()
}

/// The lines with their second contacts written, and their score printed.
fn write_with_second_contacts(
    (robot, rules): (&Robot, (&[f64], bool)),
    session: &Session,
    (pairs, singles): (&[Option<FramePair>], &[Option<DVec3>]),
    (lines, messages): (&mut [serde_json::Value], &mut [EstimateMessage]),
    out: Option<&mut Out>,
) -> Result<()> {
    let score = add_second_contacts((robot, rules), session, (pairs, singles), lines);
    // An MCAP frame called two carries both contacts of the pair.
    let named = |c: &proprioscope::core::estimate::pair::PairContact| {
        (
            robot
                .links
                .get(c.placed.link)
                .map_or_else(String::new, |l| l.name.clone()),
            c.point_world.to_array(),
            c.force_world.to_array(),
        )
    };
    // Foxglove's arrows: every frame called two shows the pair; the frame
    // after a pair shows the single contact again.
    let (mut was_two, mut single_role) = (false, ArrowRole::Estimate);
    for ((message, pair), frame) in messages.iter_mut().zip(pairs).zip(&session.frames) {
        let two = pair.as_ref().filter(|p| p.has_two());
        if let Some(p) = two {
            let [a, b] = &p.pair.contacts;
            message.contact = Some(named(a));
            message.second_contact = Some(named(b));
        }
        let contact = message.contact.clone();
        if let Some(drawn) = message.foxglove.as_mut() {
            if let (None, Some(arrows)) = (two, &drawn.arrows)
                && let Some(single) = arrows.iter().find(|a| a.role != ArrowRole::Push)
            {
                single_role = single.role;
            }
            let mut arrows = Arrow::truths(&frame.true_contacts());
            if let Some(p) = two {
                arrows.extend(p.pair.contacts.each_ref().map(|c| Arrow {
                    role: ArrowRole::Estimate,
                    point_world: c.point_world,
                    force_world: c.force_world,
                }));
                drawn.arrows = Some(arrows);
            } else if was_two && drawn.arrows.is_none() {
                arrows.extend(contact.map(|(_, point, force)| Arrow {
                    role: single_role,
                    point_world: DVec3::from_array(point),
                    force_world: DVec3::from_array(force),
                }));
                drawn.arrows = Some(arrows);
            }
        }
        was_two = two.is_some();
    }
    if let Some(w) = out {
        w.write_made(lines, messages)?;
    }
    report_pairs(&score)
}

/// Each line's `contacts` where two are called, and the score of every
/// true contact (its true pairs judged with `rules`: 1/σ², friction).
fn add_second_contacts(
    (robot, rules): (&Robot, (&[f64], bool)),
    session: &Session,
    (pairs, singles): (&[Option<FramePair>], &[Option<DVec3>]),
    lines: &mut [serde_json::Value],
) -> PairScore {
    let mut score = PairScore::default();
    for (n, (pair, frame)) in pairs.iter().zip(&session.frames).enumerate() {
        if let (Some(found), Some(line)) = (pair, lines.get_mut(n)) {
            line["two_contacts"] = pair_verdict_json(found);
            if found.has_two() {
                line["contacts"] = pair_contacts_json(robot, found, line["contact_probability"].as_f64());
            }
        }
        score.add_frame(robot, (frame, rules), pair.as_ref(), singles.get(n).copied().flatten());
    }
    score
}

/// A searched frame's `two_contacts`: the probability of two over the
/// frames taken together, the frame's own evidence ratio `ln Z₂/Z₁`,
/// and whether the pair is identifiable (if not, why).
pub(super) fn pair_verdict_json(pair: &FramePair) -> serde_json::Value {
    serde_json::json!({
        "probability": pair.probability_two,
        "log_evidence_ratio": pair.pair.log_evidence_ratio(),
        "identifiable": pair.pair.identifiable(),
        "unidentifiable": pair.pair.unidentifiable.map(|u| u.describe(pair.pair.sensing_joints)),
        "bridged": pair.bridged,
        "carried": pair.carried,
    })
}

/// A frame's `contacts` where two are called: each with its probability
/// (the frame's contact probability, times that of two for the second).
pub(super) fn pair_contacts_json(
    robot: &Robot,
    pair: &FramePair,
    contact_probability: Option<f64>,
) -> serde_json::Value {
    let contact = contact_probability.unwrap_or(1.0);
    let entries: Vec<serde_json::Value> = pair
        .pair
        .contacts
        .iter()
        .enumerate()
        .map(|(k, c)| {
            serde_json::json!({
                "link": robot.links.get(c.placed.link).map(|l| l.name.clone()),
                "point": c.point_world.to_array(),
                "force": c.force_world.to_array(),
                "probability": if k == 0 { contact } else { contact * pair.probability_two },
                "credible90_radius_m": c.credible90.radius_m,
            })
        })
        .collect();
    serde_json::json!(entries)
}

/// What `--contacts 2` found, scored against the session's `truth_all`.
fn report_pairs(score: &PairScore) -> Result<()> {
    if score.both_frames + score.one_frames == 0 {
        return Ok(());
    }
    let share = |k: usize, n: usize| if n > 0 { 100.0 * k as f64 / n as f64 } else { 0.0 };
    let mut out = std::io::stdout().lock();
    let one = format!(
        "in {} of {} frames where one presses ({:.1} %)",
        score.one_called_two,
        score.one_frames,
        share(score.one_called_two, score.one_frames),
    );
    if score.both_frames == 0 {
        writeln!(out, "two contacts: no frame where two press; called {one}")?;
        return Ok(());
    }
    let error = if score.both_errors_m.is_empty() {
        "no error measured".to_owned()
    } else {
        format!("median error {:.1} mm", 1e3 * score.median_error_m())
    };
    writeln!(
        out,
        "two contacts: called in {} of {} frames where both press ({:.1} %; {} of {} where six or more joints feel them, {:.1} %), {error}; {one}",
        score.both_called_two,
        score.both_frames,
        share(score.both_called_two, score.both_frames),
        score.both_identifiable_called_two,
        score.both_identifiable,
        share(score.both_identifiable_called_two, score.both_identifiable),
    )?;
    // The frames where a pair can be called at all: the true pair passes
    // the rules an estimated pair must (its pushes' own joints read them,
    // and so on).
    writeln!(
        out,
        "two contacts the joints can tell apart (the true pair under the rules for a pair): called in {} of {} frames where both press ({:.1} %)",
        score.both_separable_called_two,
        score.both_separable,
        share(score.both_separable_called_two, score.both_separable),
    )?;
    // Each true contact's error beside the other against alone: what the
    // second contact costs the first.
    writeln!(
        out,
        "each contact's median error, called two where both press / alone: {}",
        each_contact_text(score, " mm")
    )?;
    // The same where a pair can be placed at all: elsewhere one of the
    // true pushes is not read by its own joints, and no estimate can
    // place it.
    let separable: Vec<String> = score
        .by_link
        .iter()
        .map(|(link, errors)| format!("{link} {} mm", mm(errors.separable_median_m())))
        .collect();
    writeln!(
        out,
        "each contact's median error, called two where the joints can tell the true pair apart: {}",
        separable.join(", ")
    )?;
    Ok(())
}

/// A length in m as mm to a tenth, or a dash for NaN (none measured).
pub(super) fn mm(m: f64) -> String {
    if m.is_nan() {
        "–".to_owned()
    } else {
        format!("{:.1}", 1e3 * m)
    }
}

/// Each true contact's median error where both press and two are
/// called / where it presses alone, by link, each followed by `unit`.
pub(super) fn each_contact_text(score: &PairScore, unit: &str) -> String {
    let each: Vec<String> = score
        .by_link
        .iter()
        .map(|(link, errors)| {
            let (with_other, alone) = errors.medians_m();
            format!("{link} {} / {}{unit}", mm(with_other), mm(alone))
        })
        .collect();
    each.join(", ")
}

/// The verdict counts, times and detection record of a run.
fn report(session: &Session, verdicts: &[usize; 3], times_ms: &[f64], called: &[bool]) -> Result<()> {
    outln!(
        "{} frames: {} contact, {} no contact, {} poorly explained",
        session.frames.len(),
        verdicts[0],
        verdicts[1],
        verdicts[2]
    );
    if times_ms.is_empty() {
        outln!("update time: no frame was estimated");
    } else {
        let mean = times_ms.iter().sum::<f64>() / times_ms.len() as f64;
        outln!(
            "update time: mean {mean:.3} ms, median {:.3} ms, p99 {:.3} ms",
            percentile(times_ms, 0.5),
            percentile(times_ms, 0.99)
        );
    }
    let truth: Vec<Option<bool>> = session.frames.iter().map(|f| f.truth.has_contact()).collect();
    let found = detection(&truth, called);
    if found.contact_frames + found.quiet_frames > 0 {
        outln!(
            "detection: {}/{} contact frames ({:.1} %), {}/{} false alarms ({:.1} %), onsets found after {}",
            found.detected,
            found.contact_frames,
            100.0 * found.detection_rate(),
            found.false_alarms,
            found.quiet_frames,
            100.0 * found.false_alarm_rate(),
            onset_text(&found.onset_delays)
        );
    }
    Ok(())
}

/// "0, 1, 2 frames" (a missed onset reads "missed").
pub fn onset_text(delays: &[Option<usize>]) -> String {
    if delays.is_empty() {
        return "— (no onsets)".to_owned();
    }
    let parts: Vec<String> = delays
        .iter()
        .map(|d| d.map_or_else(|| "missed".to_owned(), |d| d.to_string()))
        .collect();
    format!("{} frames", parts.join(", "))
}

/// A table cell: the number to `decimals`, or `–` where there is none
/// to give (a statistic of no frame).
fn cell(value: f64, decimals: usize) -> String {
    if value.is_finite() {
        format!("{value:.decimals$}")
    } else {
        "–".to_owned()
    }
}

/// The errors table: all frames, then by number of sensing joints.
pub fn print_metrics(outcomes: &[FrameOutcome]) -> Result<()> {
    outln!();
    outln!(
        "| frames | sensing joints | median pos. error [mm] | p90 [mm] | median force error [N] | p90 [N] | link right | ε_r [mm] | ε_F [N] | σ_r [mm] | 90 % set holds the push |"
    );
    outln!("|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let row = |label: &str, m: &Metrics| -> Result<()> {
        let held = m
            .credible90_held
            .map_or_else(|| "–".to_owned(), |h| cell(h * 100.0, 1) + " %");
        outln!(
            "| {} | {label} | {} | {} | {} | {} | {} % | {} | {} | {} | {held} |",
            m.frames,
            cell(m.position_median_m * 1e3, 1),
            cell(m.position_p90_m * 1e3, 1),
            cell(m.force_median_newtons, 2),
            cell(m.force_p90_newtons, 2),
            cell(m.link_accuracy * 100.0, 0),
            cell(m.eps_r_m * 1e3, 1),
            cell(m.eps_f_newtons, 2),
            cell(m.sigma_r_m * 1e3, 1)
        );
        Ok(())
    };
    row("all", &metrics(outcomes))?;
    for (k, m) in metrics_by_sensing_joints(outcomes) {
        row(&k.to_string(), &m)?;
    }
    Ok(())
}
