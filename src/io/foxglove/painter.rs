//! What Foxglove is sent of an estimated frame (`estimate --out est.mcap`,
//! `estimate --live … --serve`): the heat painted as the app paints it by
//! default ([`HeatStyle::default`]), the arrows and the numbers to plot,
//! each at its rate and only when it changed.

use super::{
    Arrow, ArrowRole, ByteBudget, Clock, FoxgloveFrame, FrameNumbers, HEAT_BUDGET, HEAT_HZ, PAINT_VISIBLE, Paint,
    SCENE_HZ, heat_bytes, painted,
};
use crate::core::estimate::estimator::{Estimator, Update};
use crate::core::estimate::summary::Verdict;
use crate::core::paint::colours::TANGENTIAL_ARROW_MIN_NEWTONS;
use crate::core::paint::heat::HeatStyle;
use crate::core::paint::heat::posterior_heat;
use crate::core::paint::vertices::{VertexSamples, nearest_samples, vertex_colour};
use crate::core::robot::model::Robot;
use crate::io::session::{ContactTruth, Frame};
use glam::DVec3;

/// How far an arrow moves, m, or its force changes, N, before the arrows
/// are sent again.
const ARROW_MOVED: (f64, f64) = (0.002, 0.2);

/// The per-frame state of what Foxglove is sent: which surface samples
/// paint each mesh vertex, when the transforms, the heat and the arrows
/// are next due, and what was last sent.
pub struct FoxglovePainter {
    nearest: Vec<Vec<VertexSamples>>,
    transforms: Clock,
    heat: Clock,
    heat_budget: ByteBudget,
    arrows: Clock,
    over_time: bool,
    /// Whether the last frame called a contact.
    contact: Option<bool>,
    /// The heat and the arrows last sent.
    sent: (Option<Paint>, Option<Vec<Arrow>>),
    /// Both contacts where the frame is called two
    /// ([`FoxglovePainter::set_pair`]; boxed: most frames have none).
    pair: Option<Box<PairDrawn>>,
}

/// Both contacts of a frame called two: each one's point and push on the
/// arm, world frame, m and N.
pub type PairDrawn = [(DVec3, DVec3); 2];

/// Whether two heatmaps look the same: the same vertices painted, each
/// within [`PAINT_VISIBLE`].
fn same_paint(a: &Paint, b: &Paint) -> bool {
    a.len() == b.len()
        && a.iter().zip(b).all(|(x, y)| {
            x.len() == y.len()
                && x.iter().zip(y).all(|((vx, cx), (vy, cy))| {
                    vx == vy && cx.iter().zip(cy).all(|(p, q)| (p - q).abs() <= PAINT_VISIBLE)
                })
        })
}

/// Whether two sets of arrows look the same: each within [`ARROW_MOVED`].
fn same_arrows(a: &[Arrow], b: &[Arrow]) -> bool {
    a.len() == b.len()
        && a.iter().zip(b).all(|(x, y)| {
            x.role == y.role
                && x.point_world.distance(y.point_world) <= ARROW_MOVED.0
                && x.force_world.distance(y.force_world) <= ARROW_MOVED.1
        })
}

impl FoxglovePainter {
    /// For `estimator`'s surface on `robot`; `over_time`: the estimates
    /// come from the frames together (drawn in the over-time colour).
    /// `transforms_hz`: the most transforms a second (0: every frame).
    #[must_use]
    pub fn new(robot: &Robot, estimator: &Estimator, over_time: bool, transforms_hz: f64) -> Self {
        Self {
            nearest: nearest_samples(robot, &estimator.surface),
            transforms: Clock::every(transforms_hz),
            heat: Clock::every(HEAT_HZ),
            heat_budget: ByteBudget::new(HEAT_BUDGET),
            arrows: Clock::every(SCENE_HZ),
            over_time,
            contact: None,
            sent: (None, None),
            pair: None,
        }
    }

    /// The next frame's two contacts where it is called two, drawn
    /// instead of its single contact; `None` where it is not.
    pub fn set_pair(&mut self, pair: Option<PairDrawn>) {
        self.pair = pair.map(Box::new);
    }

    /// The frame's Foxglove part: `joint_positions` in the robot's order;
    /// the transforms, the heat and the arrows only when due and changed.
    pub fn frame(
        &mut self,
        estimator: &Estimator,
        update: &Update,
        frame: &Frame,
        joint_positions: &[f64],
        stamp_ns: i64,
    ) -> FoxgloveFrame {
        let contact = update.summary.verdict != Verdict::NoContact;
        let truths = frame.true_contacts();
        let truth = truths
            .first()
            .map(|t| (DVec3::from_array(t.point), DVec3::from_array(t.force)));
        let numbers = FrameNumbers::of(update, truth);
        let changed = self.contact.is_some_and(|was| was != contact);
        self.contact = Some(contact);
        let mut heat = None;
        if self.heat.due(stamp_ns, changed) {
            let style = HeatStyle::default();
            let h = posterior_heat(
                update,
                &estimator.surface,
                style.log_scale,
                style.threshold,
                style.red_green,
            );
            let colours: Vec<Vec<[f32; 4]>> = self
                .nearest
                .iter()
                .map(|link| link.iter().map(|w| vertex_colour(w, &h.colours)).collect())
                .collect();
            let paint = painted(&colours);
            let bytes = heat_bytes(paint.iter().map(Vec::len).sum());
            if (changed || !self.sent.0.as_ref().is_some_and(|last| same_paint(last, &paint)))
                && self.heat_budget.take(stamp_ns, bytes)
            {
                heat = Some(paint.clone());
                self.sent.0 = Some(paint);
            }
        }
        let mut arrows = None;
        if self.arrows.due(stamp_ns, changed) {
            let now = self.arrows(update, &truths);
            if changed || !self.sent.1.as_ref().is_some_and(|last| same_arrows(last, &now)) {
                arrows = Some(now.clone());
                self.sent.1 = Some(now);
            }
        }
        FoxgloveFrame {
            stamp_ns,
            joint_positions: self.transforms.due(stamp_ns, false).then(|| joint_positions.to_vec()),
            numbers,
            heat,
            arrows,
        }
    }

    /// The frame's arrows: the true contacts, the estimate (both contacts
    /// where two are called) and, over time, its friction where it reads.
    fn arrows(&self, update: &Update, truths: &[ContactTruth]) -> Vec<Arrow> {
        let s = &update.summary;
        let mut arrows = Arrow::truths(truths);
        let role = if self.over_time {
            ArrowRole::OverTime
        } else {
            ArrowRole::Estimate
        };
        if let Some(pair) = self.pair.as_deref() {
            arrows.extend(pair.map(|(point_world, force_world)| Arrow {
                role,
                point_world,
                force_world,
            }));
        } else if s.verdict != Verdict::NoContact {
            arrows.push(Arrow {
                role,
                point_world: s.map.point_world,
                force_world: s.map.force_world,
            });
            let tangential = s.map.tangential_world();
            if self.over_time && tangential.length() >= TANGENTIAL_ARROW_MIN_NEWTONS {
                arrows.push(Arrow {
                    role: ArrowRole::Tangential,
                    point_world: s.map.point_world,
                    force_world: tangential,
                });
            }
        }
        arrows
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::config::estimator::EstimatorConfig;
    use crate::core::over_time::sequence::Temporal;
    use crate::io::session::Truth;

    /// Where a pair is set, the frame's arrows are both contacts instead
    /// of its single one; unset, the single one again.
    #[test]
    fn a_pair_set_is_drawn_instead_of_the_single_contact() {
        let robot = crate::core::robot::builtin::lwr4plus_generated().unwrap_or_else(|e| panic!("{e}"));
        let config = EstimatorConfig {
            surface_points: 600,
            ..EstimatorConfig::default()
        };
        let estimator = config
            .estimator(&robot, robot.default_candidate_links(), Temporal::None)
            .unwrap_or_else(|e| panic!("{e}"));
        let q = vec![0.0; 7];
        // The thesis' push on link 4 (its torques).
        let tau = [0.09516, -0.53783, 0.09516, 0.01017, 0.0, 0.0, 0.0];
        let update = estimator.update(&robot, &q, &tau).unwrap_or_else(|e| panic!("{e}"));
        assert_ne!(update.summary.verdict, Verdict::NoContact);
        let frame = Frame {
            t: 0.0,
            q: q.clone(),
            tau: tau.to_vec(),
            truth: Truth::NoContact,
            truth_all: Vec::new(),
        };
        let mut painter = FoxglovePainter::new(&robot, &estimator, false, 0.0);
        let points = |drawn: &FoxgloveFrame| -> Vec<DVec3> {
            let arrows = drawn.arrows.as_ref().unwrap_or_else(|| panic!("no arrows sent"));
            assert!(arrows.iter().all(|a| a.role == ArrowRole::Estimate), "{arrows:?}");
            arrows.iter().map(|a| a.point_world).collect()
        };
        let second = 1_000_000_000;
        let single = points(&painter.frame(&estimator, &update, &frame, &q, 0));
        assert_eq!(single, [update.summary.map.point_world]);
        let pair = [(DVec3::X, DVec3::Y), (DVec3::Z, DVec3::NEG_Y)];
        painter.set_pair(Some(pair));
        let two = points(&painter.frame(&estimator, &update, &frame, &q, second));
        assert_eq!(two, [DVec3::X, DVec3::Z]);
        painter.set_pair(None);
        let again = points(&painter.frame(&estimator, &update, &frame, &q, 2 * second));
        assert_eq!(again, single);
    }
}
