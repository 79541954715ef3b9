//! Synthetic sessions: any settings (durations, rates, ranges, slides,
//! kinetic friction, an observer, two contacts, covered faces) and any
//! seed give frames whose times, angles, torques and true contacts are
//! finite, as many as the settings ask, or an error naming a setting;
//! never a panic.
#![no_main]

use std::sync::OnceLock;

use proprioscope::core::eval::synth::{ObserverSim, SynthSettings, synthesize};
use proprioscope::core::robot::builtin;
use proprioscope::core::robot::model::Robot;

/// The most frames one input may ask for (the time grows with them).
const MAX_FRAMES: f64 = 400.0;

fn robot() -> &'static Robot {
    static ROBOT: OnceLock<Robot> = OnceLock::new();
    ROBOT.get_or_init(|| {
        let Ok(robot) = builtin::lwr4plus_generated() else {
            std::process::abort()
        };
        robot
    })
}

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let Some((flags, rest)) = data.split_first() else {
        return;
    };
    let n: Vec<f64> = rest
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap_or([0; 8])))
        .collect();
    let Some(n) = n.get(..24) else {
        return;
    };
    let robot = robot();
    let candidates = robot.default_candidate_links();
    // Which links are pressed: the bits of the seed's low byte (none
    // chosen: all of them).
    let seed = n[0].to_bits();
    let mut links: Vec<_> = candidates
        .iter()
        .enumerate()
        .filter(|(i, _)| (seed >> (i % 8)) & 1 == 1)
        .map(|(_, l)| *l)
        .collect();
    if links.is_empty() {
        links = candidates;
    }
    let settings = SynthSettings {
        duration_secs: n[1],
        rate_hz: n[2],
        press_secs: (n[3], n[4]),
        gap_secs: (n[5], n[6]),
        force_newtons: (n[7], n[8]),
        ramp_secs: n[9],
        slide_m_per_s: n[10],
        slide_min_m_per_s: n[11],
        friction: n[12],
        bias_newton_metres: n[13],
        noise_newton_metres: n[14],
        motion_rad: n[15],
        min_torque_newton_metres: n[16],
        observer: (flags & 1 == 1).then_some(ObserverSim {
            gain_per_s: n[17],
            mass_error: n[18],
            com_error_m: n[19],
            coulomb_nm: (n[20], n[21]),
            viscous_nms_per_rad: (n[20], n[21]),
            motor_side: flags & 2 == 2,
        }),
        kinetic_friction: (flags & 4 == 4).then_some((n[22], n[23])),
        contacts_at_once: usize::from(flags >> 4 & 3),
        avoid_covered: flags & 8 == 8,
    };
    let frames = (settings.duration_secs * settings.rate_hz).floor();
    if !(frames <= MAX_FRAMES) {
        return;
    }
    let Ok(session) = synthesize(robot, &links, &settings, seed) else {
        return;
    };
    assert_eq!(session.len() as f64, frames);
    for f in &session {
        assert!(f.t_secs.is_finite(), "{f:?}");
        assert!(f.q.iter().chain(&f.tau).all(|x| x.is_finite()), "{f:?}");
        for c in f.contacts() {
            assert!(
                c.point_in_link.is_finite()
                    && c.point_world.is_finite()
                    && c.force_world.is_finite()
                    && c.normal_newtons.is_finite(),
                "{f:?}"
            );
        }
    }
});
