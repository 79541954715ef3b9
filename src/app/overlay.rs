//! What is drawn over the 3-D picture with egui: arrows with width and
//! heads (dashed where the arm hides them), their markers and labels, the
//! colour legend with its numbers, and the hover readout.

use eframe::egui;
use glam::{DVec3, Vec2};

use super::heat::Legend;
use crate::core::paint::colours::arrow_rgb;
use crate::core::robot::kinematics::RobotPose;
use crate::core::surface::picking::Picker;
use crate::render::camera::OrbitCamera;

/// What an arrow in the view stands for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MarkerRole {
    /// The push applied (or a session's recorded true contact).
    Push,
    /// The frame's most probable contact.
    Estimate,
    /// The estimate from the frames together (filtered or smoothed).
    OverTime,
    /// The over-time estimate's tangential force (friction), at its
    /// contact.
    Tangential,
}

impl MarkerRole {
    /// Its colour: none of them in either heat map (magenta, cyan, white,
    /// green).
    #[must_use]
    pub fn colour(self) -> egui::Color32 {
        let [r, g, b] = match self {
            Self::Push => arrow_rgb::PUSH,
            Self::Estimate => arrow_rgb::ESTIMATE,
            Self::OverTime => arrow_rgb::OVER_TIME,
            Self::Tangential => arrow_rgb::TANGENTIAL,
        };
        egui::Color32::from_rgb(r, g, b)
    }

    /// Its name in the view's caption.
    #[must_use]
    pub fn name(self, replay: bool) -> &'static str {
        match (self, replay) {
            (Self::Push, false) => "push",
            (Self::Push, true) => "true contact",
            (Self::Estimate, _) => "most probable",
            (Self::OverTime, _) => "over time",
            (Self::Tangential, _) => "its friction",
        }
    }
}

/// An arrow of the view: a force arriving at a surface point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Marker {
    /// What it is.
    pub role: MarkerRole,
    /// Where the force acts, world frame, m.
    pub point_world: DVec3,
    /// The force, world frame, N.
    pub force_world: DVec3,
}

pub use crate::core::paint::colours::TANGENTIAL_ARROW_MIN_NEWTONS;

/// The arrow of an over-time estimate's tangential force (`tangential_world`,
/// N) at its contact, where it reaches [`TANGENTIAL_ARROW_MIN_NEWTONS`].
#[must_use]
pub fn tangential_marker(point_world: DVec3, tangential_world: DVec3) -> Option<Marker> {
    (tangential_world.length() >= TANGENTIAL_ARROW_MIN_NEWTONS).then_some(Marker {
        role: MarkerRole::Tangential,
        point_world,
        force_world: tangential_world,
    })
}

pub use crate::core::paint::colours::arrow_length_m;

/// An arrow as drawn: its ends on the screen and whether the arm hides
/// its tip.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScreenArrow {
    /// The marker.
    pub marker: Marker,
    /// Tail and tip, view pixels from the view's top-left.
    pub tail: Vec2,
    /// The tip (the contact point).
    pub tip: Vec2,
    /// The arm is between the eye and the contact point.
    pub hidden: bool,
}

/// Projects the markers into a view of `size` pixels; those behind the eye
/// are left out.
#[must_use]
pub fn screen_arrows(
    markers: &[Marker],
    camera: &OrbitCamera,
    size: Vec2,
    picker: &Picker,
    pose: &RobotPose,
) -> Vec<ScreenArrow> {
    let eye = camera.eye().as_dvec3();
    markers
        .iter()
        .filter_map(|m| {
            let direction = m.force_world.try_normalize()?;
            let length = arrow_length_m(m.force_world.length());
            let tail_world = m.point_world - direction * length;
            let tip = camera.project(m.point_world.as_vec3(), size)?;
            let tail = camera.project(tail_world.as_vec3(), size)?;
            // Hidden when something is hit well before the contact point.
            let to_tip = m.point_world - eye;
            let hidden = picker
                .pick(pose, eye, to_tip, &[])
                .is_some_and(|hit| hit.distance_m < to_tip.length() - 0.005);
            Some(ScreenArrow {
                marker: *m,
                tail,
                tip,
                hidden,
            })
        })
        .collect()
}

/// Draws the arrows in `rect`: a dark outline under a coloured shaft, a
/// filled head, a ring at the contact, the force in newtons at the tail.
/// Hidden ones are dashed and faded, but drawn.
pub fn paint_arrows(painter: &egui::Painter, rect: egui::Rect, arrows: &[ScreenArrow]) {
    let mut labels: Vec<egui::Rect> = Vec::new();
    for a in arrows {
        let colour = if a.hidden {
            a.marker.role.colour().gamma_multiply(0.65)
        } else {
            a.marker.role.colour()
        };
        let outline = egui::Color32::from_black_alpha(if a.hidden { 110 } else { 190 });
        let tip = rect.min + egui::vec2(a.tip.x, a.tip.y);
        let tail = rect.min + egui::vec2(a.tail.x, a.tail.y);
        let along = tip - tail;
        let length = along.length();
        if length > 14.0 {
            let d = along / length;
            let normal = egui::vec2(-d.y, d.x);
            let head = 13.0f32.min(0.45 * length);
            let base = tip - d * head;
            if a.hidden {
                painter.extend(egui::Shape::dashed_line(
                    &[tail, base],
                    egui::Stroke::new(3.0, colour),
                    7.0,
                    5.0,
                ));
            } else {
                painter.line_segment([tail, base], egui::Stroke::new(5.5, outline));
                painter.line_segment([tail, base], egui::Stroke::new(3.0, colour));
            }
            let corners = vec![tip, base + normal * head * 0.5, base - normal * head * 0.5];
            painter.add(egui::Shape::convex_polygon(
                corners,
                colour,
                egui::Stroke::new(1.2, outline),
            ));
        }
        // Pointing at the eye, the ring alone says where.
        painter.circle(tip, 5.0, egui::Color32::TRANSPARENT, egui::Stroke::new(2.5, colour));
        let force = a.marker.force_world.length();
        let label_at = if length > 14.0 {
            tail
        } else {
            tip + egui::vec2(8.0, -8.0)
        };
        let text = format!("{force:.1} N");
        let galley = painter.layout_no_wrap(text, egui::FontId::proportional(13.0), colour);
        let mut pos = label_at - galley.size() * 0.5;
        // Arrows that end together would print their forces over each other.
        while labels
            .iter()
            .any(|r| r.intersects(egui::Rect::from_min_size(pos, galley.size()).expand(2.0)))
        {
            pos.y += galley.size().y + 4.0;
        }
        labels.push(egui::Rect::from_min_size(pos, galley.size()).expand(2.0));
        painter.rect_filled(
            egui::Rect::from_min_size(pos, galley.size()).expand(2.0),
            3.0,
            egui::Color32::from_black_alpha(150),
        );
        painter.galley(pos, galley, colour);
    }
}

/// Draws the over-time contact's track (world points, oldest first) as a
/// line in the over-time estimate's colour, fading towards its oldest end.
pub fn paint_track(painter: &egui::Painter, rect: egui::Rect, camera: &OrbitCamera, track: &[DVec3]) {
    let size = Vec2::new(rect.width(), rect.height());
    let screen: Vec<Option<egui::Pos2>> = track
        .iter()
        .map(|p| {
            camera
                .project(p.as_vec3(), size)
                .map(|s| rect.min + egui::vec2(s.x, s.y))
        })
        .collect();
    let count = screen.len().max(1) as f32;
    for (k, pair) in screen.windows(2).enumerate() {
        if let [Some(a), Some(b)] = pair {
            let age = 1.0 - k as f32 / count;
            let colour = MarkerRole::OverTime.colour().gamma_multiply(1.0 - 0.8 * age);
            painter.line_segment([*a, *b], egui::Stroke::new(2.5, colour));
        }
    }
}

/// Gamma-encoded RGBA (as the 3-D view uses) to egui's colour.
fn colour32(c: [f32; 4]) -> egui::Color32 {
    let byte = |x: f32| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
    egui::Color32::from_rgba_unmultiplied(byte(c[0]), byte(c[1]), byte(c[2]), byte(c[3]))
}

/// Slices the legend's ramp is drawn with.
const SLICES: usize = 60;

/// Height of the legend's ramp, points.
const RAMP_HEIGHT: f32 = 150.0;

/// Draws the legend at the bottom-right of `rect`: title, ramp (the same
/// colours as on the arm, fading included) and its numbers.
pub fn paint_legend(painter: &egui::Painter, rect: egui::Rect, legend: &Legend) {
    let font = egui::FontId::proportional(12.0);
    let text_colour = egui::Color32::from_gray(225);
    let bar_right = rect.right() - 14.0;
    let bar = egui::Rect::from_min_max(
        egui::pos2(bar_right - 14.0, rect.bottom() - 40.0 - RAMP_HEIGHT),
        egui::pos2(bar_right, rect.bottom() - 40.0),
    );
    let labels: Vec<_> = legend
        .ticks
        .iter()
        .map(|(t, label)| (*t, painter.layout_no_wrap(label.clone(), font.clone(), text_colour)))
        .collect();
    let widest = labels.iter().map(|(_, g)| g.size().x).fold(0.0, f32::max);
    let title = painter.layout(legend.title.clone(), font.clone(), text_colour, 220.0);
    let note = legend
        .note
        .as_ref()
        .map(|n| painter.layout(n.clone(), font.clone(), text_colour, 220.0));
    let left = (bar.left() - widest - 10.0).min(bar_right - title.size().x);
    let top = bar.top() - title.size().y - 6.0;
    let bottom = bar.bottom() + note.as_ref().map_or(0.0, |n| n.size().y + 6.0);
    painter.rect_filled(
        egui::Rect::from_min_max(egui::pos2(left, top), egui::pos2(bar_right, bottom)).expand(6.0),
        4.0,
        egui::Color32::from_black_alpha(170),
    );
    painter.galley(egui::pos2(bar_right - title.size().x, top), title, text_colour);
    for i in 0..SLICES {
        let t0 = i as f32 / SLICES as f32;
        let t1 = (i + 1) as f32 / SLICES as f32;
        let y = |t: f32| bar.bottom() - t * bar.height();
        let slice = egui::Rect::from_min_max(egui::pos2(bar.left(), y(t1)), egui::pos2(bar.right(), y(t0)));
        let t = f64::from(0.5 * (t0 + t1));
        painter.rect_filled(slice, 0.0, colour32(legend.ramp.colour(t, 1.0)));
    }
    painter.rect_stroke(
        bar,
        0.0,
        egui::Stroke::new(1.0, egui::Color32::from_gray(160)),
        egui::StrokeKind::Outside,
    );
    for (t, galley) in labels {
        let y = bar.bottom() - t as f32 * bar.height();
        painter.line_segment(
            [egui::pos2(bar.left() - 4.0, y), egui::pos2(bar.left(), y)],
            egui::Stroke::new(1.0, text_colour),
        );
        let pos = egui::pos2(bar.left() - 6.0 - galley.size().x, y - galley.size().y * 0.5);
        painter.galley(pos, galley, text_colour);
    }
    if let Some(note) = note {
        painter.galley(
            egui::pos2(bar_right - note.size().x, bar.bottom() + 6.0),
            note,
            text_colour,
        );
    }
}

/// Draws `text` in a dark box at the top-right of `rect` (the hover
/// readout: at a fixed place, never over the panels).
pub fn paint_readout(painter: &egui::Painter, rect: egui::Rect, text: &str) {
    let galley = painter.layout_no_wrap(
        text.to_owned(),
        egui::FontId::monospace(12.0),
        egui::Color32::from_gray(230),
    );
    let pos = egui::pos2(rect.right() - 12.0 - galley.size().x, rect.top() + 12.0);
    painter.rect_filled(
        egui::Rect::from_min_size(pos, galley.size()).expand(6.0),
        4.0,
        egui::Color32::from_black_alpha(185),
    );
    painter.galley(pos, galley, egui::Color32::from_gray(230));
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tangential force of half a newton or more gets its own arrow at
    /// the contact, carrying that force; a smaller one none.
    #[test]
    fn friction_gets_its_own_arrow_where_it_reads() {
        let at = DVec3::new(0.1, 0.2, 0.3);
        let drag = DVec3::new(0.0, 3.0, -4.0);
        let marker = tangential_marker(at, drag).unwrap();
        assert_eq!(marker.role, MarkerRole::Tangential);
        assert_eq!((marker.point_world, marker.force_world), (at, drag));
        assert!(tangential_marker(at, DVec3::new(0.3, 0.3, 0.0)).is_none());
        assert!(tangential_marker(at, DVec3::new(0.0, 0.0, TANGENTIAL_ARROW_MIN_NEWTONS)).is_some());
    }

    #[test]
    fn arrows_grow_with_the_force_and_every_force_reads() {
        assert!((arrow_length_m(1.0) - 0.05).abs() < 1e-12);
        assert!((arrow_length_m(0.2) - 0.05).abs() < 1e-12);
        let mut last = 0.0;
        for f in [1.6, 3.0, 10.0, 30.0] {
            let l = arrow_length_m(f);
            assert!(l > last && l < 0.25, "{f} N: {l} m");
            last = l;
        }
        assert!(arrow_length_m(1.6) > 0.07);
    }
}
