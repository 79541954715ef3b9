//! A press's best explanation: no tangential force, a tangential force
//! fixed in the link's frame (γ), or kinetic friction along the slide
//! (see [`crate::core::estimate::press`] and
//! [`crate::core::estimate::kinetic`]), each kept only where it explains
//! the press by far better than the simpler one.

use glam::DVec3;

use crate::core::estimate::kinetic::{descend_kinetic, gated_places};
use crate::core::estimate::place_spread::PlaceSpread;
use crate::core::estimate::press::{
    Drag, FRICTION_GAIN, KINETIC_SPREAD, PressContact, PressFrame, PressSettings, Problem, RATIO_LIMIT_SPREADS,
    along_surface,
};
use crate::core::geometry::shell::MeshPoint;
use crate::core::robot::model::LinkId;
use crate::core::surface::sampling::LinkShape;

/// The drop in `-2 ln L` from the frictionless fit that kinetic friction
/// must reach to be kept: `μ_k` is one unknown (a likelihood ratio of
/// e^7.5, a chance of 1e-4 for χ² with one degree of freedom beyond it);
/// a press that sticks throughout has no slide to carry it and gains
/// nothing.
pub const KINETIC_GAIN: f64 = 15.0;

/// The shortest slide, m (the path of the places over the frames that
/// slip), that kinetic friction may explain where no fixed γ within the
/// cone explains the press, on a link that more sensed joints feel than
/// a frame has unknowns (its place's two coordinates and its push). A
/// slip shorter than 1 cm is still a slide: the generated link 7 seed 2
/// slide (`--avoid-covered`) slips 7 mm at `μ_k` 0.52, which the fit from
/// the true places explains at 855 against 381,412 without friction (a
/// fixed γ refused, over 4μ; `docs/decisions.md`, session 71).
pub(crate) const MIN_SLIDE_M: f64 = 0.005;

/// The shortest slide elsewhere, m. A press that holds its place and
/// drags is left to the fixed γ: the track's jitter of a few millimetres,
/// read as slips, would let kinetic friction fit that drag along whatever
/// way the jitter runs (the `../shared` link 4 `MuJoCo` press, surface
/// seed 1: 15.7 → 32.4 mm without this and the margin over a fixed γ
/// below; the dragging presses of `tests/friction.rs`, whose smoothed
/// sets held the push in 86 % of frames, 72.9 % at 5 mm). On a link
/// that at most [`FRAME_UNKNOWNS`] sensed joints feel, every frame's
/// place and push match its torques whatever the jitter (the generated
/// link 3 seed 3 session drawn without friction, surface seed 0: 12.2 →
/// 19.7 mm at 5 mm).
const MIN_SLIDE_FEW_JOINTS_M: f64 = 0.01;

/// A frame's unknowns while it slips: its place's two coordinates on the
/// surface and its push (`μ_k` and the slide's direction are the
/// press's and the track's).
const FRAME_UNKNOWNS: usize = 3;

/// A press explained with a tangential force fixed in the link's frame.
#[derive(Debug, Clone, PartialEq)]
pub struct PressFit {
    /// Each frame's contact, in the frames' order.
    pub contacts: Vec<PressContact>,
    /// γ: the tangential force per newton of push, link frame (its part
    /// along the surface acts at each frame).
    pub tangential_ratio_in_link: DVec3,
    /// How much lower `-2 ln L` is with friction than without.
    pub gain: f64,
}

/// Fits the press `frames` (in time order, all on `link`) with a
/// tangential force fixed in the link's frame, and returns it when the
/// friction model explains the press by [`FRICTION_GAIN`] better than the
/// frictionless one with a plausible γ; `None` otherwise (also when μ is
/// 0, there are no frames, or the surface cannot be evaluated).
#[must_use]
pub fn fit_press(shape: &LinkShape, link: LinkId, frames: &[PressFrame], settings: &PressSettings) -> Option<PressFit> {
    let answer = explain_press(shape, link, frames, settings)?;
    answer.friction.then_some(PressFit {
        contacts: answer.contacts,
        tangential_ratio_in_link: answer.tangential_ratio_in_link,
        gain: answer.gain,
    })
}

/// The press's best explanation on one link from one start: the
/// frictionless fit, or the friction model's where it is kept (as in
/// [`fit_press`]), with its cost, so that explanations on other links or
/// from other starts can be weighed against it.
#[derive(Debug, Clone, PartialEq)]
pub struct PressAnswer {
    /// Each frame's contact, in the frames' order.
    pub contacts: Vec<PressContact>,
    /// γ, link frame (zero without friction, and with kinetic friction).
    pub tangential_ratio_in_link: DVec3,
    /// `μ_k` where kinetic friction along the slide explains the press
    /// (see [`crate::core::estimate::kinetic`]); `None` otherwise.
    pub kinetic_friction: Option<f64>,
    /// `-2 ln` of the posterior at the fit (the cost of the module's
    /// documentation, γ's prior included when friction is kept), without
    /// the normalizer of places held still (see `Normal::cost_as_moving`):
    /// answers from other starts and pieces are weighed against it.
    pub cost: f64,
    /// Whether the friction model was kept.
    pub friction: bool,
    /// How much lower the cost is with friction than without (0 without a
    /// friction setting).
    pub gain: f64,
}

/// Fits the press `frames` (in time order, all on `link`, each started at
/// its `start`) without friction and, with a friction setting, with it;
/// returns the friction model's fit where [`fit_press`] would keep it and
/// the frictionless one otherwise. `None` without frames, without a
/// positive finite slide length, or where the surface cannot be
/// evaluated.
#[must_use]
pub fn explain_press(
    shape: &LinkShape,
    link: LinkId,
    frames: &[PressFrame],
    settings: &PressSettings,
) -> Option<PressAnswer> {
    let problem = Problem::new(shape, link, frames, settings)?;
    let start: Vec<MeshPoint> = frames.iter().map(|f| f.start).collect();
    let frictionless = problem.descend(start.clone(), false)?;
    let with_friction = settings.friction > 0.0 && settings.friction.is_finite();
    // From the recording's places; where that search ends above the
    // frictionless cost (in another valley: γ = 0 is the frictionless
    // answer, so the friction model's best is never worse), again from
    // where the frictionless search ended, which ends at or below it.
    let frictional = if with_friction {
        match problem.descend(start.clone(), true) {
            Some(cold) if cold.normal.cost <= frictionless.normal.cost => Some(cold),
            cold => problem.descend(frictionless.locations.clone(), true).or(cold),
        }
    } else {
        None
    };
    let gain = frictional
        .as_ref()
        .map_or(0.0, |f| frictionless.normal.cost - f.normal.cost);
    let fixed = frictional.as_ref().map(|f| (f.locations.clone(), f.ratio));
    let fixed_start = fixed.as_ref().map(|(locations, _)| locations.clone());
    let kept =
        frictional.filter(|f| gain > FRICTION_GAIN && f.ratio.length() <= RATIO_LIMIT_SPREADS * settings.friction);
    // Kinetic friction, where a fixed γ already explains the press
    // better by `KINETIC_GAIN` (a press that sticks throughout gains
    // nothing from either): from the recording's places, the
    // frictionless answer's, the fixed γ's and those of γ gated by the
    // press's states; only where the recording's places or the fixed
    // γ's spread over the shortest slide or more (a press that holds
    // its place has no slide to find). Kept where it explains the press
    // by `KINETIC_GAIN` better than none (with the places at rest, and
    // expected to move as they slide) and than a fixed γ, over the
    // shortest slide or more.
    let min_slide_m = shortest_slide_m(&problem, kept.is_some());
    let spreads_out = |locations: &[MeshPoint]| extent_m(&problem, locations) >= min_slide_m;
    let moves = spreads_out(&start) || fixed_start.as_deref().is_some_and(spreads_out);
    let kinetic = if with_friction && gain > KINETIC_GAIN && moves {
        let gated_start = fixed.and_then(|(locations, ratio)| gated_places(&problem, locations, ratio));
        [
            Some(start),
            Some(frictionless.locations.clone()),
            fixed_start,
            gated_start,
        ]
        .into_iter()
        .flatten()
        .filter_map(|from| descend_kinetic(&problem, from))
        .min_by(|a, b| a.found.normal.cost.total_cmp(&b.found.normal.cost))
        // The tests that cost nothing first: the reference search with
        // μ_k held at 0 runs only for a fit that passes them.
        .filter(|k| {
            let cost = k.found.normal.cost_as_moving();
            cost < frictionless.normal.cost - KINETIC_GAIN
                && k.found.ratio.x <= RATIO_LIMIT_SPREADS * KINETIC_SPREAD
                && k.slid_m() >= min_slide_m
                && kept.as_ref().is_none_or(|f| cost < f.normal.cost - KINETIC_GAIN)
        })
        .and_then(|k| k.weighed(&problem))
        .filter(|k| k.gain > KINETIC_GAIN)
    } else {
        None
    };
    let fixed_kept = kept.is_some();
    let (found, slides, gain) = match kinetic {
        Some(k) => (k.found, Some(k.slides), k.gain),
        None => (kept.unwrap_or(frictionless), None, gain),
    };
    let friction = slides.is_some() || fixed_kept;
    let ratio = found.ratio;
    let spreads = match &slides {
        Some(slides) => problem.spreads_with(&found.locations, ratio, Drag::Kinetic(slides)),
        None => problem.spreads(&found.locations, ratio, with_friction),
    };
    let plan = slides.as_ref().map(|s| s.drag_plan(false)).unwrap_or_default();
    let contacts = found
        .locations
        .iter()
        .zip(&found.normal.surface)
        .zip(&found.normal.magnitudes)
        .zip(&found.normal.residuals)
        .enumerate()
        .map(
            |(t, (((&location, surface), &force_newtons), &residual_chi2))| PressContact {
                location,
                point_in_link: surface.point,
                inward_normal_in_link: surface.inward_normal,
                force_newtons,
                tangential_in_link: match (&slides, plan.get(t)) {
                    (Some(_), Some(&(d, share))) => {
                        along_surface(d, surface.inward_normal) * (share.of(ratio) * force_newtons)
                    }
                    (Some(_), None) => DVec3::ZERO,
                    (None, _) => along_surface(ratio, surface.inward_normal) * force_newtons,
                },
                residual_chi2,
                spread: spreads
                    .as_ref()
                    .and_then(|all| all.get(t))
                    .map(|&covariance_m2| PlaceSpread {
                        tangents_in_link: surface.tangents,
                        covariance_m2,
                    }),
            },
        )
        .collect();
    Some(PressAnswer {
        contacts,
        tangential_ratio_in_link: if slides.is_some() { DVec3::ZERO } else { ratio },
        kinetic_friction: slides.is_some().then_some(ratio.x),
        cost: found.normal.cost_as_moving(),
        friction,
        gain,
    })
}

/// The shortest slide kinetic friction may explain in `problem`, m:
/// [`MIN_SLIDE_M`] where no fixed γ is kept (`fixed_kept` false) on a
/// link that more than [`FRAME_UNKNOWNS`] sensed joints feel,
/// [`MIN_SLIDE_FEW_JOINTS_M`] elsewhere.
fn shortest_slide_m(problem: &Problem, fixed_kept: bool) -> f64 {
    if !fixed_kept && problem.sensing_joints() > FRAME_UNKNOWNS {
        MIN_SLIDE_M
    } else {
        MIN_SLIDE_FEW_JOINTS_M
    }
}

/// The farthest any of `locations` lies from the first, m (0 where the
/// surface cannot be evaluated).
fn extent_m(problem: &Problem, locations: &[MeshPoint]) -> f64 {
    let points: Vec<DVec3> = locations
        .iter()
        .filter_map(|&at| problem.shape.frame(at).map(|f| f.point))
        .collect();
    points.first().map_or(0.0, |&first| {
        points.iter().map(|p| p.distance(first)).fold(0.0, f64::max)
    })
}
