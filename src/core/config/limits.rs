//! The valid range of every number a user gives the program: the command
//! line, scene files, session frames and the app's panels all check
//! against these, so that a value outside is refused with its name and
//! range instead of being clamped or carried into an overflow.
//!
//! The bounds are physical where physics sets them (a friction μ above 2,
//! a push of a meganewton) and otherwise far beyond any arm but well
//! inside what the arithmetic carries. Each is checked alone: together,
//! torques near [`TORQUE`]'s bound with σ near [`SIGMA`]'s can exceed
//! what a frame may hold (`Σ τ²/σ²` above
//! [`crate::core::estimate::settings::MAX_CHI2`], torques of 1e8 σ), and such a
//! frame is refused by the estimator with that reason.

use std::fmt;

/// A closed (or half-open at its lower end) interval of a named quantity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Range {
    /// What the number is (`σ`, `push force component`).
    pub quantity: &'static str,
    /// Its unit as printed (`N·m`; empty for a pure number).
    pub unit: &'static str,
    /// Lowest value.
    pub min: f64,
    /// Highest value.
    pub max: f64,
    /// True when `min` itself is outside (`(0, 1e4]`).
    pub min_excluded: bool,
}

/// A number outside its range: says which, its value and the range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{} is outside the valid range of {quantity}: {range}", number(*.value))]
pub struct OutOfRange {
    /// The quantity, as [`Range::quantity`].
    pub quantity: &'static str,
    /// The value given.
    pub value: f64,
    /// The range, as [`Range`]'s `Display` writes it.
    pub range: String,
}

impl Range {
    /// `[min, max]`.
    #[must_use]
    pub const fn closed(quantity: &'static str, unit: &'static str, min: f64, max: f64) -> Self {
        Self {
            quantity,
            unit,
            min,
            max,
            min_excluded: false,
        }
    }

    /// `(min, max]`: above `min`, up to `max`.
    #[must_use]
    pub const fn above(quantity: &'static str, unit: &'static str, min: f64, max: f64) -> Self {
        Self {
            quantity,
            unit,
            min,
            max,
            min_excluded: true,
        }
    }

    /// Whether `value` is inside (NaN never is).
    #[must_use]
    pub fn contains(&self, value: f64) -> bool {
        let above = if self.min_excluded {
            value > self.min
        } else {
            value >= self.min
        };
        above && value <= self.max
    }

    /// `value` when inside.
    ///
    /// # Errors
    /// [`OutOfRange`] naming the quantity, the value and the range.
    pub fn check(&self, value: f64) -> Result<f64, OutOfRange> {
        if self.contains(value) {
            Ok(value)
        } else {
            Err(OutOfRange {
                quantity: self.quantity,
                value,
                range: self.to_string(),
            })
        }
    }
}

impl Range {
    /// The interval alone, without the unit: `(0, 10000]`.
    #[must_use]
    pub fn interval(&self) -> String {
        let open = if self.min_excluded { "(" } else { "[" };
        format!("{open}{}, {}]", number(self.min), number(self.max))
    }
}

impl fmt::Display for Range {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.interval())?;
        if !self.unit.is_empty() {
            write!(f, " {}", self.unit)?;
        }
        Ok(())
    }
}

/// A count's valid range, `[min, max]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CountRange {
    /// What is counted (`surface points`).
    pub quantity: &'static str,
    /// Fewest.
    pub min: usize,
    /// Most.
    pub max: usize,
}

/// A count outside its range.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{value} is outside the valid range of {quantity}: {min} to {max}")]
pub struct CountOutOfRange {
    /// The quantity, as [`CountRange::quantity`].
    pub quantity: &'static str,
    /// The count given.
    pub value: usize,
    /// Fewest.
    pub min: usize,
    /// Most.
    pub max: usize,
}

impl CountRange {
    /// `[min, max]`.
    #[must_use]
    pub const fn new(quantity: &'static str, min: usize, max: usize) -> Self {
        Self { quantity, min, max }
    }

    /// `value` when inside.
    ///
    /// # Errors
    /// [`CountOutOfRange`] naming the quantity, the value and the range.
    pub fn check(&self, value: usize) -> Result<usize, CountOutOfRange> {
        if (self.min..=self.max).contains(&value) {
            Ok(value)
        } else {
            Err(CountOutOfRange {
                quantity: self.quantity,
                value,
                min: self.min,
                max: self.max,
            })
        }
    }
}

impl fmt::Display for CountRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} to {}", self.min, self.max)
    }
}

/// A number as a reader writes it: `0.05`, `30`, `10000`, `1e6`, `1e-9`.
fn number(value: f64) -> String {
    let magnitude = value.abs();
    if magnitude.is_finite() && magnitude != 0.0 && !(1e-3..1e5).contains(&magnitude) {
        format!("{value:e}")
    } else {
        format!("{value}")
    }
}

/// Likelihood σ per joint, N·m: below 0.1 mN·m no torque sensor resolves
/// (and the estimator's sums of `τ²/σ²` would leave its tolerances),
/// above 100 N·m every contact is within noise.
pub const SIGMA: Range = Range::closed("σ", "N·m", 1e-4, 100.0);

/// Simulated sensor noise σ, N·m (0: none).
pub const NOISE: Range = Range::closed("noise σ", "N·m", 0.0, 100.0);

/// A measured joint torque, N·m: the largest arms' joints carry tens of
/// kN·m; more is a unit error.
pub const TORQUE: Range = Range::closed("joint torque", "N·m", -1e5, 1e5);

/// The smallest push the estimator considers, N.
pub const FORCE_MIN: Range = Range::closed("smallest push", "N", 0.0, 1e4);

/// The largest push the estimator considers, N (above the smallest).
pub const FORCE_MAX: Range = Range::above("largest push", "N", 0.0, 1e4);

/// A push's magnitude, N.
pub const PUSH_NEWTONS: Range = Range::above("push force", "N", 0.0, 1e6);

/// Each component of a push's force vector, N.
pub const FORCE_COMPONENT: Range = Range::closed("push force component", "N", -1e6, 1e6);

/// Each coordinate of a point (a push's, a contact's), m: an arm reaches
/// metres; a kilometre is a unit error.
pub const COORDINATE: Range = Range::closed("point coordinate", "m", -1e3, 1e3);

/// A joint's position, rad (revolute) or m (prismatic): a thousand turns
/// at most, where `sin` and `cos` keep their precision.
pub const JOINT_POSITION: Range = Range::closed("joint position", "rad or m", -1e4, 1e4);

/// Friction μ: the tangential force's spread per newton of push. Beyond
/// 2 the tangential force would exceed twice the push, which no press does.
pub const FRICTION: Range = Range::closed("friction μ", "", 0.0, 2.0);

/// Phases' α: keep clusters with P ≥ α `P_max`.
pub const ALPHA: Range = Range {
    quantity: "α",
    unit: "",
    min: 0.0,
    max: 0.99,
    min_excluded: false,
};

/// Prior probability that a frame with contact has two.
pub const PRIOR_TWO: Range = Range {
    quantity: "prior probability of two contacts",
    unit: "",
    min: 1e-6,
    max: 0.5,
    min_excluded: false,
};

/// The rate at which contacts begin, end or jump, 1/s.
pub const EVENT_RATE: Range = Range::closed("event rate", "1/s", 0.0, 1e3);

/// How far a contact slides, RMS per surface direction after a second, m/√s.
pub const SLIDE: Range = Range::closed("slide", "m/√s", 0.0, 1.0);

/// The smoother's time step, s.
pub const TIME_STEP: Range = Range::closed("time step", "s", 0.0, 1.0);

/// The window over which a torque bias is estimated, s.
pub const BIAS_WINDOW: Range = Range::closed("bias window", "s", 0.1, 86_400.0);

/// The spread of the torque bias the generator adds (each joint's drawn
/// within ± this), N·m.
pub const BIAS: Range = Range::closed("torque bias", "N·m", 0.0, 100.0);

/// A recording's length, s (an hour at most).
pub const SECONDS: Range = Range::above("duration", "s", 0.0, 3600.0);

/// A frame rate, Hz (a robot logs at 1 kHz; 10 kHz is the most taken).
pub const RATE_HZ: Range = Range::above("frame rate", "Hz", 0.0, 1e4);

/// A momentum observer's gain K, 1/s (its lag is 1/K).
pub const OBSERVER_GAIN: Range = Range::above("observer gain", "1/s", 0.0, 1e4);

/// A simulated plant's inertial error, a fraction of the model's.
pub const MODEL_ERROR: Range = Range::closed("model error", "", 0.0, 0.99);

/// A simulated arm's swing about its pose, rad.
pub const SWING: Range = Range::closed("swing", "rad", 0.0, 3.2);

/// A slide's speed, m/s.
pub const SLIDE_SPEED: Range = Range::closed("slide speed", "m/s", 0.0, 1.0);

/// How much faster than its times a session is sent (`stream --rate`).
pub const SPEED: Range = Range::above("playback speed", "× real time", 0.0, 1e3);

/// The most Foxglove transforms a second (`estimate --tf-hz`; 0: every frame).
pub const TRANSFORMS_HZ: Range = Range::closed("transforms rate", "Hz", 0.0, 1e6);

/// How long to wait for a listener, s.
pub const WAIT_SECONDS: Range = Range::closed("wait", "s", 0.0, 3600.0);

/// The heatmap's hiding threshold (a share of the densest point).
pub const THRESHOLD: Range = Range::closed("hide-below threshold", "", 0.0, 0.99);

/// Surface samples.
pub const SURFACE_POINTS: CountRange = CountRange::new("surface points", 1, crate::core::surface::sampling::MAX_POINTS);

/// Particles (particle mode).
pub const PARTICLES: CountRange = CountRange::new("particles", 1, crate::core::estimate::settings::MAX_PARTICLES);

/// Magnitudes per point (deterministic particles).
pub const MAGNITUDES: CountRange = CountRange::new(
    "magnitudes per point",
    1,
    crate::core::estimate::settings::MAX_MAGNITUDES,
);

/// Points of phase A or B.
pub const PHASE_POINTS: CountRange = CountRange::new("phase points", 1, crate::core::surface::sampling::MAX_POINTS);

/// Worker threads.
pub const THREADS: CountRange = CountRange::new("threads", 1, 1024);

/// Frames a live estimate takes before it stops.
pub const LIVE_FRAMES: CountRange = CountRange::new("live frames", 1, usize::MAX);

/// Memory a smoothed recording may take, MiB.
pub const MEMORY_MIB: CountRange = CountRange::new("memory (MiB)", 64, 1 << 20);

/// Contacts looked for at once in a frame.
pub const CONTACTS_AT_ONCE: CountRange = CountRange::new("contacts at once", 1, 2);

/// Random contacts of a bench run.
pub const CONTACTS: CountRange = CountRange::new("contacts", 1, 1_000_000);

/// Every range above, for the documentation's table (and its test).
pub const RANGES: [&Range; 26] = [
    &SIGMA,
    &NOISE,
    &TORQUE,
    &FORCE_MIN,
    &FORCE_MAX,
    &PUSH_NEWTONS,
    &FORCE_COMPONENT,
    &COORDINATE,
    &JOINT_POSITION,
    &FRICTION,
    &ALPHA,
    &EVENT_RATE,
    &SLIDE,
    &TIME_STEP,
    &BIAS_WINDOW,
    &BIAS,
    &SECONDS,
    &RATE_HZ,
    &OBSERVER_GAIN,
    &MODEL_ERROR,
    &SWING,
    &SLIDE_SPEED,
    &SPEED,
    &WAIT_SECONDS,
    &THRESHOLD,
    &PRIOR_TWO,
];

/// Every count range above.
pub const COUNTS: [&CountRange; 9] = [
    &SURFACE_POINTS,
    &PARTICLES,
    &MAGNITUDES,
    &PHASE_POINTS,
    &THREADS,
    &CONTACTS,
    &LIVE_FRAMES,
    &MEMORY_MIB,
    &CONTACTS_AT_ONCE,
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_refuse_what_lies_outside_and_name_it() {
        assert_eq!(SIGMA.check(0.05), Ok(0.05));
        let e = SIGMA.check(1e-9).unwrap_err();
        assert_eq!(e.to_string(), "1e-9 is outside the valid range of σ: [1e-4, 100] N·m");
        assert!(SIGMA.check(f64::NAN).is_err());
        assert!(FORCE_MAX.check(0.0).is_err(), "(0, …] leaves 0 out");
        assert!(FORCE_MIN.check(0.0).is_ok());
        assert!(COORDINATE.check(f64::MAX).is_err());
        assert!(COORDINATE.check(f64::NEG_INFINITY).is_err());
        assert_eq!(FORCE_MAX.to_string(), "(0, 10000] N");
        assert_eq!(
            COORDINATE.check(f64::MAX).unwrap_err().to_string(),
            "1.7976931348623157e308 is outside the valid range of point coordinate: [-1000, 1000] m"
        );
        assert_eq!(FRICTION.to_string(), "[0, 2]");
        let e = SURFACE_POINTS.check(0).unwrap_err();
        assert!(e.to_string().contains("surface points: 1 to"), "{e}");
    }

    #[test]
    fn ordinary_frames_are_far_inside_what_a_frame_may_hold() {
        // A kN·m on seven joints at the sensors' 1 mN·m resolution.
        let chi2 = 7.0 * (1e3_f64 / 1e-3).powi(2);
        assert!(chi2 * 1e3 < crate::core::estimate::settings::MAX_CHI2);
    }
}
