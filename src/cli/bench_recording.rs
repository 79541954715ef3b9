//! `proprioscope bench --recording SECONDS --rate HZ`: a long recording
//! smoothed at robot rates, for each thread count: wall time, frames per
//! second, real-time factor, peak memory and the smoothed accuracy.

use std::fmt::Write as _;
use std::time::Instant;

use anyhow::{Context as _, Result, anyhow};
use proprioscope::core::config::estimator::EstimatorConfig;
use proprioscope::core::estimate::summary::Verdict;
use proprioscope::core::eval::metrics::{detection, percentile};
use proprioscope::core::eval::synth::{SynthSettings, as_sequence, joint_positions, synthesize};
use proprioscope::core::over_time::sequence::{Temporal, estimate_sequence};
use proprioscope::core::robot::builtin;

/// The links a recording is pressed on: the forearm and wrist (links 4–7).
const PRESSED_LINKS: [&str; 4] = ["lwr_4_link", "lwr_5_link", "lwr_6_link", "lwr_7_link"];

/// What `bench --recording` draws and runs.
pub struct RecordingBench {
    /// Length, s.
    pub seconds: f64,
    /// Frames per second.
    pub rate_hz: f64,
    /// Sensor noise (and σ), N·m.
    pub noise: f64,
    /// Seed of the recording.
    pub seed: u64,
    /// Thread counts (empty: 1, 2 and every core).
    pub threads: Vec<usize>,
    /// Memory the smoothing may take, MiB.
    pub memory_mib: usize,
}

/// One thread count's run.
struct Run {
    threads: usize,
    wall_secs: f64,
    peak_mib: Option<f64>,
    /// Processor time of all threads over wall time and thread count, %.
    busy_percent: Option<f64>,
    detection_percent: f64,
    false_alarm_percent: f64,
    median_mm: f64,
    p90_mm: f64,
}

/// Runs the recording bench and prints its table.
pub fn run(args: &RecordingBench) -> Result<()> {
    let seconds = args.seconds;
    let robot = builtin::lwr4plus_generated().context("the built-in LWR")?;
    let pressed = PRESSED_LINKS
        .iter()
        .map(|name| robot.link_id(name).with_context(|| format!("link {name}")))
        .collect::<Result<Vec<_>>>()?;
    let settings = SynthSettings {
        duration_secs: seconds,
        rate_hz: args.rate_hz,
        noise_newton_metres: args.noise,
        ..SynthSettings::default()
    };
    let t0 = Instant::now();
    let frames = synthesize(&robot, &pressed, &settings, args.seed).context("synthesising the recording")?;
    let positions = joint_positions(&robot, &frames).context("the recording's joint positions")?;
    let sequence = as_sequence(&frames, &positions);
    log::info!(
        "{} frames ({seconds} s at {} Hz, seed {}) drawn in {:.1} s",
        frames.len(),
        args.rate_hz,
        args.seed,
        t0.elapsed().as_secs_f64()
    );
    // σ is the noise drawn (no calibration: the estimator alone is timed).
    let config = EstimatorConfig {
        memory_mib: args.memory_mib,
        ..EstimatorConfig::default()
    };
    let links = robot.default_candidate_links();
    let estimator = config.estimator(&robot, links, Temporal::Smooth)?;
    let model = config.temporal_model(&estimator.surface, estimator.uses_patches())?;
    let all = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
    let mut counts = if args.threads.is_empty() {
        vec![1, 2, all]
    } else {
        args.threads.clone()
    };
    counts.sort_unstable();
    counts.dedup();
    let truth: Vec<Option<bool>> = frames.iter().map(|f| Some(f.contact.is_some())).collect();
    let mut runs = Vec::new();
    for threads in counts {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build()?;
        reset_peak_memory();
        let mut called = vec![false; frames.len()];
        let mut errors_m = Vec::new();
        let cpu0 = cpu_secs();
        let t0 = Instant::now();
        pool.install(|| {
            estimate_sequence(
                &estimator,
                &robot,
                Some(&model),
                Temporal::Smooth,
                &sequence,
                |i, update, _| {
                    let contact = update.summary.verdict != Verdict::NoContact;
                    if let Some(c) = called.get_mut(i) {
                        *c = contact;
                    }
                    if let Some(truth) = frames.get(i).and_then(|f| f.contact) {
                        errors_m.push(update.summary.map.point_world.distance(truth.point_world));
                    }
                },
            )
        })?;
        let wall_secs = t0.elapsed().as_secs_f64();
        let busy_percent = cpu0
            .zip(cpu_secs())
            .map(|(before, after)| 100.0 * (after - before) / (wall_secs * threads as f64));
        let found = detection(&truth, &called);
        runs.push(Run {
            threads,
            wall_secs,
            peak_mib: peak_memory_mib(),
            busy_percent,
            detection_percent: 100.0 * found.detection_rate(),
            false_alarm_percent: 100.0 * found.false_alarm_rate(),
            median_mm: 1e3 * percentile(&errors_m, 0.5),
            p90_mm: 1e3 * percentile(&errors_m, 0.9),
        });
        log::info!("{threads} threads: {wall_secs:.1} s");
    }
    let recorded_secs = frames.last().map_or(0.0, |f| f.t_secs) + 1.0 / args.rate_hz;
    outln!("{}", table(&runs, frames.len(), recorded_secs)?);
    Ok(())
}

/// The runs as a Markdown table.
fn table(runs: &[Run], frames: usize, recorded_secs: f64) -> Result<String> {
    let one = runs
        .iter()
        .find(|r| r.threads == 1)
        .map(|r| r.wall_secs)
        .ok_or_else(|| anyhow!("no run"));
    let mut out = String::new();
    writeln!(
        out,
        "| threads | wall [s] | frames/s | real-time factor | speed-up | peak memory [MiB] | threads busy | detection | false alarms | median [mm] | p90 [mm] |"
    )?;
    writeln!(out, "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")?;
    for r in runs {
        let speedup = one
            .as_ref()
            .map_or_else(|_| "–".to_owned(), |one| format!("{:.2}×", one / r.wall_secs));
        writeln!(
            out,
            "| {} | {:.1} | {:.0} | {:.2} | {speedup} | {} | {} | {:.1} % | {:.1} % | {:.1} | {:.1} |",
            r.threads,
            r.wall_secs,
            frames as f64 / r.wall_secs,
            recorded_secs / r.wall_secs,
            r.peak_mib.map_or_else(|| "–".to_owned(), |m| format!("{m:.0}")),
            r.busy_percent.map_or_else(|| "–".to_owned(), |b| format!("{b:.0} %")),
            r.detection_percent,
            r.false_alarm_percent,
            r.median_mm,
            r.p90_mm
        )?;
    }
    Ok(out)
}

/// Resets the process's peak resident memory (Linux; elsewhere nothing).
fn reset_peak_memory() {
    // "5" resets the peak resident set size (proc(5)); where it cannot be
    // written, the peak is the process's so far.
    if let Err(e) = std::fs::write("/proc/self/clear_refs", "5") {
        log::debug!("peak memory not reset: {e}");
    }
}

/// The process's peak resident memory since the last reset, MiB (Linux).
fn peak_memory_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

/// The processor time the process's threads have taken, user and system,
/// s (Linux; elsewhere `None`). With the wall time and thread count it
/// says how much of the pool waited: the share that runs in order shows
/// as threads idle.
fn cpu_secs() -> Option<f64> {
    // proc(5): the fields after the command's closing parenthesis, from
    // the state (field 3); utime and stime are fields 14 and 15, in
    // USER_HZ ticks, 100 a second on Linux.
    const TICKS_PER_SEC: f64 = 100.0;
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    let after_name = stat.rsplit_once(')')?.1;
    let mut fields = after_name.split_whitespace().skip(11);
    let user: f64 = fields.next()?.parse().ok()?;
    let system: f64 = fields.next()?.parse().ok()?;
    Some((user + system) / TICKS_PER_SEC)
}
