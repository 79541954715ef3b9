//! `bench --session`: one session's frames estimated by each estimator
//! (alone, filtered, smoothed, at the file's and the live surface), each
//! frame timed by the fastest of `--repeat` runs, per surface seed: the
//! per-frame p50 and p99 against the median position error.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Result;
use glam::DVec3;
use proprioscope::batch::credible_set_holds_truth;
use proprioscope::core::config::estimator::LIVE_SURFACE_POINTS;
use proprioscope::core::estimate::estimator::{Estimator, StageTimes, Update};
use proprioscope::core::estimate::settings::EstimatorSettings;
use proprioscope::core::eval::metrics::{detection, percentile};
use proprioscope::core::over_time::frame::SequenceFrame;
use proprioscope::core::over_time::sequence::{Temporal, estimate_sequence};
use proprioscope::core::over_time::temporal::{TemporalModel, TemporalSettings, is_continuous_recording};
use proprioscope::core::robot::model::Robot;
use proprioscope::core::surface::sampling::SurfaceRequest;

/// What `bench --session` takes of `bench`'s options.
#[derive(Debug, Clone, Copy)]
pub struct SessionBench<'a> {
    /// Extra folders for `package://` URIs.
    pub package_paths: &'a [PathBuf],
    /// Coarser surfaces to add a refined row each for.
    pub session_points: &'a [u64],
    /// Surface seeds.
    pub seeds: &'a [u64],
    /// The σ the estimators take, N·m.
    pub noise: f64,
    /// Runs of each frame, the fastest kept.
    pub repeat: u32,
}

/// One estimator on a session: per-frame times over all seeds, and the
/// median position error at each seed.
struct SessionRun {
    label: &'static str,
    points: usize,
    times_us: Vec<f64>,
    /// The times of frames whose truth says no contact, and of those with one.
    quiet_times_us: Vec<f64>,
    contact_times_us: Vec<f64>,
    medians_m: Vec<f64>,
    poor_fit: usize,
    frames: usize,
    detected: usize,
    contact_frames: usize,
    false_alarms: usize,
    quiet_frames: usize,
    /// Contact frames whose 90 % credible set holds the push (the sample
    /// whose patch holds it), and those where that could be told.
    held: usize,
    owned: usize,
    /// Frames alone: each frame's posterior, refinement and summary
    /// times, µs (empty over time, where the stages interleave).
    stage_times_us: Vec<[f64; 3]>,
    /// Smoothed, on a session with two true contacts at once: the
    /// two-contact search's score at each surface seed.
    pair_scores: Vec<(u64, proprioscope::batch::pairs::PairScore)>,
}

/// Per-frame p50/p99 and the spread of the median error over surface
/// seeds, on one recorded session, for the refined estimator and the
/// grid of points it refines (at the same and at seven times the points).
pub(super) fn session_table(path: &Path, args: &SessionBench<'_>) -> Result<String> {
    use proprioscope::batch::session_robot;
    use proprioscope::io::session::Session;
    let session = Session::read(path)?;
    let robot = session_robot(&session, None, args.package_paths, &[])?;
    let two_contacts = super::bench_pairs::has_two_contacts(&session);
    let mut runs = Vec::new();
    let coarser = args
        .session_points
        .iter()
        .filter_map(|&n| usize::try_from(n).ok())
        .map(|n| ("refined (patches)", n, true, Temporal::None));
    let estimators = [
        ("refined (patches)", 5000, true, Temporal::None),
        ("filtered over time", 5000, true, Temporal::Filter),
        // What `estimate --live` and the app listening take by default.
        ("filtered over time", LIVE_SURFACE_POINTS, true, Temporal::Filter),
        ("smoothed over time", 5000, true, Temporal::Smooth),
        ("grid of points", 5000, false, Temporal::None),
        ("grid of points", 35_000, false, Temporal::None),
    ]
    .into_iter()
    .chain(coarser);
    for (label, points, patches, temporal) in estimators {
        let mut run = SessionRun {
            label,
            points,
            times_us: Vec::new(),
            quiet_times_us: Vec::new(),
            contact_times_us: Vec::new(),
            medians_m: Vec::new(),
            poor_fit: 0,
            frames: 0,
            detected: 0,
            contact_frames: 0,
            false_alarms: 0,
            quiet_frames: 0,
            held: 0,
            owned: 0,
            stage_times_us: Vec::new(),
            pair_scores: Vec::new(),
        };
        let positions = session
            .frames
            .iter()
            .map(|frame| robot.joint_positions(&frame.q, &[]))
            .collect::<Result<Vec<_>, _>>()?;
        let sequence: Vec<SequenceFrame> = session
            .frames
            .iter()
            .zip(&positions)
            .map(|(frame, joint_positions)| SequenceFrame {
                t_secs: frame.t,
                joint_positions,
                tau: &frame.tau,
            })
            .collect();
        let times: Vec<f64> = session.frames.iter().map(|f| f.t).collect();
        let truth: Vec<Option<bool>> = session.frames.iter().map(|f| f.truth.has_contact()).collect();
        if temporal != Temporal::None && !is_continuous_recording(&times, &TemporalSettings::default()) {
            // Unrelated frames: nothing to connect over time.
            continue;
        }
        for &seed in args.seeds {
            log::info!("{}: {label}, {points} points, seed {seed} …", path.display());
            let how = How {
                robot: &robot,
                points,
                patches,
                temporal,
                seed,
                sigma: args.noise,
                repeat: args.repeat,
                pairs: two_contacts && temporal == Temporal::Smooth && points == 5000,
            };
            seed_run(&how, &session, &sequence, &truth, &mut run)?;
        }
        runs.push(run);
    }
    Ok(session_text(path, &session, args, &runs))
}

/// The table of a session's runs.
fn session_text(
    path: &Path,
    session: &proprioscope::io::session::Session,
    args: &SessionBench<'_>,
    runs: &[SessionRun],
) -> String {
    use proprioscope::io::session::Truth;
    let name = path
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let timed = if args.repeat > 1 {
        format!(", each frame timed by the fastest of {} runs in a row", args.repeat)
    } else {
        String::new()
    };
    let mut out = format!(
        "`{name}`: {} frames ({} with a contact), σ = {} N·m, one thread ({}), surface seeds {:?}{timed}.\n\n",
        session.frames.len(),
        session
            .frames
            .iter()
            .filter(|f| matches!(f.truth, Truth::Contact { .. }))
            .count(),
        args.noise,
        proprioscope::core::numerics::simd::vector_unit(),
        args.seeds
    );
    out.push_str("| estimator | points | p50 [µs] | p99 [µs] | max [µs] | without contact p50 / p99 [µs] | with a contact p50 / p99 [µs] | median pos. error per seed [mm] | spread [mm] | poorly explained | contact frames called | false alarms | 90 % set holds the push |\n");
    out.push_str("|---|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|\n");
    for r in runs {
        let (lo, hi) = r
            .medians_m
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), m| {
                (lo.min(*m), hi.max(*m))
            });
        let per_seed: Vec<String> = r.medians_m.iter().map(|m| format!("{:.1}", m * 1e3)).collect();
        let _ = writeln!(
            out,
            "| {} | {} | {:.0} | {:.0} | {:.0} | {} | {} | {} | {:.1} | {:.1} % | {:.1} % | {:.1} % | {:.1} % |",
            r.label,
            r.points,
            percentile(&r.times_us, 0.5),
            percentile(&r.times_us, 0.99),
            r.times_us.iter().copied().fold(0.0, f64::max),
            p50_p99(&r.quiet_times_us),
            p50_p99(&r.contact_times_us),
            per_seed.join(", "),
            (hi - lo) * 1e3,
            100.0 * r.poor_fit as f64 / r.frames.max(1) as f64,
            100.0 * r.detected as f64 / r.contact_frames.max(1) as f64,
            100.0 * r.false_alarms as f64 / r.quiet_frames.max(1) as f64,
            100.0 * r.held as f64 / r.owned.max(1) as f64
        );
    }
    stage_text(runs, &mut out);
    for r in runs.iter().filter(|r| !r.pair_scores.is_empty()) {
        out.push_str(&super::bench_pairs::pairs_text(&r.pair_scores));
    }
    out
}

/// Where the time of frames estimated alone goes, per stage: the table
/// under a session's (nothing without such runs).
fn stage_text(runs: &[SessionRun], out: &mut String) {
    let staged: Vec<&SessionRun> = runs.iter().filter(|r| !r.stage_times_us.is_empty()).collect();
    if staged.is_empty() {
        return;
    }
    out.push_str(
        "\nWhere the time of a frame alone goes: the parts of `Estimator::update` over every frame (with `--repeat`, each part timed by its fastest run). A frame's parts add up to a little less than its time above, which also counts handing the frame over; their percentiles do not add up.\n\n",
    );
    out.push_str(
        "| estimator | points | posterior p50 / p99 [µs] | refinement p50 / p99 [µs] | summary p50 / p99 [µs] |\n",
    );
    out.push_str("|---|---:|---:|---:|---:|\n");
    for r in staged {
        let stage = |k: usize| -> Vec<f64> { r.stage_times_us.iter().filter_map(|s| s.get(k).copied()).collect() };
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} |",
            r.label,
            r.points,
            p50_p99(&stage(0)),
            p50_p99(&stage(1)),
            p50_p99(&stage(2))
        );
    }
}

/// `p50 / p99` of `times_us`, or a dash without any.
fn p50_p99(times_us: &[f64]) -> String {
    if times_us.is_empty() {
        "–".to_owned()
    } else {
        format!("{:.0} / {:.0}", percentile(times_us, 0.5), percentile(times_us, 0.99))
    }
}

/// One estimator configuration on a session at one surface seed.
struct How<'a> {
    robot: &'a Robot,
    points: usize,
    patches: bool,
    temporal: Temporal,
    seed: u64,
    sigma: f64,
    /// Runs over the session in a row; each frame is timed by its fastest.
    repeat: u32,
    /// Whether to search the frames for second contacts and score them.
    pairs: bool,
}

/// Runs `how` over `sequence` on one thread and adds its times, errors
/// and detection record to `run`.
fn seed_run(
    how: &How,
    session: &proprioscope::io::session::Session,
    sequence: &[SequenceFrame],
    truth: &[Option<bool>],
    run: &mut SessionRun,
) -> Result<()> {
    use proprioscope::core::estimate::summary::Verdict;
    use proprioscope::io::session::Truth;
    let robot = how.robot;
    // Friction as `estimate` takes it when not told: over time only.
    let settings = EstimatorSettings {
        patches: how.patches,
        friction: how.temporal.default_friction(),
        ..EstimatorSettings::exact(vec![how.sigma; robot.sensed().len()])
    };
    let request = SurfaceRequest {
        links: robot.default_candidate_links(),
        total_points: how.points,
        seed: how.seed,
    };
    let estimator = Estimator::new(robot, &request, settings, None)?;
    let model = match how.temporal {
        Temporal::None => None,
        _ => Some(TemporalModel::new(
            &estimator.surface,
            TemporalSettings::default(),
            estimator.uses_patches(),
        )?),
    };
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    // Every run estimates the frames alike: the runs before the last one
    // only time them, and each frame keeps its fastest time.
    let mut fastest_us: Vec<Option<f64>> = vec![None; sequence.len()];
    let mut fastest_stages_us: Vec<Option<[f64; 3]>> = vec![None; sequence.len()];
    // One run over the session on the one thread, each frame handed to `each`.
    let run_once = |each: &mut (dyn FnMut(usize, Update, f64) + Send)| {
        pool.install(|| estimate_sequence(&estimator, robot, model.as_ref(), how.temporal, sequence, each))
    };
    for _ in 1..how.repeat {
        run_once(&mut |i, update, ms| {
            keep_fastest(&mut fastest_us, i, ms * 1e3);
            keep_fastest_stages(&mut fastest_stages_us, i, update.stages.as_ref());
        })?;
    }
    let (mut errors, mut called) = (Vec::new(), Vec::new());
    let mut singles = super::bench_pairs::Singles::default();
    run_once(&mut |i, update, ms| {
        if how.pairs {
            singles.push(&update);
        }
        let us = keep_fastest(&mut fastest_us, i, ms * 1e3);
        run.times_us.push(us);
        if let Some(stages) = keep_fastest_stages(&mut fastest_stages_us, i, update.stages.as_ref()) {
            run.stage_times_us.push(stages);
        }
        match truth.get(i).copied().flatten() {
            Some(true) => run.contact_times_us.push(us),
            Some(false) => run.quiet_times_us.push(us),
            None => {}
        }
        run.frames += 1;
        run.poor_fit += usize::from(update.summary.verdict == Verdict::PoorFit);
        called.push(update.summary.verdict != Verdict::NoContact);
        if let Some(truth @ Truth::Contact { point, .. }) = session.frames.get(i).map(|f| &f.truth) {
            errors.push(update.summary.map.point_world.distance(DVec3::from_array(*point)));
            if let Some(held) = credible_set_holds_truth(robot, &estimator.surface, &update, truth) {
                run.owned += 1;
                run.held += usize::from(held);
            }
        }
    })?;
    let found = detection(truth, &called);
    run.detected += found.detected;
    run.contact_frames += found.contact_frames;
    run.false_alarms += found.false_alarms;
    run.quiet_frames += found.quiet_frames;
    run.medians_m.push(percentile(&errors, 0.5));
    if how.pairs {
        let score = super::bench_pairs::score_smoothed(&estimator, robot, session, sequence, &singles)?;
        run.pair_scores.push((how.seed, score));
    }
    Ok(())
}

/// Frame `i`'s fastest time, µs: this run's `us` or an earlier run's.
fn keep_fastest(fastest_us: &mut [Option<f64>], i: usize, us: f64) -> f64 {
    match fastest_us.get_mut(i) {
        Some(slot) => *slot.insert(slot.map_or(us, |t| t.min(us))),
        None => us,
    }
}

/// Frame `i`'s fastest time of each stage, µs, as [`keep_fastest`]
/// (`None` where the update has no stages).
fn keep_fastest_stages(fastest_us: &mut [Option<[f64; 3]>], i: usize, stages: Option<&StageTimes>) -> Option<[f64; 3]> {
    let s = stages?;
    let us = [s.posterior_ms, s.refine_ms, s.summary_ms].map(|ms| ms * 1e3);
    Some(match fastest_us.get_mut(i) {
        Some(slot) => *slot.insert(slot.map_or(us, |t| std::array::from_fn(|k| t[k].min(us[k])))),
        None => us,
    })
}
