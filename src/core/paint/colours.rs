//! The colours an estimate is painted with: the arm's grey, the two colour
//! ramps, the arrows' colours and lengths. Display values (gamma-encoded RGBA
//! in [0, 1], f32 as a screen takes them), the same in the app and in what
//! is written for Foxglove.

/// Grey of the robot where no heat is shown.
pub const ROBOT_GREY: [f32; 4] = [0.72, 0.73, 0.75, 1.0];

/// The viridis colour map (gamma-encoded), `t` in [0, 1], by linear
/// interpolation between nine of its anchors.
#[must_use]
pub fn viridis(t: f32) -> [f32; 4] {
    const ANCHORS: [[f32; 3]; 9] = [
        [0.267, 0.005, 0.329],
        [0.283, 0.141, 0.458],
        [0.254, 0.265, 0.530],
        [0.207, 0.372, 0.553],
        [0.164, 0.471, 0.558],
        [0.128, 0.567, 0.551],
        [0.135, 0.659, 0.518],
        [0.478, 0.821, 0.317],
        [0.993, 0.906, 0.144],
    ];
    let x = t.clamp(0.0, 1.0) * (ANCHORS.len() - 1) as f32;
    let i = (x.floor() as usize).min(ANCHORS.len() - 2);
    let f = x - i as f32;
    let (a, b) = (ANCHORS[i], ANCHORS[i + 1]);
    [
        a[0] + (b[0] - a[0]) * f,
        a[1] + (b[1] - a[1]) * f,
        a[2] + (b[2] - a[2]) * f,
        1.0,
    ]
}

/// The thesis' map: red (improbable) through yellow to green (probable),
/// `t` in [0, 1].
#[must_use]
pub fn red_green(t: f32) -> [f32; 4] {
    let t = t.clamp(0.0, 1.0);
    [(2.0 * (1.0 - t)).min(1.0) * 0.9, (2.0 * t).min(1.0) * 0.85, 0.15, 1.0]
}

/// An arrow's colour by what it stands for (RGB, 0–255): none of them is
/// in either heat map.
pub mod arrow_rgb {
    /// The push applied, or a recording's true contact (magenta).
    pub const PUSH: [u8; 3] = [255, 70, 210];
    /// The frame's most probable contact (cyan).
    pub const ESTIMATE: [u8; 3] = [40, 225, 255];
    /// The estimate from the frames together, filtered or smoothed (white).
    pub const OVER_TIME: [u8; 3] = [245, 245, 245];
    /// The over-time estimate's tangential force, friction (green).
    pub const TANGENTIAL: [u8; 3] = [90, 255, 90];
}

/// The least tangential force drawn as its own arrow, N: below it the
/// arrow would be shorter than its head (and a held press's estimate
/// carries a few tenths of a newton of fitted drag).
pub const TANGENTIAL_ARROW_MIN_NEWTONS: f64 = 0.5;

/// Arrow length for a force: 5 cm at 1 N and below, growing with the
/// logarithm so that 1–30 N all read (1.6 N: 7 cm, 10 N: 17 cm, 30 N: 22 cm).
#[must_use]
pub fn arrow_length_m(force_newtons: f64) -> f64 {
    0.05 * (1.0 + force_newtons.max(1.0).ln())
}
