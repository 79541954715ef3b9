//! Recordings of any length: the smoother in stretches against the whole
//! recording's smoother on a real surface, the same estimates on any
//! number of threads, and every recording smoothed.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use proprioscope::core::config::estimator::EstimatorConfig;
use proprioscope::core::estimate::estimator::Estimator;
use proprioscope::core::eval::synth::{SynthFrame, SynthSettings, as_sequence, joint_positions, synthesize};
use proprioscope::core::over_time::offsets::FrameLikelihood;
use proprioscope::core::over_time::sequence::{
    Temporal, automatic_temporal, estimate_sequence, estimate_sequence_while,
};
use proprioscope::core::over_time::smoother::Smoother;
use proprioscope::core::over_time::stretches::StretchSmoother;
use proprioscope::core::over_time::temporal::{Belief, TemporalModel, TemporalSettings};
use proprioscope::core::robot::builtin;
use proprioscope::core::robot::model::Robot;

/// A recording of `seconds` at 1 kHz pressed on links 4–7, and an
/// estimator of 1,000 surface points with its temporal model.
fn recording(seconds: f64, seed: u64) -> (Robot, Vec<SynthFrame>, Estimator, TemporalModel) {
    let robot = builtin::lwr4plus_generated().unwrap();
    let links: Vec<usize> = ["lwr_4_link", "lwr_5_link", "lwr_6_link", "lwr_7_link"]
        .iter()
        .map(|n| robot.link_id(n).unwrap())
        .collect();
    let settings = SynthSettings {
        duration_secs: seconds,
        rate_hz: 1000.0,
        ..SynthSettings::default()
    };
    let frames = synthesize(&robot, &links, &settings, seed).unwrap();
    let config = EstimatorConfig {
        surface_points: 1000,
        ..EstimatorConfig::default()
    };
    let estimator = config
        .estimator(&robot, robot.default_candidate_links(), Temporal::Smooth)
        .unwrap();
    let model = config
        .temporal_model(&estimator.surface, estimator.uses_patches())
        .unwrap();
    (robot, frames, estimator, model)
}

/// Each frame's belief from a smoother in stretches holding `limit_bytes`,
/// and how many pieces it cut.
fn in_stretches(
    model: &TemporalModel,
    times: &[f64],
    likelihoods: &[FrameLikelihood],
    limit_bytes: usize,
) -> (Vec<Belief>, usize) {
    let mut smoother = StretchSmoother::new(model, limit_bytes);
    let mut out = Vec::new();
    let mut pieces = 0;
    for (t, l) in times.iter().zip(likelihoods) {
        if let Some(piece) = smoother.push(*t, l.clone()).unwrap() {
            pieces += 1;
            let stretch = piece.smooth(model);
            assert_eq!(stretch.first, out.len());
            out.extend((0..stretch.len()).map(|i| stretch.belief(i).unwrap()));
        }
        assert!(smoother.held_bytes() <= limit_bytes);
    }
    for piece in smoother.finish().unwrap() {
        let stretch = piece.smooth(model);
        out.extend((0..stretch.len()).map(|i| stretch.belief(i).unwrap()));
    }
    (out, pieces)
}

/// The most probable sample of a belief.
fn best(belief: &Belief) -> usize {
    belief
        .points
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .map_or(0, |(k, _)| k)
}

/// On a generated 1 kHz recording with offsets tracked (the two-filter
/// smoother), stretches cut where the filter is sure of no contact give
/// the whole recording's contact probability (within 1e-3) and most
/// probable place at every frame; a store of 400 frames, cut inside
/// presses, still calls every frame the same way and places the contact
/// within 10 mm of the whole recording's in 99 % of the pressed frames.
#[test]
fn stretches_give_the_whole_recordings_beliefs() {
    let (robot, frames, estimator, model) = recording(3.0, 4);
    let positions = joint_positions(&robot, &frames).unwrap();
    let times: Vec<f64> = frames.iter().map(|f| f.t_secs).collect();
    let likelihoods: Vec<FrameLikelihood> = frames
        .iter()
        .zip(&positions)
        .map(|(f, p)| estimator.update_for_sequence(&robot, p, &f.tau).unwrap().1)
        .collect();
    let mut whole = Smoother::new(&model);
    for (t, l) in times.iter().zip(&likelihoods) {
        whole.push(*t, l).unwrap();
    }
    let whole = whole.finish().unwrap();
    let pressed = whole.iter().filter(|b| b.contact_probability() > 0.5).count();
    assert!(pressed > 500, "{pressed} pressed frames");

    let (quiet, pieces) = in_stretches(&model, &times, &likelihoods, 1 << 30);
    assert!(pieces >= 2, "{pieces} quiet cuts");
    for (i, (a, b)) in quiet.iter().zip(&whole).enumerate() {
        let (pa, pb) = (a.contact_probability(), b.contact_probability());
        assert!((pa - pb).abs() < 1e-3, "frame {i}: {pa} vs {pb}");
        if pb > 0.5 {
            assert_eq!(best(a), best(b), "frame {i}");
        }
    }

    // A store of 400 frames: cut inside presses, with 100 ms passed back over.
    let surface = &estimator.surface;
    let apart_m = |a: usize, b: usize| {
        if surface.link.get(a) == surface.link.get(b) {
            surface.point_in_link[a].distance(surface.point_in_link[b])
        } else {
            f64::INFINITY
        }
    };
    let frame_bytes = 1001 * 52;
    let (forced, pieces) = in_stretches(&model, &times, &likelihoods, 400 * frame_bytes);
    assert!(pieces > 5, "{pieces} cuts in a small store");
    let mut near = 0;
    for (i, (a, b)) in forced.iter().zip(&whole).enumerate() {
        let (pa, pb) = (a.contact_probability(), b.contact_probability());
        assert_eq!(pa > 0.5, pb > 0.5, "frame {i}: {pa} vs {pb}");
        if pb > 0.5 && apart_m(best(a), best(b)) <= 0.01 {
            near += 1;
        }
    }
    assert!(
        near * 100 >= 99 * pressed,
        "{near} of {pressed} pressed frames within 10 mm"
    );
}

/// One thread, two, or four (where the filter runs on a thread of its
/// own), the estimates of a smoothed and a filtered recording are the
/// same, frame for frame; also with a store so small that the memory
/// limit holds the filter back and cuts stretches by force.
#[test]
fn threads_do_not_change_the_estimates() {
    let (robot, frames, estimator, model) = recording(1.5, 5);
    let positions = joint_positions(&robot, &frames).unwrap();
    let sequence = as_sequence(&frames, &positions);
    let small = model.clone().with_store_limit(150 * 1001 * 52);
    for (temporal, model) in [
        (Temporal::Smooth, &model),
        (Temporal::Filter, &model),
        (Temporal::Smooth, &small),
    ] {
        let runs: Vec<Vec<(usize, String)>> = [1, 2, 4]
            .iter()
            .map(|&threads| {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                let mut out = Vec::new();
                pool.install(|| {
                    estimate_sequence(&estimator, &robot, Some(model), temporal, &sequence, |i, update, _| {
                        let s = &update.summary;
                        out.push((
                            i,
                            format!(
                                "{:?} {} {:.9} {:?}",
                                s.verdict, s.map.point, s.map.force_newtons, s.contact_probability
                            ),
                        ));
                    })
                })
                .unwrap();
                out
            })
            .collect();
        assert_eq!(runs[0].len(), frames.len(), "{temporal:?}");
        assert!(runs[0].windows(2).all(|w| w[0].0 < w[1].0), "{temporal:?}: in order");
        assert_eq!(runs[0], runs[1], "{temporal:?}, two threads");
        assert_eq!(runs[0], runs[2], "{temporal:?}, four threads");
    }
}

/// A recording is smoothed whatever its length (a 10-minute one at 1 kHz
/// was filtered, too long to smooth in memory).
#[test]
fn every_recording_is_smoothed() {
    let times: Vec<f64> = (0..600_000).map(|i| f64::from(i) * 1e-3).collect();
    let (temporal, _) = automatic_temporal(&times, &TemporalSettings::default());
    assert_eq!(temporal, Temporal::Smooth);
}

/// Frames handed on, frames failed, the error where none is skipped,
/// frames handed on before a stop.
type Outcome = (Vec<usize>, Vec<usize>, String, Vec<usize>);

/// On any number of threads, a frame whose estimate fails is handed to
/// `failed`: left out where it says so (the others as without it, in
/// order), else the sequence's error, naming it; and a sequence that
/// `keep_going` stops ends with what it has handed on, in order.
#[test]
fn failed_frames_and_a_stop_on_any_number_of_threads() {
    let (robot, frames, estimator, model) = recording(1.0, 7);
    let positions = joint_positions(&robot, &frames).unwrap();
    let bad_tau = vec![f64::NAN; 7];
    let mut sequence = as_sequence(&frames, &positions);
    let bad = 300;
    sequence[bad].tau = &bad_tau;
    let runs: Vec<Outcome> = [1, 2, 4]
        .iter()
        .map(|&threads| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let (mut out, mut failed) = (Vec::new(), Vec::new());
                let skipped = estimate_sequence_while(
                    &estimator,
                    &robot,
                    (Some(&model), Temporal::Smooth),
                    &sequence,
                    || true,
                    |i, _, _| out.push(i),
                    |i, _| {
                        failed.push(i);
                        true
                    },
                );
                assert_eq!(skipped, Ok(true), "{threads} threads");
                let refused = estimate_sequence_while(
                    &estimator,
                    &robot,
                    (Some(&model), Temporal::Smooth),
                    &sequence,
                    || true,
                    |_, _, _| {},
                    |_, _| false,
                )
                .unwrap_err()
                .to_string();
                let mut calls = 0;
                let mut stopped = Vec::new();
                let kept_going = estimate_sequence_while(
                    &estimator,
                    &robot,
                    (Some(&model), Temporal::Smooth),
                    &sequence,
                    || {
                        calls += 1;
                        calls < 8
                    },
                    |i, _, _| stopped.push(i),
                    |_, _| true,
                );
                assert_eq!(kept_going, Ok(false), "{threads} threads");
                (out, failed, refused, stopped)
            })
        })
        .collect();
    for (threads, (out, failed, refused, stopped)) in [1, 2, 4].iter().zip(&runs) {
        assert_eq!(failed, &vec![bad], "{threads} threads");
        assert_eq!(out.len(), frames.len() - 1, "{threads} threads");
        assert!(!out.contains(&bad), "{threads} threads");
        assert!(out.windows(2).all(|w| w[0] < w[1]), "{threads} threads: in order");
        assert!(
            refused.starts_with(&format!("frame {bad}:")),
            "{threads} threads: {refused}"
        );
        assert!(stopped.len() < out.len(), "{threads} threads: stopped");
        assert!(stopped.windows(2).all(|w| w[0] < w[1]), "{threads} threads: in order");
    }
    assert_eq!(runs[0].0, runs[2].0);
}
