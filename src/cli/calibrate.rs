//! `proprioscope calibrate RECORDING`: learns what a robot's torques carry
//! besides contacts (the observer's lag, the model's inertial error, joint
//! friction, offsets) from a recording's free motion, prints it per joint
//! and saves it for `estimate --calibration FILE`; and the same learning
//! for `estimate` itself (`--calibrate auto`, `--sigma auto`).

use std::path::{Path, PathBuf};

use anyhow::Result;
use proprioscope::batch::calibration::{corrected, learn, learned_sigma};
use proprioscope::batch::session_robot;
use proprioscope::core::config::estimator::TorqueModel;
use proprioscope::core::over_time::calibration::{
    Calibration, CalibrationError, CalibrationSettings, ObserverGain, STICTION_SPEED_RAD_S,
};
use proprioscope::core::over_time::sequence::Temporal;
use proprioscope::core::robot::model::Robot;
use proprioscope::io::calibration::CalibrationFile;
use proprioscope::io::session::Session;

use super::{TopicArgs, gain_arg, open_session};

/// Options of `calibrate`.
#[derive(Debug, clap::Args)]
pub struct CalibrateArgs {
    /// A session file or robot recording with stretches of free motion.
    pub session: PathBuf,
    /// The robot (built-in name or URDF), overriding the session's. A URDF
    /// with inertials lets the inertial error be learned too.
    #[arg(long)]
    pub robot: Option<String>,
    /// Extra folder for `package://` URIs (repeatable).
    #[arg(long = "package-path")]
    pub package_paths: Vec<PathBuf>,
    /// Write the calibration here (JSON, e.g. `robot.calib.json`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// The momentum observer's gain K, 1/s: `auto` estimates it, `none`
    /// says there is no lag (valid: (0, 10000] 1/s).
    #[arg(long, default_value = "auto", value_parser = gain_arg)]
    pub observer_gain: ObserverGain,
    /// Every frame is free motion (a recording made to calibrate, with
    /// nothing touching the arm): every frame fits, none is gated out.
    #[arg(long)]
    pub free_motion: bool,
    /// Topics of a recording.
    #[command(flatten)]
    pub topics: TopicArgs,
}

/// Runs the command.
pub fn run(args: &CalibrateArgs) -> Result<()> {
    let (session, problems) = open_session(&args.session, &args.topics)?;
    for p in &problems {
        log::warn!("{}: skipped {p}", args.session.display());
    }
    let robot = session_robot(&session, args.robot.as_deref(), &args.package_paths, &[])?;
    let settings = CalibrationSettings {
        observer_gain: args.observer_gain,
        free_motion: args.free_motion,
        ..CalibrationSettings::default()
    };
    let torques: Vec<Vec<f64>> = session.frames.iter().map(|f| f.tau.clone()).collect();
    let calibration = learn(&robot, (&session.path, &session.frames), &torques, &settings)?;
    print_calibration(&robot, &calibration)?;
    if let Some(out) = &args.out {
        let robot_name = args.robot.clone().or_else(|| session.robot.clone()).unwrap_or_default();
        let links = robot.links.iter().map(|l| l.name.clone()).collect();
        CalibrationFile::new(&calibration, &robot_name, links).write(out)?;
        outln!("calibration written to {}", out.display());
    }
    Ok(())
}

/// The calibration per joint, on stdout.
pub fn print_calibration(robot: &Robot, c: &Calibration) -> Result<()> {
    let gain = c.observer_gain_per_s.map_or_else(
        || "none (no lag)".to_owned(),
        |k| format!("{k} 1/s (lag {:.0} ms)", 1e3 / k),
    );
    outln!(
        "calibration: {} of {} frames free; observer gain {gain}; {}",
        c.free_frames,
        c.frames_read,
        if c.found {
            if c.inertial_corrections.is_empty() {
                "friction and offsets learned (the robot has no inertials)"
            } else {
                "inertial error, friction and offsets learned"
            }
        } else {
            "no model error found beyond noise: nothing taken off"
        }
    );
    outln!(
        "| joint | RMS before [N·m] | RMS after [N·m] | σ without the lag [N·m] | its correlation [ms] | Coulomb [N·m] | its lead [ms] | its switch [rad/s] | viscous [N·m·s/rad] | offset [N·m] |"
    );
    outln!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for (j, name) in robot.sensed_names().iter().enumerate() {
        outln!(
            "| {name} | {:.4} | {:.4} | {:.4} | {:.1} | {:.3} | {:.0} | {:.3} | {:.3} | {:+.4} |",
            c.rms_before_nm[j],
            c.rms_after_nm[j],
            c.sigma_nm[j],
            c.correlation_secs[j] * 1e3,
            c.coulomb_nm[j],
            c.coulomb_lead_secs.get(j).copied().unwrap_or(0.0) * 1e3,
            c.coulomb_switch_rad_s.get(j).copied().unwrap_or(STICTION_SPEED_RAD_S),
            c.viscous_nms_per_rad[j],
            c.offset_nm[j]
        );
    }
    Ok(())
}

/// What `estimate` takes as torques and σ: the session's torques less
/// the calibration's model error (from `file`, or learned where `model`
/// says so on a `recording` or frames combined over `temporal`), and σ
/// learned per joint where `model` says so (else `sigma`; widened for
/// the correlation over time unless frames are alone). Said on stdout.
pub fn torques_and_sigma(
    robot: &Robot,
    session: &Session,
    torques: Vec<Vec<f64>>,
    sigma: Vec<f64>,
    model: &TorqueModel,
    (temporal, recording): (Temporal, bool),
    file: Option<&Path>,
) -> Result<(Vec<Vec<f64>>, Vec<f64>)> {
    let over_time = temporal != Temporal::None;
    let calibration = if let Some(path) = file {
        let links: Vec<String> = robot.links.iter().map(|l| l.name.clone()).collect();
        let c = CalibrationFile::read(path, &links)?;
        if c.joints != robot.sensed_names() {
            anyhow::bail!(
                "{}: calibrated joints {} are not the session's {}",
                path.display(),
                c.joints.join(", "),
                robot.sensed_names().join(", ")
            );
        }
        Some(c)
    } else if (over_time || recording) && (model.calibrate || model.sigma_auto) {
        match learn(robot, (&session.path, &session.frames), &torques, &model.calibration) {
            Ok(c) => Some(c),
            Err(e) => {
                let held = matches!(
                    e.downcast_ref::<CalibrationError>(),
                    Some(CalibrationError::NoMotion { .. })
                );
                if held {
                    log::info!("{e:#}: torques taken as they are, σ as given");
                } else {
                    log::warn!("{e:#}: torques taken as they are, σ as given");
                }
                None
            }
        }
    } else {
        None
    };
    let Some(calibration) = calibration else {
        return Ok((torques, sigma));
    };
    print_calibration(robot, &calibration)?;
    let apply = file.is_some() || model.calibrate;
    let torques = if apply {
        corrected(robot, (&session.path, &session.frames), &calibration, &torques)?
    } else {
        torques
    };
    if !model.sigma_auto {
        return Ok((torques, sigma));
    }
    let learned = learned_sigma(&calibration, &session.frames, apply, over_time);
    outln!(
        "σ (learned, N·m{}): {}",
        if over_time {
            ", widened for the residual's correlation over time"
        } else {
            ""
        },
        robot
            .sensed_names()
            .iter()
            .zip(&learned)
            .map(|(n, s)| format!("{n} {s:.4}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok((torques, learned))
}
