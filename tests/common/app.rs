//! Helpers of the app's tests: the harness on a scene, opening a target
//! and waiting for its estimate.

// Not every test file uses every helper.
#![allow(dead_code, clippy::unwrap_used)]

use egui_kittest::Harness;
use proprioscope::app::{ProprioscopeApp, open_target};

/// The app on its default scene, 1200 × 800.
pub fn app_harness() -> Harness<'static, ProprioscopeApp> {
    proprioscope::app::headless_harness(open_target(None).unwrap(), [1200.0, 800.0])
}

/// Opens a scene, URDF or robot and runs frames until it is installed
/// (or its error shown).
pub fn open_and_wait(harness: &mut Harness<'_, ProprioscopeApp>, target: &str) {
    harness.state_mut().open(target);
    for _ in 0..1000 {
        harness.step();
        if !harness.state().is_opening() {
            harness.run_steps(2);
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    panic!("{target} did not open within 10 s");
}

/// Runs frames until the newest estimate has arrived.
pub fn settle(harness: &mut Harness<'_, ProprioscopeApp>) {
    proprioscope::app::settle(harness).unwrap();
}
