//! Calibration files: any text gives a checked calibration or an error;
//! a calibration that reads applies to a few frames of the built-in LWR
//! (when it names seven joints) without a panic or a non-finite torque
//! from finite input.
#![no_main]
use proprioscope::core::robot::builtin;
use proprioscope::core::robot::dynamics::RigidBodies;
use proprioscope::io::calibration::CalibrationFile;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let path = std::path::Path::new("fuzz.calib.json");
    let Ok(file) = CalibrationFile::parse(&text, path) else {
        return;
    };
    let Ok(calibration) = file.calibration(path) else {
        return;
    };
    let Ok(robot) = builtin::lwr4plus_kinematics() else {
        return;
    };
    let bodies = RigidBodies::new(&robot);
    let times = [0.0, 0.001, 0.002, 0.003];
    let q: Vec<Vec<f64>> = times
        .iter()
        .map(|&t| vec![0.1 + t, -0.4, 0.2, 1.0 - t, 0.0, 0.5, t])
        .collect();
    let tau = vec![vec![0.5; 7]; times.len()];
    let _ = calibration.corrected(&bodies, &times, &q, &tau);
});
