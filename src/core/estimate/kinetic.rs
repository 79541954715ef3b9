//! Kinetic friction over a press: while the place slides over the link,
//! the object drags the arm along the slide with `μ_k` times the push;
//! while it sticks, static friction holds a drag along the slide that
//! stopped there (or is about to start).
//!
//! The slide's direction is the fitted track's own: each frame's
//! velocity over the surface is the slope of a line fitted through the
//! places within 500 ms (`WINDOW_SECS`) either side, along the surface: a
//! fitted track strays by millimetres from the true one, smoothly, and a
//! slide of a few cm/s moves only as much in 50 ms. A slide shorter than
//! the window is read with its ends smeared into the frames at rest. A frame
//! either slips (`μ_k f_n` along its velocity) or sticks; one that moves
//! slower than 5 mm/s (`MOVING_M_PER_S`) cannot slip.
//! `μ_k` is one unknown for the whole press (one object on one surface)
//! under a half-normal prior of spread
//! [`crate::core::estimate::press::KINETIC_SPREAD`]. The states are the
//! cheapest sequence of the two (Viterbi, 10 a change, `SWITCH_COST`) at
//! the last round's places, `μ_k` and held drags.
//!
//! While it sticks, the friction may lie anywhere inside the cone. The
//! model reads it along the slide direction of the nearest frame that
//! slips ([`Slides::drag_directions`]): a slide that stops leaves the
//! object holding its drag, and one about to start pulls the way it will
//! go. Its ratio to the push is one more unknown for the frames after the
//! press's first slide (`ratio.y`) and one for those before (`ratio.z`),
//! under the same prior. Without them, a slide that stops holding its
//! drag was fitted with its places moved to explain the drag (the test
//! `a_slide_that_stops_holding_its_drag_is_found_with_it`: 2.9 N and
//! 9.9 mm off at p90, against 0.2–0.4 N and 1.3–2.9 mm).
//!
//! The slide term expects each frame's place to move on at its
//! velocity, which the window smears from a short slide into the rests
//! around it. So a press that both slips and sticks, on a link that four
//! or more joints feel, is fitted a second time with its places expected
//! to stay put wherever it sticks (and a frame held still free to slip
//! along the nearest slide's direction), and the cheaper fit is kept
//! (`docs/decisions.md`, session 65). In that fit each slipping frame's
//! velocity is fitted through the frames of its own slip alone: through
//! the rests as well, the slope reads a slide slower than it goes.
//!
//! The velocities and states depend on the places that the search
//! moves, so the search runs in rounds: they are held fixed through a
//! Gauss–Newton search of the places and `μ_k` ([`super::press`]'s, with
//! the slide's column in place of γ's three, and each move expected
//! along the velocity), then chosen again at the places it found. A
//! round's answer is scored at its own velocities and states, and the
//! best round is kept.

use glam::DVec3;

use crate::core::estimate::press::{Drag, Found, Problem, Slides, along_surface};
use crate::core::geometry::shell::{MeshPoint, SurfaceFrame};

/// The slowest a place moves over the surface in a frame that may slip,
/// m/s: the track's own jitter (a fraction of a millimetre over the
/// window) reads as less; the slides of interest run at 2–10 cm/s.
const MOVING_M_PER_S: f64 = 0.005;

/// `μ_k` that the first round's states are chosen at.
const MU_START: f64 = 0.4;

/// `-2 ln` of the chance that a press changes between sticking and
/// slipping at a frame.
const SWITCH_COST: f64 = 10.0;

/// Sensed joints that must feel a press's link for its rests to be
/// fitted held still as well (see [`descend_kinetic`]). With fewer (link
/// 3 of the LWR and the links before it) a frame's place, push and drag
/// are more unknowns than its readings, and places held still there were
/// fitted cheaper but farther off: the generated link 3 seed 2 slide at
/// surface seed 1 16.8 → 96.3 mm (`docs/decisions.md`, session 65). On
/// link 4 the cheaper fit holds: the generated link 4 slides' paths
/// within 20 % go from none of ten presses to four at surface seed 0
/// (`docs/validation.md`, *Rests held still on link 4*).
const HELD_STILL_MIN_JOINTS: usize = 4;

/// The shortest slip whose pace is fitted through its own frames, s
/// ([`slip_velocities`]): through a few frames the slope is noise. The
/// shared motor-side observer example's held presses break into slips
/// of 2–15 ms at 1 kHz, and paced on their own they put its place 157 mm
/// off at p90 at surface seed 2 (23 mm with the window's pace). `synth`
/// slips for the middle half of a press of 0.3–1.2 s.
const PACED_MIN_SECS: f64 = 0.2;

/// Half the window a frame's velocity is fitted over, s (see
/// `docs/decisions.md`, *The slide's direction over a wider window*).
const WINDOW_SECS: f64 = 0.5;

/// Rounds of directions and search (`docs/decisions.md`, *Friction
/// while a slide sticks*: 4 and 10 did no better on the generated
/// slides than 6).
const ROUNDS: usize = 6;

/// A press fitted with kinetic friction.
pub(super) struct Kinetic {
    /// Places, `μ_k` (`ratio.x`), the held drags' ratios (`ratio.y`,
    /// `ratio.z`) and the cost at `slides`.
    pub(super) found: Found,
    /// The slides of `found`'s places.
    pub(super) slides: Slides,
    /// Where the search started.
    start: Vec<MeshPoint>,
    /// How much lower `-2 ln L` is than without friction, the places
    /// expected to move as they slide in both (see [`Kinetic::weighed`];
    /// 0 until then).
    pub(super) gain: f64,
}

impl Kinetic {
    /// The path the places take over the frames that slip, m.
    pub(super) fn slid_m(&self) -> f64 {
        let surface = &self.found.normal.surface;
        surface
            .iter()
            .zip(surface.iter().skip(1))
            .zip(self.slides.directions.iter().skip(1))
            .filter(|(_, d)| d.length() > 0.0)
            .map(|((before, here), _)| here.point.distance(before.point))
            .sum()
    }

    /// With its gain: the same search from the same start with `μ_k` held
    /// at 0. `None` where the surface cannot be evaluated.
    pub(super) fn weighed(mut self, problem: &Problem) -> Option<Self> {
        let (still, _) = rounds(problem, self.start.clone(), false, false)?;
        self.gain = still.normal.cost - self.found.normal.cost_as_moving();
        Some(self)
    }
}

/// The press fitted with kinetic friction from `start` (see the module's
/// documentation). `None` where the surface cannot be evaluated.
pub(super) fn descend_kinetic(problem: &Problem, start: Vec<MeshPoint>) -> Option<Kinetic> {
    let moving = rounds(problem, start.clone(), true, false)?;
    // A press that both slips and sticks is fitted again with its places
    // held still where it sticks, and the cheaper fit kept.
    let mixed = |slides: &Slides| {
        let slipping = slides.directions.iter().filter(|d| d.length() > 0.0).count();
        slipping > 0 && slipping < slides.directions.len()
    };
    let try_held = mixed(&moving.1) && problem.sensing_joints() >= HELD_STILL_MIN_JOINTS;
    let (found, slides) = match try_held.then(|| rounds(problem, start.clone(), true, true)).flatten() {
        Some(held) if held.0.normal.cost < moving.0.normal.cost => held,
        _ => moving,
    };
    Some(Kinetic {
        found,
        slides,
        start,
        gain: 0.0,
    })
}

/// Rounds of slides and search from `start`, `μ_k` free or held at 0,
/// the places expected to stay put where the press sticks when
/// `held_still` (else to go on at the track's velocity); the round whose
/// places cost least at their own slides.
fn rounds(problem: &Problem, start: Vec<MeshPoint>, free: bool, held_still: bool) -> Option<(Found, Slides)> {
    let slides_of = |locations: &[MeshPoint], ratio: DVec3| {
        let moving = slides_at(problem, locations)?;
        if free {
            slipping(problem, locations, moving, ratio, held_still)
        } else {
            Some(moving)
        }
    };
    let mut slides = slides_of(&start, DVec3::new(MU_START, 0.0, 0.0))?;
    let mut locations = start;
    let mut best: Option<(Found, Slides)> = None;
    for _ in 0..ROUNDS {
        let found = problem.descend_with(locations, drag(&slides, free))?;
        let next = slides_of(&found.locations, found.ratio)?;
        let normal = problem.normal_with(&found.locations, found.ratio, drag(&next, free))?;
        let scored = Found {
            locations: found.locations.clone(),
            ratio: found.ratio,
            normal,
        };
        if best.as_ref().is_none_or(|b| scored.normal.cost < b.0.normal.cost) {
            best = Some((scored, next.clone()));
        }
        locations = found.locations;
        slides = next;
    }
    best
}

/// `moving` with each frame's direction kept where the press slips and
/// cleared where it sticks: the states that explain the frames at
/// `locations` best with kinetic friction `μ_k` = `ratio.x` while
/// slipping and the drags held at `ratio.y` and `ratio.z` while sticking
/// (a frame that does not move cannot slip; where `held_still`, one
/// may, along the nearest slide's direction: a frame the last round held
/// still would otherwise never slip again). Where `held_still`, a frame
/// that sticks is expected not to move.
fn slipping(
    problem: &Problem,
    locations: &[MeshPoint],
    moving: Slides,
    ratio: DVec3,
    held_still: bool,
) -> Option<Slides> {
    let moving = if held_still {
        Slides {
            directions: moving.drag_directions(),
            velocities_m_per_s: moving.velocities_m_per_s,
            held_still: moving.held_still,
        }
    } else {
        moving
    };
    let slip = problem
        .normal_with(locations, DVec3::new(ratio.x, 0.0, 0.0), Drag::Kinetic(&moving))?
        .residuals;
    let stick = problem
        .normal_with(locations, DVec3::new(0.0, ratio.y, ratio.z), Drag::Held(&moving))?
        .residuals;
    let can_slip: Vec<bool> = moving.directions.iter().map(|d| d.length() > 0.0).collect();
    let chosen = states(moving, &stick, &slip, &can_slip, held_still)?;
    if held_still {
        slip_velocities(problem, locations, chosen)
    } else {
        Some(chosen)
    }
}

/// `slides` with each slipping frame's velocity fitted again through the
/// frames of its own slip only (within the window): the places held
/// still on either side would flatten the slope, and a slide fitted at
/// that slower pace lags its truth by centimetres at its end
/// (`docs/decisions.md`, *A slip's pace from its own frames*). A slip
/// shorter than [`PACED_MIN_SECS`] keeps the window's pace. `None` where
/// the surface cannot be evaluated.
fn slip_velocities(problem: &Problem, locations: &[MeshPoint], mut slides: Slides) -> Option<Slides> {
    let Track { surface, points, times } = Track::at(problem, locations)?;
    let slips: Vec<bool> = slides.directions.iter().map(|d| d.length() > 0.0).collect();
    let mut run_start = 0;
    while run_start < slips.len() {
        if !slips.get(run_start).copied().unwrap_or(false) {
            run_start += 1;
            continue;
        }
        let mut run_end = run_start;
        while slips.get(run_end + 1).copied().unwrap_or(false) {
            run_end += 1;
        }
        if times.get(run_end)? - times.get(run_start)? >= PACED_MIN_SECS {
            let (mut first, mut last) = (run_start, run_start);
            for t in run_start..=run_end {
                let now = *times.get(t)?;
                while first < t && times.get(first).is_some_and(|&s| s < now - WINDOW_SECS) {
                    first += 1;
                }
                last = last.max(t);
                while last < run_end && times.get(last + 1).is_some_and(|&s| s <= now + WINDOW_SECS) {
                    last += 1;
                }
                let normal = surface.get(t)?.inward_normal;
                if let Some(velocity) = fitted_velocity(points.get(first..=last)?, times.get(first..=last)?, normal)
                    && let Some(v) = slides.velocities_m_per_s.get_mut(t)
                {
                    *v = velocity;
                }
            }
        }
        run_start = run_end + 1;
    }
    Some(slides)
}

/// A press's places as the velocity fits read them: each frame's surface
/// frame, its point (link frame, m) and its time (s).
struct Track {
    surface: Vec<SurfaceFrame>,
    points: Vec<DVec3>,
    times: Vec<f64>,
}

impl Track {
    /// The track of `locations`; `None` where the surface cannot be
    /// evaluated.
    fn at(problem: &Problem, locations: &[MeshPoint]) -> Option<Self> {
        let surface: Vec<SurfaceFrame> = locations
            .iter()
            .map(|&at| problem.shape.frame(at))
            .collect::<Option<_>>()?;
        Some(Self {
            points: surface.iter().map(|s| s.point).collect(),
            times: problem.frames.iter().map(|f| f.t_secs).collect(),
            surface,
        })
    }
}

/// The slope of the line fitted through `points` at `times` (least
/// squares), along the surface of inward normal `normal`, m/s. `None`
/// where the times do not spread or the slope is not finite.
fn fitted_velocity(points: &[DVec3], times: &[f64], normal: DVec3) -> Option<DVec3> {
    let count = points.len().min(times.len()) as f64;
    if count < 2.0 {
        return None;
    }
    let mean_t = times.iter().sum::<f64>() / count;
    let mean_p = points.iter().sum::<DVec3>() / count;
    let (mut moved, mut spread) = (DVec3::ZERO, 0.0);
    for (p, &time) in points.iter().zip(times) {
        let dt = time - mean_t;
        moved += (*p - mean_p) * dt;
        spread += dt * dt;
    }
    let velocity = along_surface(moved / spread, normal);
    (spread > 0.0 && velocity.is_finite()).then_some(velocity)
}

/// `slides` with each frame's direction cleared where the press sticks:
/// the sequence of states, sticking with each frame's `stick` residual
/// or slipping with its `slip` residual (where `can_slip`), that costs
/// least, 10 a change, `SWITCH_COST`. A frame without a direction that
/// slips is given a unit one (the gated model reads only the state).
/// Where `held_still`, a frame that sticks has no velocity either, and
/// is held still: the slide term expects it not to move, and holds it
/// closer ([`crate::core::estimate::press::STILL_SLIDE_FRACTION`]).
fn states(mut slides: Slides, stick: &[f64], slip: &[f64], can_slip: &[bool], held_still: bool) -> Option<Slides> {
    let n = stick.len();
    let mut from = vec![[0usize; 2]; n];
    let mut cost = [0.0, f64::INFINITY];
    for t in 0..n {
        let slip_here = if *can_slip.get(t)? {
            *slip.get(t)?
        } else {
            f64::INFINITY
        };
        let here = [*stick.get(t)?, slip_here];
        let mut next = [0.0; 2];
        for (state, slot) in next.iter_mut().enumerate() {
            let stay = cost.get(state).copied().unwrap_or(f64::INFINITY);
            let switch = cost.get(1 - state).copied().unwrap_or(f64::INFINITY) + SWITCH_COST;
            let (best, came) = if stay <= switch {
                (stay, state)
            } else {
                (switch, 1 - state)
            };
            *slot = best + here.get(state).copied().unwrap_or(f64::INFINITY);
            if let Some(f) = from.get_mut(t).and_then(|f| f.get_mut(state)) {
                *f = came;
            }
        }
        cost = next;
    }
    let mut state = usize::from(cost[1] < cost[0]);
    for t in (0..n).rev() {
        if held_still
            && state == 0
            && let (Some(v), Some(held)) = (slides.velocities_m_per_s.get_mut(t), slides.held_still.get_mut(t))
        {
            *v = DVec3::ZERO;
            *held = true;
        }
        if let Some(d) = slides.directions.get_mut(t) {
            if state == 0 {
                *d = DVec3::ZERO;
            } else if d.length() == 0.0 {
                *d = DVec3::X;
            }
        }
        state = from.get(t)?.get(state).copied()?;
    }
    Some(slides)
}

/// The places of the press fitted with γ fixed in the link's frame while
/// it slips and none while it sticks ([`Drag::Gated`]), from `start` and
/// γ = `ratio` (a fixed γ's fit): the states chosen at the last round's
/// places and γ, then a search, in rounds. `None` where the surface
/// cannot be evaluated.
pub(super) fn gated_places(problem: &Problem, start: Vec<MeshPoint>, ratio: DVec3) -> Option<Vec<MeshPoint>> {
    let (mut locations, mut ratio) = (start, ratio);
    for _ in 0..ROUNDS {
        let moving = slides_at(problem, &locations)?;
        let slip = problem.normal_with(&locations, ratio, Drag::Fixed)?.residuals;
        let stick = problem.normal_with(&locations, DVec3::ZERO, Drag::None)?.residuals;
        let everywhere = vec![true; slip.len()];
        let slides = states(moving, &stick, &slip, &everywhere, false)?;
        let found = problem.descend_from(locations, ratio, Drag::Gated(&slides))?;
        locations = found.locations;
        ratio = found.ratio;
    }
    Some(locations)
}

/// `μ_k` free along the slides, or held at 0 with the places still
/// expected to move with them.
fn drag(slides: &Slides, free: bool) -> Drag<'_> {
    if free {
        Drag::Kinetic(slides)
    } else {
        Drag::Drift(slides)
    }
}

/// Each frame's slide (see the module's documentation) at `locations`.
/// `None` where the surface cannot be evaluated.
pub(super) fn slides_at(problem: &Problem, locations: &[MeshPoint]) -> Option<Slides> {
    let Track { surface, points, times } = Track::at(problem, locations)?;
    let mut directions = Vec::with_capacity(surface.len());
    let mut velocities_m_per_s = Vec::with_capacity(surface.len());
    let (mut first, mut last) = (0, 0);
    for (t, (here, &now)) in surface.iter().zip(&times).enumerate() {
        while times.get(first).is_some_and(|&s| s < now - WINDOW_SECS) {
            first += 1;
        }
        last = last.max(t);
        while times.get(last + 1).is_some_and(|&s| s <= now + WINDOW_SECS) {
            last += 1;
        }
        let span = first.min(t)..=last;
        let velocity =
            fitted_velocity(points.get(span.clone())?, times.get(span)?, here.inward_normal).unwrap_or(DVec3::ZERO);
        directions.push(if velocity.length() > MOVING_M_PER_S {
            velocity.normalize()
        } else {
            DVec3::ZERO
        });
        velocities_m_per_s.push(velocity);
    }
    let held_still = vec![false; directions.len()];
    Some(Slides {
        directions,
        velocities_m_per_s,
        held_still,
    })
}

#[cfg(test)]
#[path = "kinetic_tests.rs"]
mod tests;
