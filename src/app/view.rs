//! The 3-D view: the frame drawn (robot, heatmap, arrows, markers),
//! its texture, picking and the mouse.

use std::fmt::Write as _;

use crate::core::paint::vertices::vertex_colour;

use super::{
    Command, DVec3, Frame, Heat, HeatLayer, Legend, LinkId, Marker, MarkerRole, OBSERVABILITY_PUSH_NEWTONS,
    OrbitCamera, PUSH_NEWTONS_PER_POINT, Picker, Push, ROBOT_GREY, Renderer, Robot, RobotPose, Vec2, Verdict, ViewKey,
    egui, grid_and_axes, heat, joint_torques, overlay, robot_triangles,
};

/// The 3-D view's part: the camera, the picker on the posed meshes, the
/// offscreen renderer and its texture, what it last drew, the legend, the
/// push being dragged and what the pointer is over.
pub(crate) struct ViewPart {
    pub(crate) camera: OrbitCamera,
    pub(crate) picker: Picker,
    pub(crate) renderer: Option<Renderer>,
    pub(crate) texture: Option<egui::TextureId>,
    /// Where the view was last drawn in the window.
    pub(crate) rect: Option<egui::Rect>,
    /// What the view texture last showed: it is redrawn only when this changes.
    pub(crate) drawn: Option<ViewKey>,
    /// The legend of the heat last drawn.
    pub(crate) legend: Option<Legend>,
    /// A push being dragged: the contact found where the drag started.
    pub(crate) push_drag: Option<crate::core::surface::picking::Pick>,
    /// Fit the camera to the robot when the view is next laid out (its
    /// aspect is known then).
    pub(crate) fit_pending: bool,
    /// What the sample under the pointer explains (shown in the view).
    pub(crate) hover_text: Option<String>,
    /// The joint whose torque bar the pointer is over (sensed index).
    pub(crate) hovered_joint: Option<usize>,
}

impl ViewPart {
    /// The view of a robot (`picker` on its meshes), drawn by `renderer`
    /// where there is a GPU.
    pub(crate) fn new(picker: Picker, renderer: Option<Renderer>) -> Self {
        Self {
            camera: OrbitCamera::default(),
            picker,
            renderer,
            texture: None,
            rect: None,
            drawn: None,
            legend: None,
            push_drag: None,
            fit_pending: true,
            hover_text: None,
            hovered_joint: None,
        }
    }
}

/// Width of the small arrow beside each name in the view's caption, points.
const CAPTION_SWATCH: f32 = 22.0;

impl ViewPart {
    /// Renders the 3-D view into its texture and shows it in `rect`.
    pub(super) fn paint_view(&mut self, shown: &Shown<'_>, ui: &egui::Ui, frame: &eframe::Frame, rect: egui::Rect) {
        let pixels = rect.size() * ui.ctx().pixels_per_point();
        let size = [pixels.x.round() as u32, pixels.y.round() as u32];
        // The vertex lists and the GPU pass are redone only when something
        // they show has changed, not every frame.
        let key = ViewKey {
            inputs: shown.model.estimate_inputs(),
            view: shown.model.view,
            generation: shown.outcome.map(|o| o.generation),
            hovered_joint: self.hovered_joint,
            camera: self.camera,
            size,
        };
        let scene = (self.drawn.as_ref() != Some(&key)).then(|| {
            let (scene, legend) = self.scene_frame(shown);
            self.legend = legend;
            scene
        });
        match (frame.wgpu_render_state(), self.renderer.as_mut()) {
            (Some(state), Some(renderer)) => {
                let resized = renderer.resize(&state.device, size);
                if let Some(scene) = &scene {
                    renderer.render(&state.device, &state.queue, &self.camera, scene);
                    self.drawn = Some(key);
                }
                let mut egui_renderer = state.renderer.write();
                match self.texture {
                    None => {
                        self.texture = Some(egui_renderer.register_native_texture(
                            &state.device,
                            renderer.color_view(),
                            wgpu::FilterMode::Linear,
                        ));
                    }
                    Some(id) if resized => {
                        egui_renderer.update_egui_texture_from_wgpu_texture(
                            &state.device,
                            renderer.color_view(),
                            wgpu::FilterMode::Linear,
                            id,
                        );
                    }
                    Some(_) => {}
                }
                if let Some(id) = self.texture {
                    let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
                    ui.painter().image(id, rect, uv, egui::Color32::WHITE);
                }
            }
            _ => {
                ui.painter().text(
                    rect.center(),
                    egui::Align2::CENTER_CENTER,
                    "no GPU renderer",
                    egui::FontId::default(),
                    egui::Color32::GRAY,
                );
            }
        }
        self.paint_overlay(shown, ui, rect);
        if !shown.status.is_empty() {
            ui.painter().text(
                rect.left_top() + egui::vec2(8.0, 8.0),
                egui::Align2::LEFT_TOP,
                shown.status,
                egui::FontId::default(),
                egui::Color32::LIGHT_GRAY,
            );
        }
    }

    /// The arm under a pixel of the view, with the pose it was found in.
    pub(super) fn pick(
        &self,
        shown: &Shown<'_>,
        pos: egui::Pos2,
        rect: egui::Rect,
    ) -> Option<crate::core::surface::picking::Pick> {
        let local = pos - rect.min;
        let (origin, dir) = self
            .camera
            .ray(Vec2::new(local.x, local.y), Vec2::new(rect.width(), rect.height()));
        let pose = shown.model.pose();
        self.picker.pick(&pose, origin.as_dvec3(), dir.as_dvec3(), &[])
    }

    /// The push a drag from `drag`'s contact to `pointer` sets: it comes
    /// from where the pointer is (the arrow's tail follows it, on the plane
    /// through the contact facing the eye), never pulling (a component
    /// out of the surface is turned inward), `PUSH_NEWTONS_PER_POINT` per
    /// point of drag, 0.5–30 N.
    pub(super) fn dragged_push(
        &self,
        shown: &Shown<'_>,
        drag: &crate::core::surface::picking::Pick,
        pointer: egui::Pos2,
        rect: egui::Rect,
    ) -> Push {
        let local = pointer - rect.min;
        let size = Vec2::new(rect.width(), rect.height());
        let (origin, dir) = self.camera.ray(Vec2::new(local.x, local.y), size);
        let (origin, dir) = (origin.as_dvec3(), dir.as_dvec3());
        let facing = self.camera.forward().as_dvec3();
        let contact = drag.point_world;
        let denom = dir.dot(facing);
        let tail = if denom.abs() > 1e-9 {
            origin + dir * ((contact - origin).dot(facing) / denom)
        } else {
            contact
        };
        let inward = drag.inward_normal_world;
        let mut direction = (contact - tail).try_normalize().unwrap_or(inward);
        let into = direction.dot(inward);
        if into < 0.0 {
            direction = (direction - 2.0 * into * inward).try_normalize().unwrap_or(inward);
        }
        let pixels = self
            .camera
            .project(contact.as_vec3(), size)
            .map_or(0.0, |c| (Vec2::new(local.x, local.y) - c).length());
        let force = (f64::from(pixels) * PUSH_NEWTONS_PER_POINT).clamp(0.5, 30.0);
        let pose = shown.model.pose();
        let link_from_world = pose.world_from_link[drag.link].inverse();
        Push {
            link: drag.link,
            point_in_link: drag.point_in_link,
            inward_normal_in_link: link_from_world.transform_vector3(direction),
            force_newtons: force,
        }
    }

    /// Points the camera at the robot in its current pose, from where it
    /// looks, just far enough that all of it is in view.
    pub(super) fn fit_camera(&mut self, shown: &Shown<'_>, aspect: f32) {
        let pose = shown.model.pose();
        if let Some((min, max)) = robot_bounds(&shown.model.robot, &pose) {
            self.camera.fit(min.as_vec3(), max.as_vec3(), aspect);
        }
    }

    /// The arrows, the legend, the caption and the hover readout over the
    /// picture.
    fn paint_overlay(&self, shown: &Shown<'_>, ui: &egui::Ui, rect: egui::Rect) {
        let painter = ui.painter().with_clip_rect(rect);
        let pose = shown.model.pose();
        let markers = Self::markers(shown, &pose);
        let size = Vec2::new(rect.width(), rect.height());
        overlay::paint_track(&painter, rect, &self.camera, &shown.track);
        let arrows = overlay::screen_arrows(&markers, &self.camera, size, &self.picker, &pose);
        overlay::paint_arrows(&painter, rect, &arrows);
        if let Some(legend) = &self.legend {
            overlay::paint_legend(&painter, rect, legend);
        }
        // The caption names each arrow beside a small one in its colour.
        let replay = shown.model.replay.is_some();
        let font = egui::FontId::proportional(13.0);
        let mut items: Vec<(Option<MarkerRole>, String)> = Vec::new();
        for role in [
            MarkerRole::Push,
            MarkerRole::Estimate,
            MarkerRole::OverTime,
            MarkerRole::Tangential,
        ] {
            if role == MarkerRole::OverTime && shown.over_time.is_none()
                || role == MarkerRole::Tangential && !markers.iter().any(|m| m.role == role)
            {
                continue;
            }
            items.push((Some(role), role.name(replay).to_owned()));
        }
        items.push((None, "length: log of the force; dashed: hidden".to_owned()));
        let galleys: Vec<_> = items
            .into_iter()
            .map(|(role, text)| {
                let grey = if role.is_some() { 225 } else { 175 };
                (
                    role,
                    painter.layout_no_wrap(text, font.clone(), egui::Color32::from_gray(grey)),
                )
            })
            .collect();
        let height = galleys.iter().map(|(_, g)| g.size().y).fold(0.0, f32::max);
        let width: f32 = galleys
            .iter()
            .map(|(role, g)| g.size().x + 14.0 + if role.is_some() { CAPTION_SWATCH + 4.0 } else { 0.0 })
            .sum();
        let mut pos = rect.left_bottom() + egui::vec2(10.0, -10.0 - height);
        painter.rect_filled(
            egui::Rect::from_min_size(pos, egui::vec2(width, height)).expand(5.0),
            3.0,
            egui::Color32::from_black_alpha(150),
        );
        for (role, galley) in galleys {
            if let Some(role) = role {
                let y = pos.y + 0.5 * height;
                let (a, b) = (egui::pos2(pos.x, y), egui::pos2(pos.x + CAPTION_SWATCH, y));
                painter.line_segment([a, b - egui::vec2(6.0, 0.0)], egui::Stroke::new(3.0, role.colour()));
                painter.add(egui::Shape::convex_polygon(
                    vec![b, b + egui::vec2(-7.0, 4.5), b + egui::vec2(-7.0, -4.5)],
                    role.colour(),
                    egui::Stroke::NONE,
                ));
                pos.x += CAPTION_SWATCH + 4.0;
            }
            let advance = galley.size().x + 14.0;
            painter.galley(pos, galley, egui::Color32::WHITE);
            pos.x += advance;
        }
        if let Some(text) = &self.hover_text {
            overlay::paint_readout(&painter, rect, text);
        }
    }

    /// What the candidate under the pointer would explain: its force and
    /// the torques it produces beside the measured ones.
    pub(super) fn candidate_tooltip(&self, shown: &Shown<'_>, pos: egui::Pos2, rect: egui::Rect) -> Option<String> {
        let outcome = shown.outcome?;
        let update = outcome.update.as_ref().ok()?;
        let surface = &outcome.estimator.surface;
        let size = Vec2::new(rect.width(), rect.height());
        let local = pos - rect.min;
        let (origin, dir) = self.camera.ray(Vec2::new(local.x, local.y), size);
        let hit = self.picker.pick(&update.pose, origin.as_dvec3(), dir.as_dvec3(), &[])?;
        let k = (0..surface.len())
            .filter(|&k| surface.link[k] == hit.link)
            .min_by(|&a, &b| {
                surface.point_in_link[a]
                    .distance_squared(hit.point_in_link)
                    .total_cmp(&surface.point_in_link[b].distance_squared(hit.point_in_link))
            })?;
        let contact = crate::core::estimate::summary::contact_at(&update.posterior, surface, &update.pose, k);
        let produced = joint_torques(
            &shown.model.robot,
            &update.pose,
            contact.link,
            contact.point_world,
            contact.force_world,
        );
        let measured = shown.model.measured_torques(&update.pose);
        let mut text = format!(
            "{}: P = {:.2e}, best push {:.1} N\njoint   produces   measured",
            shown.model.robot.links[contact.link].name, contact.probability, contact.force_newtons
        );
        for (i, (p, m)) in produced.iter().zip(&measured).enumerate() {
            let _ = write!(text, "\n{:>5}   {:>8.3}   {:>8.3}", i + 1, p, m);
        }
        Some(text)
    }

    /// The sensed joints' axes (all with the toggle; the hovered one in
    /// yellow with its lever arm to the push).
    pub(super) fn joint_axes(
        &self,
        shown: &Shown<'_>,
        pose: &RobotPose,
        lines: &mut Vec<crate::render::renderer::LineVertex>,
    ) {
        let view = shown.model.view;
        let cyan = [0.3, 0.9, 1.0, 1.0];
        for (i, &j) in shown.model.robot.sensed().iter().enumerate() {
            let hovered = self.hovered_joint == Some(i);
            if !(view.show_axes || hovered) {
                continue;
            }
            let o = pose.joint_origin_world(j);
            let a = pose.joint_axis_world(&shown.model.robot, j);
            let colour = if hovered { [1.0, 1.0, 0.2, 1.0] } else { cyan };
            crate::render::scene::line(lines, (o - a * 0.2).as_vec3(), (o + a * 0.2).as_vec3(), colour);
            if hovered && let Some((_, point, _)) = shown.model.push_world(pose) {
                // The lever: from the axis to the contact, at right angles to the axis.
                let foot = o + a * a.dot(point - o);
                crate::render::scene::line(lines, foot.as_vec3(), point.as_vec3(), [1.0, 1.0, 0.2, 1.0]);
            }
        }
    }

    /// What the arm is painted with for the current estimate, and its legend.
    #[must_use]
    pub fn heat(shown: &Shown<'_>) -> Option<Heat> {
        let outcome = shown.outcome?;
        let update = outcome.update.as_ref().ok()?;
        let surface = &outcome.estimator.surface;
        let view = shown.model.view;
        Some(match view.layer {
            HeatLayer::Contacts => {
                if let Some(pair) = outcome.pair.as_ref().and_then(|p| p.as_ref().ok()) {
                    heat::contacts_heat(pair, surface, view.log_scale, view.threshold, view.red_green)
                } else {
                    let mut heat =
                        heat::posterior_heat(update, surface, view.log_scale, view.threshold, view.red_green);
                    heat.legend.note = Some(if shown.model.config.contacts_at_once < 2 {
                        "one contact looked for: the posterior".to_owned()
                    } else {
                        "no second place: the posterior".to_owned()
                    });
                    heat
                }
            }
            HeatLayer::Posterior => {
                heat::posterior_heat(update, surface, view.log_scale, view.threshold, view.red_green)
            }
            HeatLayer::Observability => heat::observability_heat(
                &shown.model.robot,
                &update.pose,
                surface,
                shown.model.sigma(),
                shown.model.push.map_or(OBSERVABILITY_PUSH_NEWTONS, |p| p.force_newtons),
                view.red_green,
            ),
        })
    }

    /// The legend of the picture last drawn.
    #[must_use]
    pub fn legend(&self) -> Option<&Legend> {
        self.legend.as_ref()
    }

    /// The posed robot with its heat and the candidate points; the arrows
    /// and markers are drawn over the picture (see [`Self::markers`]).
    pub(super) fn scene_frame(&self, shown: &Shown<'_>) -> (Frame, Option<Legend>) {
        let pose = shown.model.pose();
        let mut frame = Frame::default();
        let outcome = shown.outcome.filter(|o| o.update.is_ok());
        let heat = Self::heat(shown);
        let colour = |link: LinkId, vertex: usize| -> [f32; 4] {
            let (Some(o), Some(h)) = (outcome, heat.as_ref()) else {
                return ROBOT_GREY;
            };
            o.nearest
                .get(link)
                .and_then(|v| v.get(vertex))
                .map_or(ROBOT_GREY, |weights| vertex_colour(weights, &h.colours))
        };
        robot_triangles(&shown.model.robot, &pose, &colour, &mut frame.triangles);
        grid_and_axes(1.0, 0.1, &mut frame.lines);
        self.joint_axes(shown, &pose, &mut frame.lines);
        if let (true, Some(o), Some(h)) = (shown.model.view.show_points, outcome, heat.as_ref())
            && let Ok(u) = &o.update
        {
            let surface = &o.estimator.surface;
            let in_set: std::collections::HashSet<usize> = u.summary.credible90.points.iter().copied().collect();
            for k in 0..surface.len() {
                let flags = u.posterior.phase_flags.get(k).copied().unwrap_or(0);
                let colour = if in_set.contains(&k) {
                    [1.0, 1.0, 1.0, 1.0]
                } else if flags & crate::core::estimate::posterior::phase_flag::A != 0 {
                    [0.95, 0.2, 0.2, 1.0]
                } else if flags & crate::core::estimate::posterior::phase_flag::B != 0 {
                    [1.0, 0.6, 0.1, 1.0]
                } else {
                    h.colours.get(k).copied().unwrap_or(ROBOT_GREY)
                };
                let world_from_link = pose.world_from_link[surface.link[k]];
                let p = world_from_link.transform_point3(surface.point_in_link[k]);
                let n = world_from_link.transform_vector3(surface.inward_normal_in_link[k]);
                // A short hair standing out of the surface at each candidate.
                crate::render::scene::line(&mut frame.lines, p.as_vec3(), (p - n * 0.012).as_vec3(), colour);
            }
        }
        (frame, heat.map(|h| h.legend))
    }

    /// The arrows drawn over the view: the push (or the recorded true
    /// contact), the frame's most probable contact and, over time, the
    /// frames' together; `pose` is the model's.
    #[must_use]
    pub fn markers(shown: &Shown<'_>, pose: &RobotPose) -> Vec<Marker> {
        let mut out = Vec::new();
        for (_, point, force) in shown
            .model
            .push_world(pose)
            .into_iter()
            .chain(shown.model.second_push_world(pose))
        {
            out.push(Marker {
                role: MarkerRole::Push,
                point_world: point,
                force_world: force,
            });
        }
        // Two contacts where the evidence calls two: both are the most
        // probable account.
        let pair = shown
            .outcome
            .and_then(|o| o.pair.as_ref())
            .and_then(|p| p.as_ref().ok())
            .filter(|p| p.has_two());
        if let Some(pair) = pair {
            for c in &pair.contacts {
                out.push(Marker {
                    role: MarkerRole::Estimate,
                    point_world: c.point_world,
                    force_world: c.force_world,
                });
            }
        } else if let Some(u) = shown.outcome.and_then(|o| o.update.as_ref().ok())
            && (u.summary.verdict != Verdict::NoContact || u.summary.contact_probability.is_some_and(|p| p >= 0.5))
        {
            out.push(Marker {
                role: MarkerRole::Estimate,
                point_world: u.summary.map.point_world,
                force_world: u.summary.map.force_world,
            });
        }
        if let Some(e) = shown.over_time
            && e.verdict != Verdict::NoContact
        {
            // Where the frames together call two contacts, both are.
            if let Some(two) = e.second.filter(|s| s.called) {
                out.extend(two.contacts.map(|(_, point_world, force_world)| Marker {
                    role: MarkerRole::OverTime,
                    point_world,
                    force_world,
                }));
            } else {
                out.push(Marker {
                    role: MarkerRole::OverTime,
                    point_world: e.point_world,
                    force_world: e.force_world,
                });
                out.extend(overlay::tangential_marker(e.point_world, e.tangential_world));
            }
        }
        out
    }

    pub(super) fn ui(&mut self, shown: &Shown<'_>, ui: &mut egui::Ui, frame: &eframe::Frame) -> Vec<Command> {
        let mut commands = Vec::new();
        let rect = ui.available_rect_before_wrap();
        self.rect = Some(rect);
        let response = ui.allocate_rect(rect, egui::Sense::click_and_drag());
        let size = Vec2::new(rect.width(), rect.height());
        // A drag that starts on the arm sets a push (unless Ctrl is held);
        // elsewhere it turns the view.
        if response.drag_started_by(egui::PointerButton::Primary) && !ui.input(|i| i.modifiers.command) {
            let origin = ui.input(|i| i.pointer.press_origin());
            self.push_drag = origin.and_then(|p| self.pick(shown, p, rect));
        }
        if response.dragged_by(egui::PointerButton::Primary) {
            if let Some(drag) = self.push_drag {
                if let Some(pointer) = response.interact_pointer_pos() {
                    let push = self.dragged_push(shown, &drag, pointer, rect);
                    commands.push(if ui.input(|i| i.modifiers.shift) {
                        Command::SecondPush(push)
                    } else {
                        Command::Push(push)
                    });
                }
            } else {
                let d = response.drag_delta();
                self.camera.orbit(Vec2::new(d.x, d.y));
            }
        }
        if response.drag_stopped() {
            self.push_drag = None;
        }
        if response.dragged_by(egui::PointerButton::Secondary) || response.dragged_by(egui::PointerButton::Middle) {
            let d = response.drag_delta();
            self.camera.pan(Vec2::new(d.x, d.y), size);
        }
        if let Some(hover) = response.hover_pos() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                let local = hover - rect.min;
                self.camera
                    .zoom_towards((-scroll * 0.002).exp(), Vec2::new(local.x, local.y), size);
            }
        }
        if ui.input(|i| i.key_pressed(egui::Key::R)) && !ui.ctx().egui_wants_keyboard_input() {
            self.camera = OrbitCamera::default();
            self.fit_pending = true;
        }
        if self.fit_pending && rect.width() > 1.0 && rect.height() > 1.0 {
            self.fit_camera(shown, rect.width() / rect.height());
            self.fit_pending = false;
        }
        let pick_at = |pos: egui::Pos2, camera: &OrbitCamera| {
            let local = pos - rect.min;
            let (origin, dir) = camera.ray(Vec2::new(local.x, local.y), size);
            let pose = shown.model.pose();
            self.picker
                .pick(&pose, origin.as_dvec3(), dir.as_dvec3(), &[])
                .map(|hit| (hit, pose))
        };
        self.hover_text = response
            .hover_pos()
            .filter(|_| !response.dragged())
            .and_then(|pos| self.candidate_tooltip(shown, pos, rect));
        if response.double_clicked() {
            if let Some((hit, _)) = response.interact_pointer_pos().and_then(|p| pick_at(p, &self.camera)) {
                self.camera.centre_on(hit.point_world.as_vec3());
            }
        } else if response.clicked()
            && let Some((hit, pose)) = response.interact_pointer_pos().and_then(|p| pick_at(p, &self.camera))
        {
            // Shift adds a second push, pressing with the first.
            let second = ui.input(|i| i.modifiers.shift);
            let held = if second {
                shown.model.second_push
            } else {
                shown.model.push
            };
            let push = Push {
                link: hit.link,
                point_in_link: hit.point_in_link,
                inward_normal_in_link: pose.world_from_link[hit.link]
                    .inverse()
                    .transform_vector3(hit.inward_normal_world),
                force_newtons: held.or(shown.model.push).map_or(15.0, |p| p.force_newtons),
            };
            commands.push(if second {
                Command::SecondPush(push)
            } else {
                Command::Push(push)
            });
        }
        self.paint_view(shown, ui, frame, rect);
        commands
    }
}

/// What the view shows from outside its part: the model, the estimate
/// of the frame on screen, the session's estimate over time at that frame
/// and the status line.
pub(crate) struct Shown<'a> {
    pub(crate) model: &'a super::Model,
    pub(crate) outcome: Option<&'a super::Outcome>,
    pub(crate) over_time: Option<crate::batch::FrameEstimate>,
    /// The over-time contact's places over the last second of the session,
    /// on its link as the arm is posed now (world, m; oldest first).
    pub(crate) track: Vec<DVec3>,
    pub(crate) status: &'a str,
}

/// The box around the posed robot's meshes (`None` without vertices).
#[must_use]
pub fn robot_bounds(robot: &Robot, pose: &RobotPose) -> Option<(DVec3, DVec3)> {
    let mut bounds: Option<(DVec3, DVec3)> = None;
    for (link, l) in robot.links.iter().enumerate() {
        let Some(world_from_link) = pose.world_from_link.get(link) else {
            continue;
        };
        for p in &l.mesh.positions {
            let w = world_from_link.transform_point3(*p);
            bounds = Some(bounds.map_or((w, w), |(lo, hi)| (lo.min(w), hi.max(w))));
        }
    }
    bounds
}
