//! How far each press travelled over the link's surface, truly and as
//! estimated: the path lengths a sliding contact is scored by.
//!
//! A press is a run of frames with a true contact on one link. Both paths
//! are measured in that link's frame (the arm's own motion is not a
//! slide), through the press's points taken every [`PATH_STEP_SECS`] and
//! its last frame: at 1 kHz a tenth of a millimetre of jitter per frame
//! would add ten centimetres a second to a path summed frame by frame,
//! while a slide of a few centimetres a second moves millimetres between
//! the points taken.

use glam::DVec3;

/// Time between the points a path is measured through, s.
pub const PATH_STEP_SECS: f64 = 0.05;

/// A press whose true path is shorter than this is held, not slid, m:
/// its relative error is not scored.
pub const MIN_SLIDE_M: f64 = 0.01;

/// One press's paths.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlidePath {
    /// Index of the link pressed.
    pub link: usize,
    /// Frames of the press.
    pub frames: usize,
    /// The true contact's path over the link, m.
    pub true_length_m: f64,
    /// The estimated contact's path over the link, m, through the points
    /// taken where the estimate was on the true link (0 where it never
    /// was).
    pub estimated_length_m: f64,
}

impl SlidePath {
    /// Whether the press slid ([`MIN_SLIDE_M`] or more).
    #[must_use]
    pub fn slid(&self) -> bool {
        self.true_length_m >= MIN_SLIDE_M
    }

    /// `estimated / true - 1` (`None` for a press that did not slide).
    #[must_use]
    pub fn relative_error(&self) -> Option<f64> {
        self.slid().then(|| self.estimated_length_m / self.true_length_m - 1.0)
    }
}

/// A press under way.
#[derive(Debug, Clone, Copy)]
struct Press {
    link: usize,
    frames: usize,
    /// Time of the last point taken.
    taken_t_secs: f64,
    taken_true: DVec3,
    taken_estimate: Option<DVec3>,
    /// The latest frame's points (the press's end is measured to them).
    last_true: DVec3,
    last_estimate: Option<DVec3>,
    true_length_m: f64,
    estimated_length_m: f64,
}

impl Press {
    fn new(t_secs: f64, link: usize, true_point: DVec3, estimate: Option<DVec3>) -> Self {
        Self {
            link,
            frames: 1,
            taken_t_secs: t_secs,
            taken_true: true_point,
            taken_estimate: estimate,
            last_true: true_point,
            last_estimate: estimate,
            true_length_m: 0.0,
            estimated_length_m: 0.0,
        }
    }

    /// Takes the latest frame's points into the paths.
    fn take(&mut self, t_secs: f64) {
        self.true_length_m += self.last_true.distance(self.taken_true);
        self.taken_true = self.last_true;
        if let Some(estimate) = self.last_estimate {
            if let Some(before) = self.taken_estimate {
                self.estimated_length_m += estimate.distance(before);
            }
            self.taken_estimate = Some(estimate);
        }
        self.taken_t_secs = t_secs;
    }

    fn path(mut self) -> SlidePath {
        self.take(self.taken_t_secs);
        SlidePath {
            link: self.link,
            frames: self.frames,
            true_length_m: self.true_length_m,
            estimated_length_m: self.estimated_length_m,
        }
    }
}

/// Follows the presses of a session frame by frame, holding only the
/// press under way and each ended press's [`SlidePath`].
#[derive(Debug, Clone, Default)]
pub struct SlideTracker {
    press: Option<Press>,
    paths: Vec<SlidePath>,
}

impl SlideTracker {
    /// The next frame, at `t_secs`: its true contact's link and place in
    /// that link's frame (`None` without a contact, which ends a press),
    /// and the estimated place in the same frame (`None` where the frame
    /// is not called a contact on that link: the estimated path then goes
    /// straight from the last place on it to the next). A true place that
    /// is not finite counts as no contact.
    pub fn push(&mut self, t_secs: f64, truth: Option<(usize, DVec3)>, estimate: Option<DVec3>) {
        let Some((link, true_point)) = truth.filter(|(_, p)| p.is_finite()) else {
            self.end_press();
            return;
        };
        let estimate = estimate.filter(|p| p.is_finite());
        match &mut self.press {
            Some(press) if press.link == link && t_secs.is_finite() => {
                press.frames += 1;
                press.last_true = true_point;
                if estimate.is_some() {
                    press.last_estimate = estimate;
                }
                if t_secs - press.taken_t_secs >= PATH_STEP_SECS {
                    press.take(t_secs);
                }
            }
            _ => {
                self.end_press();
                self.press = Some(Press::new(t_secs, link, true_point, estimate));
            }
        }
    }

    fn end_press(&mut self) {
        if let Some(press) = self.press.take() {
            self.paths.push(press.path());
        }
    }

    /// Every press's paths, in order.
    #[must_use]
    pub fn finish(mut self) -> Vec<SlidePath> {
        self.end_press();
        self.paths
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A straight slide at `speed` (m/s) along x for `secs` at `rate` Hz,
    /// the estimate up to `jitter` m off the truth across y, frame by
    /// frame in a scrambled order.
    fn slide(speed: f64, secs: f64, rate: f64, jitter: f64) -> Vec<SlidePath> {
        let mut tracker = SlideTracker::default();
        tracker.push(0.0, None, None);
        let frames = (secs * rate).round() as usize;
        for i in 0..=frames {
            let t = i as f64 / rate;
            let truth = DVec3::new(speed * t, 0.0, 0.0);
            let side = jitter * (((i * 7919) % 13) as f64 / 6.0 - 1.0);
            tracker.push(t, Some((3, truth)), Some(truth + DVec3::new(0.0, side, 0.0)));
        }
        tracker.push(secs + 1.0 / rate, None, None);
        tracker.finish()
    }

    #[test]
    fn a_straight_slide_has_its_length_and_jitter_adds_little() {
        // 5 cm/s for 1 s at 1 kHz: 5 cm.
        let paths = slide(0.05, 1.0, 1000.0, 0.0);
        assert_eq!(paths.len(), 1);
        let p = paths[0];
        assert_eq!((p.link, p.frames), (3, 1001));
        assert!((p.true_length_m - 0.05).abs() < 1e-12, "{p:?}");
        assert!((p.estimated_length_m - 0.05).abs() < 1e-12, "{p:?}");
        assert!(p.slid() && p.relative_error().unwrap().abs() < 1e-9);
        // A tenth of a millimetre of jitter per frame: summed frame by
        // frame it would be 20 cm; through the points taken, within 1 %.
        let p = slide(0.05, 1.0, 1000.0, 1e-4)[0];
        assert!(p.relative_error().unwrap().abs() < 0.01, "{p:?}");
    }

    #[test]
    fn a_held_press_is_not_scored_and_presses_split_by_link_and_release() {
        let mut tracker = SlideTracker::default();
        for i in 0..100 {
            let t = f64::from(i) * 0.005;
            let link = if i < 50 { 2 } else { 4 };
            let truth = (i % 40 != 39).then_some((link, DVec3::new(0.1, 0.0, 0.0)));
            tracker.push(t, truth, Some(DVec3::new(0.1, 0.002, 0.0)));
        }
        let paths = tracker.finish();
        // Released at frames 39 and 79, the link changed at 50.
        let frames: Vec<(usize, usize)> = paths.iter().map(|p| (p.link, p.frames)).collect();
        assert_eq!(frames, vec![(2, 39), (2, 10), (4, 29), (4, 20)]);
        for p in &paths {
            assert!(
                p.true_length_m.abs() < 1e-15 && !p.slid() && p.relative_error().is_none(),
                "{p:?}"
            );
        }
    }

    #[test]
    fn an_estimate_off_the_link_is_bridged_and_a_bad_truth_ends_the_press() {
        let mut tracker = SlideTracker::default();
        // 10 cm in 1 s at 100 Hz; the estimate missing for the middle half.
        for i in 0..=100 {
            let t = f64::from(i) * 0.01;
            let truth = DVec3::new(0.1 * t, 0.0, 0.0);
            let estimate = (!(25..75).contains(&i)).then_some(truth);
            tracker.push(t, Some((1, truth)), estimate);
        }
        tracker.push(1.01, Some((1, DVec3::NAN)), Some(DVec3::ZERO));
        let paths = tracker.finish();
        assert_eq!(paths.len(), 1, "{paths:?}");
        let p = paths[0];
        assert!((p.true_length_m - 0.1).abs() < 1e-12, "{p:?}");
        // Straight from the last place before the gap to the first after:
        // on a straight slide, the same length.
        assert!((p.estimated_length_m - 0.1).abs() < 1e-12, "{p:?}");
        // Never on the link: no estimated path.
        let mut tracker = SlideTracker::default();
        tracker.push(0.0, Some((1, DVec3::ZERO)), None);
        tracker.push(0.1, Some((1, DVec3::X * 0.02)), None);
        let p = tracker.finish()[0];
        assert!(p.estimated_length_m.abs() < 1e-15, "{p:?}");
        assert!((p.relative_error().unwrap() + 1.0).abs() < 1e-12);
    }
}
