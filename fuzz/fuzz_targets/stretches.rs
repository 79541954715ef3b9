//! The smoother of a recording in stretches: any frames (times that may go
//! backwards or be NaN, likelihoods of any value, a store of any size)
//! give beliefs that are probabilities, or an error; never a panic, and
//! the store never holds more than its limit.
#![no_main]

use std::sync::OnceLock;

use proprioscope::core::over_time::offsets::FrameLikelihood;
use proprioscope::core::over_time::stretches::StretchSmoother;
use proprioscope::core::over_time::temporal::{TemporalModel, TemporalSettings};
use proprioscope::core::robot::builtin;
use proprioscope::core::surface::sampling::{Surface, SurfaceRequest};

/// Samples of the model's surface.
const POINTS: usize = 12;

/// The temporal model of about 12 samples of the built-in LWR.
fn model() -> &'static TemporalModel {
    static MODEL: OnceLock<TemporalModel> = OnceLock::new();
    MODEL.get_or_init(|| {
        let Ok(robot) = builtin::lwr4plus_generated() else {
            std::process::abort()
        };
        let request = SurfaceRequest {
            links: robot.default_candidate_links(),
            total_points: POINTS,
            seed: 0,
        };
        let Ok(surface) = Surface::sample(&robot, &request) else {
            std::process::abort()
        };
        let Ok(model) = TemporalModel::new(&surface, TemporalSettings::default(), false) else {
            std::process::abort()
        };
        model
    })
}

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let Some((&limit_frames, rest)) = data.split_first() else {
        return;
    };
    let model = model();
    let samples = model.graph().len();
    let numbers: Vec<f64> = rest
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap_or([0; 8])))
        .collect();
    // Each frame: an interval, the no-contact likelihood, one per sample.
    let limit_bytes = usize::from(limit_frames) * 200;
    let mut smoother = StretchSmoother::new(model, limit_bytes);
    let mut t = 0.0;
    let check = |beliefs: &proprioscope::core::over_time::stretches::Stretch| {
        for i in 0..beliefs.len() {
            let Some(b) = beliefs.belief(i) else {
                panic!("belief {i} of {} missing", beliefs.len())
            };
            let p = b.contact_probability();
            assert!((0.0..=1.0).contains(&p) && (0.0..=1.0).contains(&b.no_contact), "{b:?}");
        }
    };
    for frame in numbers.chunks_exact(samples + 2) {
        t += frame[0];
        let likelihood = FrameLikelihood {
            no_contact: frame[1],
            points: frame[2..].to_vec(),
            patch: Vec::new(),
        };
        match smoother.push(t, likelihood) {
            Ok(Some(piece)) => check(&piece.smooth(model)),
            Ok(None) => {}
            Err(_) => return,
        }
        assert!(smoother.held_bytes() <= limit_bytes);
    }
    if let Ok(pieces) = smoother.finish() {
        for piece in pieces {
            check(&piece.smooth(model));
        }
    }
});
