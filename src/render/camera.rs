//! An orbit camera for the 3-D view (z up, like the robots): view and
//! projection matrices for wgpu, pixel rays for picking, and the mouse
//! gestures users know from robot viewers (orbit, pan, zoom toward the cursor).

use glam::{Mat4, Vec2, Vec3, Vec4Swizzles as _};

/// Camera orbiting `target` at `distance`, seen from `yaw` (about z, from
/// +x) and `pitch` (above the xy plane), radians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrbitCamera {
    /// The point looked at, m.
    pub target: Vec3,
    /// Azimuth of the eye about +z, rad.
    pub yaw: f32,
    /// Elevation of the eye above the xy plane, rad.
    pub pitch: f32,
    /// Eye to target, m.
    pub distance: f32,
    /// Vertical field of view, rad.
    pub fov_y: f32,
}

/// Elevation limit: straight up or down would make "up" undefined.
const MAX_PITCH: f32 = 1.55;

impl Default for OrbitCamera {
    /// A three-quarter view of a 1.2 m arm standing at the origin.
    fn default() -> Self {
        Self {
            target: Vec3::new(0.0, 0.0, 0.55),
            yaw: 0.7,
            pitch: 0.35,
            distance: 2.2,
            fov_y: 40f32.to_radians(),
        }
    }
}

impl OrbitCamera {
    /// The eye position, m.
    #[must_use]
    pub fn eye(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        self.target + self.distance * Vec3::new(cp * cy, cp * sy, sp)
    }

    /// World to view (right-handed, y up in view space).
    #[must_use]
    pub fn view_from_world(&self) -> Mat4 {
        glam::camera::rh::view::look_at_mat4(self.eye(), self.target, Vec3::Z)
    }

    /// View to clip, depth 0..1 as wgpu expects.
    #[must_use]
    pub fn clip_from_view(&self, aspect: f32) -> Mat4 {
        let near = (self.distance * 0.01).max(1e-4);
        glam::camera::rh::proj::directx::perspective(self.fov_y, aspect.max(1e-3), near, self.distance * 100.0 + 10.0)
    }

    /// World to clip for a viewport of `size` pixels.
    #[must_use]
    pub fn clip_from_world(&self, size: Vec2) -> Mat4 {
        self.clip_from_view(size.x / size.y.max(1.0)) * self.view_from_world()
    }

    /// The ray through `pixel` (origin at the eye, unit direction).
    #[must_use]
    pub fn ray(&self, pixel: Vec2, size: Vec2) -> (Vec3, Vec3) {
        let ndc = Vec2::new(
            2.0 * pixel.x / size.x.max(1.0) - 1.0,
            1.0 - 2.0 * pixel.y / size.y.max(1.0),
        );
        let world_from_clip = self.clip_from_world(size).inverse();
        let far = world_from_clip * ndc.extend(1.0).extend(1.0);
        let far = far.xyz() / far.w;
        let eye = self.eye();
        (eye, (far - eye).normalize_or(-self.forward()))
    }

    /// Pixel of a world point, or `None` behind the eye.
    #[must_use]
    pub fn project(&self, point: Vec3, size: Vec2) -> Option<Vec2> {
        let clip = self.clip_from_world(size) * point.extend(1.0);
        if clip.w <= 0.0 {
            return None;
        }
        let ndc = clip.xy() / clip.w;
        Some(Vec2::new((ndc.x + 1.0) * 0.5 * size.x, (1.0 - ndc.y) * 0.5 * size.y))
    }

    /// Unit vector from the eye to the target.
    #[must_use]
    pub fn forward(&self) -> Vec3 {
        (self.target - self.eye()).normalize_or(Vec3::NEG_X)
    }

    /// Left drag: turn around the target by a pixel offset.
    pub fn orbit(&mut self, delta: Vec2) {
        self.yaw -= delta.x * 0.01;
        self.pitch = (self.pitch + delta.y * 0.01).clamp(-MAX_PITCH, MAX_PITCH);
    }

    /// Right or middle drag: slide the target so the scene follows the
    /// cursor in the view plane.
    pub fn pan(&mut self, delta: Vec2, size: Vec2) {
        let metres_per_pixel = 2.0 * self.distance * (0.5 * self.fov_y).tan() / size.y.max(1.0);
        let right = self.forward().cross(Vec3::Z).normalize_or(Vec3::X);
        let up = right.cross(self.forward());
        self.target += (-right * delta.x + up * delta.y) * metres_per_pixel;
    }

    /// Wheel: scale the distance by `factor` (< 1 zooms in), keeping the
    /// point under `pixel` (on the plane through the target facing the
    /// eye) under the cursor.
    pub fn zoom_towards(&mut self, factor: f32, pixel: Vec2, size: Vec2) {
        let factor = factor.clamp(0.2, 5.0);
        let (origin, dir) = self.ray(pixel, size);
        let normal = self.forward();
        let denom = dir.dot(normal);
        let anchor = if denom.abs() > 1e-6 {
            origin + dir * ((self.target - origin).dot(normal) / denom)
        } else {
            self.target
        };
        self.target = anchor + (self.target - anchor) * factor;
        self.distance = (self.distance * factor).clamp(0.05, 100.0);
    }

    /// Looks at the box `min`–`max` from the current direction, from just
    /// far enough that its eight corners fit a view of aspect `aspect`
    /// (width over height) with a small margin.
    pub fn fit(&mut self, min: Vec3, max: Vec3, aspect: f32) {
        const MARGIN: f32 = 0.92;
        self.target = 0.5 * (min + max);
        let back = -self.forward();
        let right = self.forward().cross(Vec3::Z).normalize_or(Vec3::X);
        let up = right.cross(self.forward());
        let tan_y = (0.5 * self.fov_y).tan() * MARGIN;
        let tan_x = tan_y * aspect.max(0.1);
        // A corner at (x, y) across and z towards the eye is in view from a
        // distance d when |x| ≤ (d - z)·tan_x and |y| ≤ (d - z)·tan_y.
        let mut distance: f32 = 0.05;
        for i in 0..8 {
            let corner = Vec3::new(
                if i & 1 == 0 { min.x } else { max.x },
                if i & 2 == 0 { min.y } else { max.y },
                if i & 4 == 0 { min.z } else { max.z },
            ) - self.target;
            let (x, y, z) = (corner.dot(right), corner.dot(up), corner.dot(back));
            distance = distance.max(z + x.abs() / tan_x).max(z + y.abs() / tan_y);
        }
        self.distance = distance.clamp(0.05, 100.0);
    }

    /// Double click: look at `point` from where we are.
    pub fn centre_on(&mut self, point: Vec3) {
        self.target = point;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SIZE: Vec2 = Vec2::new(800.0, 600.0);

    #[test]
    fn the_target_projects_to_the_centre_and_the_centre_ray_hits_it() {
        let cam = OrbitCamera::default();
        let centre = cam.project(cam.target, SIZE).unwrap();
        assert!((centre - SIZE / 2.0).length() < 1e-3, "{centre}");
        let (origin, dir) = cam.ray(SIZE / 2.0, SIZE);
        let miss = (cam.target - origin).cross(dir).length();
        assert!(miss < 1e-4, "{miss}");
    }

    #[test]
    fn a_fitted_box_lies_inside_the_view_at_any_aspect() {
        for (aspect, min, max) in [
            (800.0 / 600.0, Vec3::new(-0.1, -0.1, 0.0), Vec3::new(0.1, 0.1, 1.3)),
            (0.5, Vec3::new(-0.6, -0.2, 0.0), Vec3::new(0.6, 0.2, 0.4)),
            (2.5, Vec3::new(-0.05, -0.05, 0.0), Vec3::new(0.05, 0.05, 0.1)),
        ] {
            let mut cam = OrbitCamera::default();
            cam.fit(min, max, aspect);
            let size = Vec2::new(600.0 * aspect, 600.0);
            let mut extent = (f32::MAX, f32::MIN);
            for i in 0..8 {
                let corner = Vec3::new(
                    if i & 1 == 0 { min.x } else { max.x },
                    if i & 2 == 0 { min.y } else { max.y },
                    if i & 4 == 0 { min.z } else { max.z },
                );
                let p = cam.project(corner, size).unwrap();
                assert!(
                    p.x >= 0.0 && p.y >= 0.0 && p.x <= size.x && p.y <= size.y,
                    "{aspect}: {p}"
                );
                extent = (extent.0.min(p.y), extent.1.max(p.y));
            }
            // Not lost in the distance either: the box spans a good part of the view.
            let span = (extent.1 - extent.0).max(0.0) / size.y;
            assert!(span > 0.25, "{aspect}: {span}");
        }
    }

    #[test]
    fn rays_pass_through_the_points_that_project_to_their_pixel() {
        let cam = OrbitCamera::default();
        for p in [Vec3::new(0.3, -0.2, 0.9), Vec3::new(-0.5, 0.4, 0.1), Vec3::ZERO] {
            let pixel = cam.project(p, SIZE).unwrap();
            let (origin, dir) = cam.ray(pixel, SIZE);
            assert!((p - origin).cross(dir).length() < 1e-4, "{p}");
        }
        // Up in the world is up on the screen.
        let low = cam.project(Vec3::new(0.0, 0.0, 0.0), SIZE).unwrap();
        let high = cam.project(Vec3::new(0.0, 0.0, 1.0), SIZE).unwrap();
        assert!(high.y < low.y);
        assert!(cam.project(cam.eye() - cam.forward(), SIZE).is_none());
    }

    #[test]
    fn orbit_keeps_the_distance_and_clamps_the_pitch() {
        let mut cam = OrbitCamera::default();
        cam.orbit(Vec2::new(120.0, 1000.0));
        assert!((cam.eye().distance(cam.target) - cam.distance).abs() < 1e-5);
        assert!(cam.pitch <= MAX_PITCH);
    }

    #[test]
    fn zooming_keeps_the_point_under_the_cursor() {
        let mut cam = OrbitCamera::default();
        let pixel = Vec2::new(600.0, 200.0);
        let (origin, dir) = cam.ray(pixel, SIZE);
        let normal = cam.forward();
        let anchor = origin + dir * ((cam.target - origin).dot(normal) / dir.dot(normal));
        cam.zoom_towards(0.5, pixel, SIZE);
        let after = cam.project(anchor, SIZE).unwrap();
        assert!((after - pixel).length() < 0.5, "{after}");
        assert!((cam.distance - 1.1).abs() < 1e-5);
    }

    #[test]
    fn panning_moves_the_target_with_the_cursor() {
        let mut cam = OrbitCamera::default();
        let before = cam.target;
        let marker = cam.project(before, SIZE).unwrap();
        cam.pan(Vec2::new(50.0, 0.0), SIZE);
        // The old target now appears 50 px to the right.
        let moved = cam.project(before, SIZE).unwrap();
        assert!(
            (moved - marker - Vec2::new(50.0, 0.0)).length() < 0.5,
            "{moved} {marker}"
        );
    }
}
