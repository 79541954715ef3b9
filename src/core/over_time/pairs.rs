//! Two contacts over a session. Seven torques leave two contacts' six
//! unknowns barely determined in one frame (several pairs explain the same
//! torques; `docs/method.md`, *Two contacts*), but contacts come one at a
//! time: where one has pressed alone, its place is known when the other
//! arrives, and a pair once found moves little from frame to frame. So
//! each frame's search starts where the frames before left the contacts
//! ([`PairTracker`]), and whether a second contact presses is a chain of
//! two states over the frames' evidence ([`SecondContactChain`]), with its
//! own onset and release: one contact may hold while the other comes and
//! goes. A recording smooths the chain; a live stream filters it a frame
//! at a time ([`ChainFilter`]).

use glam::DVec3;

use crate::core::estimate::pair::{PairEstimate, PairStart, Placed, Unidentifiable};
use crate::core::numerics::special::logistic;
use crate::core::robot::model::LinkId;

/// Where the next frame's pair search starts, from what the frames so
/// far said.
#[derive(Debug, Clone, Default)]
pub struct PairTracker {
    /// Both contacts as the last frame's search left them (called two or
    /// not: a second push that grows from nothing is followed from its
    /// first newtons).
    both: Option<Box<[Placed; 2]>>,
    /// The first contact that a frame's single contact explained since
    /// the last frame without contact (its sample and magnitude): where
    /// the first push is when a second arrives, before the single
    /// contact, explaining both, drifts between them.
    first_held: Option<(usize, f64)>,
    /// The last contact that a frame's single contact explained.
    held: Option<(usize, f64)>,
}

impl PairTracker {
    /// A tracker that has seen nothing.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Where the next frame's search starts: both contacts as the last
    /// frame left them, the contact first held alone in this press and the
    /// one last held; nothing known, the coarse grid.
    #[must_use]
    pub fn starts(&self) -> Vec<PairStart> {
        let mut starts = Vec::with_capacity(2);
        if let Some(both) = &self.both {
            starts.push(PairStart::Both(both.clone()));
        }
        for (point, force_newtons) in self.first_held.into_iter().chain(self.held) {
            let start = PairStart::One { point, force_newtons };
            if !starts.contains(&start) {
                starts.push(start);
            }
        }
        if starts.is_empty() {
            starts.push(PairStart::Unknown);
        }
        starts
    }

    /// What a frame said: `alone`, its single contact (sample and
    /// magnitude) where that explains the torques, and `pair`, its
    /// two-contact account. A frame with neither forgets both.
    pub fn observe(&mut self, alone: Option<(usize, f64)>, pair: Option<&PairEstimate>) {
        self.both = pair.map(|p| Box::new(p.contacts.clone().map(|c| c.placed)));
        if alone.is_some() {
            self.held = alone;
            self.first_held = self.first_held.or(alone);
        } else if pair.is_none() {
            self.held = None;
            self.first_held = None;
        }
    }
}

/// What [`bridged`] reads of a frame's pair.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairSketch {
    /// Whether the frame's own rules find the pair identifiable.
    pub identifiable: bool,
    /// Whether the only rule that says it is not is that one of its
    /// contacts alone, pushing sideways, explains the torques within the
    /// noise ([`Unidentifiable::OneExplains`]).
    pub one_explains: bool,
    /// Each contact's link and place in it, m.
    pub places: [(LinkId, DVec3); 2],
    /// Probability of two contacts over the frames taken together.
    pub probability_two: f64,
}

impl PairSketch {
    /// The sketch of `pair` with its probability of two over the frames.
    #[must_use]
    pub fn of(pair: &PairEstimate, probability_two: f64) -> Self {
        Self {
            identifiable: pair.identifiable(),
            one_explains: pair.unidentifiable == Some(Unidentifiable::OneExplains),
            places: pair
                .contacts
                .each_ref()
                .map(|c| (c.placed.link, c.placed.point_in_link)),
            probability_two,
        }
    }

    /// Whether `other` is the same pair: each contact on the same link
    /// as one of `other`'s, within `separation_m` of it.
    fn same_pair(&self, other: &Self, separation_m: f64) -> bool {
        let near = |(la, pa): (LinkId, DVec3), (lb, pb): (LinkId, DVec3)| la == lb && pa.distance(pb) < separation_m;
        let [a, b] = self.places;
        let [c, d] = other.places;
        (near(a, c) && near(b, d)) || (near(a, d) && near(b, c))
    }
}

/// Frames whose pair is identified by the frames beside it: the pair is
/// more probable than one contact over the frames, the only rule that
/// calls it unidentifiable is that one of its contacts alone, pushing
/// sideways, explains the torques within the noise, and the frames just
/// before and after identify the same pair and call it. That rule is a χ²
/// threshold that one frame's noise crosses, and a pair held over three
/// frames does not become one push sideways for the middle one (on the
/// `../shared` two-contact example, surface seed 0, six such frames
/// inside a run of 60, each 10–19 nats more probable than one contact).
/// The other rules with friction are not bridged: between two false pairs
/// of a generated slide, the push held before explained the frame, or the
/// farther push was not confirmed (`docs/decisions.md`, session 70). A
/// run's first and last frames have a neighbour on one side only and keep
/// their own rules: that is where a slide's false pairs begin and end.
#[must_use]
pub fn bridged(frames: &[Option<PairSketch>], separation_m: f64) -> Vec<bool> {
    let called = |sketch: &Option<PairSketch>| sketch.filter(|s| s.identifiable && s.probability_two > 0.5);
    (0..frames.len())
        .map(|k| {
            let here = frames.get(k).copied().flatten();
            let before = k.checked_sub(1).and_then(|b| frames.get(b)).and_then(called);
            let after = frames.get(k + 1).and_then(called);
            match (here, before, after) {
                (Some(here), Some(before), Some(after)) => {
                    here.one_explains
                        && here.probability_two > 0.5
                        && here.same_pair(&before, separation_m)
                        && here.same_pair(&after, separation_m)
                }
                _ => false,
            }
        })
        .collect()
}

/// Log evidence ratio a frame without a pair account gives: "no second
/// contact", surely but finitely (the chain stays arithmetic).
pub const NO_PAIR_LOG_RATIO: f64 = -50.0;

/// Whether a second contact presses, as a chain of two states over the
/// frames: it arrives at `onset_per_s` and leaves at `release_per_s`; each
/// frame weighs the states by its evidence ratio `Z₂ / Z₁`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SecondContactChain {
    /// Rate at which a second contact arrives while one presses, 1/s.
    pub onset_per_s: f64,
    /// Rate at which it leaves, 1/s.
    pub release_per_s: f64,
}

impl SecondContactChain {
    /// The chances that a second contact arrives, and that it leaves,
    /// within `dt_secs`.
    fn onset_release(&self, dt_secs: f64) -> (f64, f64) {
        let p = |rate: f64| -(-rate * dt_secs.max(0.0)).exp_m1();
        (p(self.onset_per_s), p(self.release_per_s))
    }

    /// Probability of "two" after a step of `dt_secs` from `two`.
    fn predict(&self, two: f64, dt_secs: f64) -> f64 {
        let (onset, release) = self.onset_release(dt_secs);
        (two * (1.0 - release) + (1.0 - two) * onset).clamp(0.0, 1.0)
    }

    /// `predicted` weighed by a frame's `ln (Z₂ / Z₁)`.
    fn correct(predicted: f64, log_ratio: f64) -> f64 {
        let log_ratio = if log_ratio.is_nan() {
            NO_PAIR_LOG_RATIO
        } else {
            log_ratio.clamp(-700.0, 700.0)
        };
        // odds × ratio, in logs.
        let log_odds = predicted.max(1e-300).ln() - (1.0 - predicted).max(1e-300).ln() + log_ratio;
        logistic(log_odds)
    }

    /// Each frame's probability of two contacts given it and the frames
    /// before (`times_secs` ascending, `log_ratios` one per frame),
    /// starting from `prior_two`: [`ChainFilter`] over the frames.
    #[must_use]
    pub fn filter(&self, times_secs: &[f64], log_ratios: &[f64], prior_two: f64) -> Vec<f64> {
        let mut filter = ChainFilter::new(*self, prior_two);
        times_secs
            .iter()
            .zip(log_ratios)
            .map(|(&t, &r)| filter.push(t, r))
            .collect()
    }

    /// Each frame's probability of two contacts given every frame: the
    /// filter forwards, and a backward pass of the messages.
    #[must_use]
    pub fn smooth(&self, times_secs: &[f64], log_ratios: &[f64], prior_two: f64) -> Vec<f64> {
        let filtered = self.filter(times_secs, log_ratios, prior_two);
        let n = filtered.len();
        let mut out = filtered.clone();
        // β over (one, two), scaled to sum to 1.
        let mut beta = [0.5, 0.5];
        for k in (0..n.saturating_sub(1)).rev() {
            let (Some(&t0), Some(&t1), Some(&r1)) = (times_secs.get(k), times_secs.get(k + 1), log_ratios.get(k + 1))
            else {
                continue;
            };
            let (onset, release) = self.onset_release(t1 - t0);
            // The next frame's likelihood of each state, relative: two
            // weighs e^r against one's 1 (scaled to keep the larger at 1).
            let r = if r1.is_nan() {
                NO_PAIR_LOG_RATIO
            } else {
                r1.clamp(-700.0, 700.0)
            };
            let (l_one, l_two) = if r > 0.0 { ((-r).exp(), 1.0) } else { (1.0, r.exp()) };
            let next = [l_one * beta[0], l_two * beta[1]];
            let from_one = (1.0 - onset) * next[0] + onset * next[1];
            let from_two = release * next[0] + (1.0 - release) * next[1];
            let sum = from_one + from_two;
            beta = if sum > 0.0 && sum.is_finite() {
                [from_one / sum, from_two / sum]
            } else {
                [0.5, 0.5]
            };
            if let (Some(slot), Some(&f)) = (out.get_mut(k), filtered.get(k)) {
                let two = f * beta[1];
                let one = (1.0 - f) * beta[0];
                *slot = if two + one > 0.0 { two / (two + one) } else { f };
            }
        }
        out
    }
}

/// [`SecondContactChain`]'s filter a frame at a time: what a live stream
/// knows of a second contact, from the frames so far.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChainFilter {
    chain: SecondContactChain,
    prior_two: f64,
    /// Probability of two contacts after the last frame.
    two: f64,
    /// The last frame's time, s (`None` before the first).
    last_secs: Option<f64>,
}

impl ChainFilter {
    /// A filter that has seen no frame, starting from `prior_two`.
    #[must_use]
    pub fn new(chain: SecondContactChain, prior_two: f64) -> Self {
        Self {
            chain,
            prior_two,
            two: prior_two,
            last_secs: None,
        }
    }

    /// The probability of two contacts at a frame at `t_secs` with the
    /// evidence ratio `ln (Z₂ / Z₁)` (NaN: the frame has no pair
    /// account), given it and the frames before.
    pub fn push(&mut self, t_secs: f64, log_ratio: f64) -> f64 {
        let predicted = self
            .last_secs
            .map_or(self.two, |l| self.chain.predict(self.two, t_secs - l));
        self.two = SecondContactChain::correct(predicted, log_ratio);
        self.last_secs = Some(t_secs);
        self.two
    }

    /// Forgets every frame (a new stream starts).
    pub fn reset(&mut self) {
        *self = Self::new(self.chain, self.prior_two);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const CHAIN: SecondContactChain = SecondContactChain {
        onset_per_s: 0.5,
        release_per_s: 2.0,
    };

    /// A pair on links 5 and 7 (the second contact `shift` m along x).
    fn sketch(identifiable: bool, one_explains: bool, shift: f64, probability_two: f64) -> PairSketch {
        PairSketch {
            identifiable,
            one_explains,
            places: [(5, DVec3::new(0.0, 0.05, 0.2)), (7, DVec3::new(shift, 0.0, 0.0))],
            probability_two,
        }
    }

    /// Only a frame that one push alone explains, between two frames that
    /// call the same pair, is bridged: not at a run's ends, not across a
    /// gap, not a pair elsewhere, not one the chain finds improbable, not
    /// one another rule calls unidentifiable.
    #[test]
    fn a_pair_is_bridged_only_between_frames_that_call_it() {
        let called = Some(sketch(true, false, 0.0, 0.9));
        let vetoed = Some(sketch(false, true, 0.01, 0.9));
        let frames = [
            vetoed,
            called,
            vetoed,
            called,
            vetoed,
            vetoed,
            called,
            Some(sketch(false, true, 0.08, 0.9)),
            called,
            Some(sketch(false, true, 0.0, 0.3)),
            called,
            Some(sketch(false, false, 0.0, 0.9)),
            called,
            None,
            called,
            vetoed,
        ];
        let bridged = bridged(&frames, 0.05);
        let expected: Vec<usize> = vec![2];
        let found: Vec<usize> = (0..frames.len()).filter(|&k| bridged[k]).collect();
        assert_eq!(found, expected);
        // Swapped labels are the same pair.
        let swapped = Some(PairSketch {
            identifiable: false,
            one_explains: true,
            places: [(7, DVec3::ZERO), (5, DVec3::new(0.0, 0.05, 0.2))],
            probability_two: 0.9,
        });
        assert!(bridged_at_one(called, swapped, called));
        // A neighbour that identifies the pair but finds two improbable
        // does not call it.
        assert!(!bridged_at_one(Some(sketch(true, false, 0.0, 0.4)), vetoed, called));
    }

    fn bridged_at_one(a: Option<PairSketch>, b: Option<PairSketch>, c: Option<PairSketch>) -> bool {
        bridged(&[a, b, c], 0.05)[1]
    }

    /// The smoother against the sum over every path of a short chain,
    /// done by brute force.
    #[test]
    fn smoothing_matches_every_path_summed() {
        let times = [0.0, 0.01, 0.03, 0.04, 0.1, 0.12];
        let ratios = [-3.0, 2.0, -0.5, 4.0, f64::NAN, 1.0];
        let prior = 0.2;
        let smoothed = CHAIN.smooth(&times, &ratios, prior);
        let filtered = CHAIN.filter(&times, &ratios, prior);
        let n = times.len();
        let mut marginal = vec![0.0; n];
        let mut total = 0.0;
        for path in 0..(1usize << n) {
            let state = |k: usize| (path >> k) & 1 == 1;
            let mut w = if state(0) { prior } else { 1.0 - prior };
            for k in 0..n {
                if k > 0 {
                    let dt = times[k] - times[k - 1];
                    let onset = -(-CHAIN.onset_per_s * dt).exp_m1();
                    let release = -(-CHAIN.release_per_s * dt).exp_m1();
                    w *= match (state(k - 1), state(k)) {
                        (false, false) => 1.0 - onset,
                        (false, true) => onset,
                        (true, false) => release,
                        (true, true) => 1.0 - release,
                    };
                }
                let r = if ratios[k].is_nan() {
                    NO_PAIR_LOG_RATIO
                } else {
                    ratios[k]
                };
                if state(k) {
                    w *= r.exp();
                }
            }
            total += w;
            for (k, m) in marginal.iter_mut().enumerate() {
                if state(k) {
                    *m += w;
                }
            }
        }
        for k in 0..n {
            let exact = marginal[k] / total;
            assert!(
                (smoothed[k] - exact).abs() < 1e-12,
                "frame {k}: {} vs {exact}",
                smoothed[k]
            );
        }
        // The last frame's smoothed belief is its filtered one.
        assert!((smoothed[n - 1] - filtered[n - 1]).abs() < 1e-15);
    }

    /// A frame at a time, the filter gives what the whole-session filter
    /// gives, to the bit; after `reset`, what a new one gives.
    #[test]
    fn the_filter_a_frame_at_a_time_is_the_session_filter() {
        let times = [0.0, 0.01, 0.03, 0.04, 0.1, 0.12];
        let ratios = [-3.0, 2.0, -0.5, 4.0, f64::NAN, 1.0];
        let whole = CHAIN.filter(&times, &ratios, 0.2);
        let mut live = ChainFilter::new(CHAIN, 0.2);
        let each: Vec<f64> = times.iter().zip(&ratios).map(|(&t, &r)| live.push(t, r)).collect();
        assert_eq!(each, whole);
        // By hand: the first frame corrects the prior alone.
        let odds = (0.2_f64 / 0.8).ln() - 3.0;
        assert!((whole[0] - 1.0 / (1.0 + (-odds).exp())).abs() < 1e-15);
        live.reset();
        assert_eq!(live, ChainFilter::new(CHAIN, 0.2));
        assert_eq!(
            live.push(5.0, 2.0).to_bits(),
            CHAIN.filter(&[5.0], &[2.0], 0.2)[0].to_bits()
        );
    }

    #[test]
    fn extreme_ratios_stay_probabilities() {
        let times = [0.0, 0.001, 0.002];
        for r in [f64::INFINITY, f64::NEG_INFINITY, 1e308, -1e308, f64::NAN] {
            for p in CHAIN.smooth(&times, &[r, r, r], 0.1) {
                assert!((0.0..=1.0).contains(&p), "{r}: {p}");
            }
        }
        // A live stream's times may be anything: backwards, repeated, not
        // finite.
        let mut live = ChainFilter::new(CHAIN, 0.1);
        for (t, r) in [
            (1.0, 3.0),
            (0.5, -2.0),
            (0.5, f64::NAN),
            (f64::NAN, 4.0),
            (f64::INFINITY, 1e308),
            (-1e308, -1e308),
        ] {
            let p = live.push(t, r);
            assert!((0.0..=1.0).contains(&p), "t {t}, ratio {r}: {p}");
        }
    }

    #[test]
    fn the_tracker_starts_where_the_contacts_were() {
        let mut tracker = PairTracker::new();
        assert_eq!(tracker.starts(), [PairStart::Unknown]);
        tracker.observe(Some((7, 12.0)), None);
        let one = |point, force_newtons| PairStart::One { point, force_newtons };
        assert_eq!(tracker.starts(), [one(7, 12.0)]);
        // The press's first contact is kept beside the last.
        tracker.observe(Some((9, 14.0)), None);
        assert_eq!(tracker.starts(), [one(7, 12.0), one(9, 14.0)]);
        // A frame without contact forgets it.
        tracker.observe(None, None);
        assert_eq!(tracker.starts(), [PairStart::Unknown]);
    }
}
