//! What tests, tours and the monkey read of the app: where things are
//! drawn, the camera, the model's invariants.

use super::{OrbitCamera, ProprioscopeApp, Vec2, egui, view};

impl ProprioscopeApp {
    /// Where a link's origin region appears in the window (the centre of
    /// its sampled surface, projected), for tests and tours.
    #[must_use]
    pub fn pixel_of_link(&self, name: &str) -> Option<egui::Pos2> {
        let link = self.model.robot.link_id(name).ok()?;
        let pose = self.model.pose();
        let rect = self.view.rect?;
        let mesh = &self.model.robot.links[link].mesh;
        let (lo, hi) = mesh.bounds()?;
        let centre = pose.point_to_world(link, 0.5 * (lo + hi));
        // Aim at the centre, then walk towards the eye until the ray hits this link.
        let size = Vec2::new(rect.width(), rect.height());
        let pixel = self.view.camera.project(centre.as_vec3(), size)?;
        let (origin, dir) = self.view.camera.ray(pixel, size);
        let hit = self.view.picker.pick(&pose, origin.as_dvec3(), dir.as_dvec3(), &[])?;
        (hit.link == link).then(|| rect.min + egui::vec2(pixel.x, pixel.y))
    }

    /// The model's invariants (what the monkey test checks after every
    /// action): one q and one σ per sensed joint, all finite; candidate
    /// links, the push's link and the shown estimate of this robot; the
    /// session frame within the session.
    pub fn check_invariants(&self) -> Result<(), String> {
        let m = &self.model;
        let joints = m.robot.sensed().len();
        if m.q.len() != joints || m.sigma().len() != joints {
            return Err(format!(
                "{} q and {} σ for {joints} sensed joints",
                m.q.len(),
                m.sigma().len()
            ));
        }
        if !m.q.iter().chain(m.sigma()).all(|v| v.is_finite()) {
            return Err(format!("non-finite q {:?} or σ {:?}", m.q, m.sigma()));
        }
        let links = m.robot.links.len();
        if m.candidate_links.is_empty() || m.candidate_links.iter().any(|&l| l >= links) {
            return Err(format!("candidate links {:?} of {links}", m.candidate_links));
        }
        if let Some(p) = m
            .push
            .into_iter()
            .chain(m.second_push)
            .find(|p| p.link >= links || !p.force_newtons.is_finite() || !p.point_in_link.is_finite())
            && (p.link >= links || !p.force_newtons.is_finite() || !p.point_in_link.is_finite())
        {
            return Err(format!("push {p:?} on a robot of {links} links"));
        }
        if let Some(o) = self.current_outcome()
            && let Ok(u) = &o.update
            && (u.summary.map.link >= links || u.posterior.probability.iter().any(|p| !p.is_finite()))
        {
            return Err("the shown estimate does not fit the robot".to_owned());
        }
        if let Some(o) = self.current_outcome()
            && let Ok(u) = &o.update
            && let Some(field) = u.summary.non_finite_field()
        {
            return Err(format!("the shown estimate's {field} is not finite"));
        }
        if let Some(why) = m.out_of_range() {
            return Err(format!("a setting outside its range: {why}"));
        }
        if let Some(r) = &m.replay
            && !r.session.frames.is_empty()
            && r.frame >= r.session.frames.len()
        {
            return Err(format!("frame {} of {}", r.frame, r.session.frames.len()));
        }
        Ok(())
    }

    /// The heat the view paints for the current model and estimate.
    #[must_use]
    pub fn heat(&self) -> Option<super::Heat> {
        view::ViewPart::heat(&self.shown())
    }

    /// The legend of the heat last drawn.
    #[must_use]
    pub fn legend(&self) -> Option<&super::Legend> {
        self.view.legend()
    }

    /// The arrows the view draws over the robot at `pose`.
    #[must_use]
    pub fn markers(&self, pose: &super::RobotPose) -> Vec<super::Marker> {
        view::ViewPart::markers(&self.shown(), pose)
    }

    /// The 3-D view's camera.
    #[must_use]
    pub fn camera(&self) -> &OrbitCamera {
        &self.view.camera
    }

    /// The sensed joint whose torque bar the pointer is over.
    #[must_use]
    pub fn hovered_joint(&self) -> Option<usize> {
        self.view.hovered_joint
    }

    /// Where the 3-D view was last drawn in the window.
    #[must_use]
    pub fn view_rect(&self) -> Option<egui::Rect> {
        self.view.rect
    }

    /// How the robot was named when opened: a built-in name or the
    /// URDF's absolute path.
    #[must_use]
    pub fn robot_spec(&self) -> &str {
        &self.robot_spec
    }
}
