//! `view --serve`: what the view shows, published live to Foxglove over
//! its WebSocket protocol (the arm as posed, the heat as painted, the
//! arrows as drawn, the numbers), each time the estimate or the pose
//! changes.

use std::sync::Arc;

use super::view::{Shown, ViewPart};
use super::{MarkerRole, Robot};
use crate::core::paint::vertices::vertex_colour;
use crate::io::foxglove::serve::FoxgloveServer;
use crate::io::foxglove::{ArmScene, Arrow, ArrowRole, FoxgloveFrame, FrameNumbers, frame_messages, opening, painted};

/// The server and what it last sent.
#[derive(Default)]
pub(crate) struct FoxglovePart {
    server: Option<FoxgloveServer>,
    /// The arm's scene, for the robot it was built for.
    scene: Option<(Arc<Robot>, ArmScene)>,
    /// What was last published: the estimate's generation and the joint
    /// positions.
    sent: Option<(u64, Vec<f64>)>,
    /// Why the server stopped or did not start.
    pub(crate) error: Option<String>,
}

/// Nanoseconds since 1970 now (the live clock Foxglove shows).
fn now_ns() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX))
}

impl FoxglovePart {
    /// Starts the server on `addr`; a failure is kept to be shown.
    pub(crate) fn start(addr: &str) -> Self {
        match FoxgloveServer::start(addr, "proprioscope view") {
            Ok(server) => {
                log::info!("{}", server.open_hint());
                Self {
                    server: Some(server),
                    ..Self::default()
                }
            }
            Err(e) => Self {
                error: Some(e.to_string()),
                ..Self::default()
            },
        }
    }

    /// The address it serves on.
    pub(crate) fn address(&self) -> Option<std::net::SocketAddr> {
        self.server.as_ref().map(FoxgloveServer::address)
    }

    /// Publishes what `shown` draws when the estimate or the pose changed.
    pub(crate) fn publish(&mut self, shown: &Shown<'_>) {
        let Some(server) = self.server.as_mut() else { return };
        let robot = &shown.model.robot;
        let positions = shown.model.joint_positions();
        let generation = shown.outcome.map_or(0, |o| o.generation);
        if self
            .sent
            .as_ref()
            .is_some_and(|(g, q)| *g == generation && *q == positions)
        {
            return;
        }
        let stamp = now_ns();
        if self.scene.as_ref().is_none_or(|(r, _)| !Arc::ptr_eq(r, robot)) {
            let scene = ArmScene::new(robot);
            if let Err(e) = server.set_opening(opening(&scene, stamp)) {
                self.error = Some(e.to_string());
                return;
            }
            self.scene = Some((robot.clone(), scene));
        }
        let Some((_, scene)) = self.scene.as_ref() else { return };
        let pose = shown.model.pose();
        let colours: Vec<Vec<[f32; 4]>> = match (ViewPart::heat(shown), shown.outcome) {
            (Some(heat), Some(outcome)) => outcome
                .nearest
                .iter()
                .map(|link| link.iter().map(|w| vertex_colour(w, &heat.colours)).collect())
                .collect(),
            _ => Vec::new(),
        };
        let arrows: Vec<Arrow> = ViewPart::markers(shown, &pose)
            .iter()
            .map(|m| Arrow {
                role: match m.role {
                    MarkerRole::Push => ArrowRole::Push,
                    MarkerRole::Estimate => ArrowRole::Estimate,
                    MarkerRole::OverTime => ArrowRole::OverTime,
                    MarkerRole::Tangential => ArrowRole::Tangential,
                },
                point_world: m.point_world,
                force_world: m.force_world,
            })
            .collect();
        let numbers = shown
            .outcome
            .and_then(|o| o.update.as_ref().ok())
            .map_or(FrameNumbers::NONE, |u| {
                let push = shown.model.push_world(&pose).map(|(_, point, force)| (point, force));
                FrameNumbers::of(u, push)
            });
        let frame = FoxgloveFrame {
            stamp_ns: stamp,
            joint_positions: Some(positions.clone()),
            numbers,
            heat: Some(painted(&colours)),
            arrows: Some(arrows),
        };
        match server.publish(&frame_messages(scene, &frame)) {
            Ok(()) => self.sent = Some((generation, positions)),
            Err(e) => self.error = Some(e.to_string()),
        }
    }
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // equal colours are equal numbers
mod tests {
    use super::*;
    use crate::app::worker::{Request, answer};
    use crate::app::{Model, ProprioscopeApp, StartSettings, ViewOptions};
    use crate::core::paint::colours::ROBOT_GREY;
    use crate::io::builtin::load_robot;
    use crate::io::foxglove::{FoxglovePainter, PAINT_VISIBLE, as_8_bit};
    use crate::io::session::{Frame, Truth};
    use crate::io::urdf::UrdfOptions;

    /// What the MCAP out paints for Foxglove is what the app's view paints
    /// for the same frame, vertex by vertex (as 8 bits show both).
    #[test]
    fn foxglove_heat_is_the_app_s_heat() {
        let robot = load_robot("lwr4plus", std::path::Path::new("."), &UrdfOptions::default()).unwrap();
        let (q, push) = ProprioscopeApp::default_scene(&robot);
        let model = Model::from_start(robot, q.clone(), push, StartSettings::default(), ViewOptions::default());
        let pose = model.pose();
        let tau = model.measured_torques(&pose);
        let request = Request {
            generation: 1,
            robot: model.robot.clone(),
            joint_positions: model.joint_positions(),
            tau: tau.clone(),
            config: model.estimation_config(),
            links: model.candidate_links.clone(),
        };
        let outcome = answer(&request);
        let update = outcome.update.as_ref().unwrap();
        let shown = Shown {
            model: &model,
            outcome: Some(&outcome),
            over_time: None,
            track: Vec::new(),
            status: "",
        };
        let heat = ViewPart::heat(&shown).unwrap();

        let mut painter = FoxglovePainter::new(&model.robot, &outcome.estimator, false, 0.0);
        let frame = Frame {
            t: 0.0,
            q,
            tau,
            truth: Truth::NoContact,
            truth_all: Vec::new(),
        };
        let drawn = painter.frame(&outcome.estimator, update, &frame, &model.joint_positions(), 0);
        let paint = drawn.heat.unwrap();
        let (mut sent, mut grey) = (0, 0);
        for (link, weights) in outcome.nearest.iter().enumerate() {
            for (v, w) in weights.iter().enumerate() {
                let app = vertex_colour(w, &heat.colours);
                if let Some((_, c)) = paint[link].iter().find(|(pv, _)| *pv as usize == v) {
                    assert!(*c == as_8_bit(app), "link {link} vertex {v}: {c:?} against {app:?}");
                    sent += 1;
                } else {
                    // Left to the grey arm beneath: the app paints it within a trace of grey.
                    assert!(app.iter().zip(&ROBOT_GREY).all(|(a, g)| (a - g).abs() <= PAINT_VISIBLE));
                    grey += 1;
                }
            }
        }
        // The push on link 3 paints a band, not the whole arm.
        assert!(sent > 50 && grey > sent, "{sent} painted, {grey} grey");
    }
}
