//! The forward filter's step on a 1 kHz recording (the built-in LWR, 5000
//! samples with patches, the defaults of `estimate`): the part of a long
//! recording that runs in order, and so bounds its speed-up over threads
//! (`docs/decisions.md`, session 67).

// Benchmarks may unwrap: a panic aborts the run with its message.
#![allow(clippy::unwrap_used, missing_docs)]

use criterion::{Criterion, criterion_group, criterion_main};
use proprioscope::core::config::estimator::EstimatorConfig;
use proprioscope::core::eval::synth::{SynthSettings, as_sequence, joint_positions, synthesize};
use proprioscope::core::over_time::offsets::FrameLikelihood;
use proprioscope::core::over_time::sequence::Temporal;
use proprioscope::core::over_time::smoother::FilterState;
use proprioscope::core::robot::builtin;

fn filter(c: &mut Criterion) {
    let robot = builtin::lwr4plus_generated().unwrap();
    let pressed: Vec<_> = ["lwr_5_link", "lwr_6_link"]
        .iter()
        .map(|name| robot.link_id(name).unwrap())
        .collect();
    let settings = SynthSettings {
        duration_secs: 2.0,
        rate_hz: 1000.0,
        ..SynthSettings::default()
    };
    let frames = synthesize(&robot, &pressed, &settings, 1).unwrap();
    let positions = joint_positions(&robot, &frames).unwrap();
    let sequence = as_sequence(&frames, &positions);
    let config = EstimatorConfig::default();
    let estimator = config
        .estimator(&robot, robot.default_candidate_links(), Temporal::Smooth)
        .unwrap();
    let model = config
        .temporal_model(&estimator.surface, estimator.uses_patches())
        .unwrap();
    // Every 2nd frame of the first 400 ms (each a step of 2 ms), a press
    // among them.
    let steps: Vec<(f64, FrameLikelihood)> = sequence
        .iter()
        .step_by(2)
        .take(200)
        .map(|f| {
            let (_, likelihood) = estimator.update_for_sequence(&robot, f.joint_positions, f.tau).unwrap();
            (f.t_secs, likelihood)
        })
        .collect();
    c.bench_function("filter: 200 steps of 2 ms", |b| {
        b.iter(|| {
            let mut state = FilterState::default();
            for (t, likelihood) in &steps {
                state.step(&model, *t, likelihood).unwrap();
            }
        });
    });
}

criterion_group!(benches, filter);
criterion_main!(benches);
