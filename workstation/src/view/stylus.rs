//! The mouse as the stylus (`workstation view` without a device): turns the mouse's ray, the
//! left button, Shift and the wheel into the cursor the mouse thread streams
//! ([`crate::live::mouse::MouseHand`]), so that each tool does what a person expects of a mouse.
//! Deterministic, no window: tested here.
//!
//! The cursor lives on the surface under the mouse ([`super::pick`]: the ray cast into the
//! field the force thread reads, the points where there is none). A press makes contact there.
//! While the button is held the surface is the one of the press (that moment's field and
//! points), so a tool that changes the shape does not chase its own change:
//! - **touch**, **paint**: the tip follows the surface under the mouse, pressed the tool's depth
//!   into it (the force is the contact stiffness × depth; the brush grows with it);
//! - **rope (point)**: the press grabs the surface under the mouse; a drag pulls the tip out
//!   along the grabbed normal by the distance dragged (the screen drag in metres at the grabbed
//!   point's depth), **Shift** pushes it in; the release commits the shape;
//! - **rope (curve)**: the tip follows the surface under the mouse, the tool's depth above it
//!   (Shift: below it); its path becomes the rope;
//! - **probe (carve, pull)**: the probe's centre follows the surface under the mouse, the tool's
//!   depth below it (a negative depth: above it).
//!
//! The wheel sets the selected tool's depth (each tool keeps its own, [`MouseStylus::depth`]).
//! Without a press the tip rests on the surface (the probe at its depth, so it shows where a
//! press carves); off the object the cursor keeps its distance from the eye. A press off the
//! object does nothing until the button is released.

use std::sync::Arc;

use glam::DVec3;
use sim_core::grid::ScalarGrid;

use super::pick::{Hit, pick_chunks};
use crate::live::scene_file::ToolKind;
use crate::live::shared::RenderSnapshot;

/// Depth the wheel changes per point of scroll (m): 1 mm per wheel notch under X11 (egui
/// scrolled 80 points a notch under Xvfb).
pub const DEPTH_PER_SCROLL_POINT_M: f64 = 1.25e-5;

/// What the window knows of the mouse this frame.
#[derive(Debug, Clone)]
pub struct MouseFrame {
    /// The selected tool.
    pub tool: ToolKind,
    /// The eye (m).
    pub origin: DVec3,
    /// Unit direction of the ray through the mouse.
    pub dir: DVec3,
    /// Unit view direction (for depths from the eye).
    pub forward: DVec3,
    /// The mouse in the view (points).
    pub pixel: (f64, f64),
    /// Metres per point of the view at 1 m from the eye (scales with depth).
    pub metres_per_point_per_m: f64,
    /// Distance from the eye of the cursor's plane before anything was hit (m).
    pub start_depth: f64,
    /// The left button is down on the view.
    pub pressed: bool,
    /// Shift is held (the rope pushes in).
    pub shift: bool,
    /// The field snapshot the force thread reads.
    pub field: Option<Arc<ScalarGrid>>,
    /// The newest points.
    pub snapshot: Arc<RenderSnapshot>,
    /// How near the ray a point must be to be hit (m, about the points' spacing).
    pub radius: f64,
}

/// A press in progress.
#[derive(Debug, Clone)]
struct Held {
    tool: ToolKind,
    field: Option<Arc<ScalarGrid>>,
    snapshot: Arc<RenderSnapshot>,
    grab: Hit,
    pixel: (f64, f64),
    /// Metres per point at the grabbed point's depth.
    metres_per_point: f64,
}

/// The mouse stylus's state; see the module doc.
#[derive(Debug, Clone)]
pub struct MouseStylus {
    depths: [f64; 6],
    held: Option<Held>,
    /// A press off the object: ignored until released.
    ignored: bool,
    hit: Option<Hit>,
    cursor: DVec3,
}

impl Default for MouseStylus {
    fn default() -> Self {
        Self {
            depths: std::array::from_fn(|i| Self::DEFAULT_DEPTHS[i]),
            held: None,
            ignored: false,
            hit: None,
            cursor: DVec3::NAN,
        }
    }
}

fn slot(tool: ToolKind) -> usize {
    match tool {
        ToolKind::Touch => 0,
        ToolKind::Rope => 1,
        ToolKind::RopeCurve => 2,
        ToolKind::Paint => 3,
        ToolKind::ProbePush => 4,
        ToolKind::ProbePull => 5,
    }
}

impl MouseStylus {
    /// Depths at start (m), by tool: touch and paint press 1 mm in, the curve rope rides 5 mm
    /// above the surface, the probes' centres sit on it (the point rope uses the drag instead).
    pub const DEFAULT_DEPTHS: [f64; 6] = [0.001, 0.0, 0.005, 0.001, 0.0, 0.0];

    /// The range of a tool's depth (m).
    pub fn depth_range(tool: ToolKind) -> (f64, f64) {
        match tool {
            ToolKind::Touch | ToolKind::Paint => (0.0, 0.01),
            ToolKind::Rope => (0.0, 0.0),
            ToolKind::RopeCurve => (0.0, 0.02),
            ToolKind::ProbePush | ToolKind::ProbePull => (-0.02, 0.02),
        }
    }

    /// A tool's depth (m): see the module doc for what it means per tool.
    pub fn depth(&self, tool: ToolKind) -> f64 {
        self.depths[slot(tool)]
    }

    /// Change a tool's depth by `delta` (m), within its range.
    pub fn add_depth(&mut self, tool: ToolKind, delta: f64) {
        let (lo, hi) = Self::depth_range(tool);
        let d = &mut self.depths[slot(tool)];
        if delta.is_finite() {
            *d = (*d + delta).clamp(lo, hi);
        }
    }

    /// The surface under the mouse this frame (`None` off the object).
    pub fn hit(&self) -> Option<Hit> {
        self.hit
    }

    /// The grabbed surface point of the press in progress.
    pub fn grabbed(&self) -> Option<Hit> {
        self.held.as_ref().map(|h| h.grab)
    }

    /// Forget the press and the cursor's depth (a new scene, a new framing).
    pub fn reset(&mut self) {
        self.held = None;
        self.ignored = false;
        self.hit = None;
        self.cursor = DVec3::NAN;
    }

    /// The mouse left the view: the button counts as up, the cursor stays.
    pub fn leave(&mut self) -> (DVec3, u16) {
        self.held = None;
        self.ignored = false;
        (self.cursor, 0)
    }

    /// The cursor (scene m; NaN before the mouse was first over the object) and the buttons for
    /// this frame.
    pub fn update(&mut self, f: &MouseFrame) -> (DVec3, u16) {
        if !f.pressed {
            self.held = None;
            self.ignored = false;
        }
        // The surface under the mouse: the press's while held, else the newest.
        let (field, snapshot) = match &self.held {
            Some(h) => (h.field.clone(), Arc::clone(&h.snapshot)),
            None => (f.field.clone(), Arc::clone(&f.snapshot)),
        };
        self.hit = pick_chunks(
            field.as_deref(),
            &snapshot.points,
            f.origin,
            f.dir,
            f.radius,
        );
        if f.pressed && self.held.is_none() && !self.ignored {
            match self.hit {
                Some(grab) => {
                    self.held = Some(Held {
                        tool: f.tool,
                        field,
                        snapshot,
                        grab,
                        pixel: f.pixel,
                        metres_per_point: f.metres_per_point_per_m
                            * (grab.point - f.origin).dot(f.forward).max(0.0),
                    });
                }
                None => self.ignored = true,
            }
        }
        let tool = self.held.as_ref().map_or(f.tool, |h| h.tool);
        let depth = self.depth(tool);
        let on_surface = |h: Hit, below: f64| h.point - h.normal * below;
        let cursor = match (&self.held, self.hit) {
            (Some(h), _) if tool == ToolKind::Rope => {
                let (dx, dy) = (f.pixel.0 - h.pixel.0, f.pixel.1 - h.pixel.1);
                let out = dx.hypot(dy) * h.metres_per_point;
                let sign = if f.shift { -1.0 } else { 1.0 };
                h.grab.point + h.grab.normal * (sign * out)
            }
            (Some(_), Some(hit)) => match tool {
                ToolKind::RopeCurve => {
                    let sign = if f.shift { -1.0 } else { 1.0 };
                    hit.point + hit.normal * (sign * depth)
                }
                _ => on_surface(hit, depth),
            },
            (None, Some(hit)) => match tool {
                ToolKind::ProbePush | ToolKind::ProbePull => on_surface(hit, depth),
                _ => hit.point,
            },
            (_, None) => {
                // Off the object: at the cursor's distance from the eye.
                let along = f.dir.dot(f.forward).max(1e-6);
                let z = if self.cursor.is_finite() {
                    (self.cursor - f.origin).dot(f.forward)
                } else {
                    f.start_depth
                };
                f.origin + f.dir * (z.max(0.0) / along)
            }
        };
        self.cursor = cursor;
        (cursor, u16::from(self.held.is_some()))
    }
}

/// One line for the view: what the mouse does with `tool` at `depth` (m).
pub fn hint(tool: ToolKind, depth: f64) -> String {
    let mm = depth * 1e3;
    match tool {
        ToolKind::Touch => format!(
            "touch: the tip rides the surface under the mouse; hold the left button to press {mm:.1} mm in (wheel)"
        ),
        ToolKind::Paint => format!(
            "paint: hold the left button and drag over the surface, pressed {mm:.1} mm in (wheel)"
        ),
        ToolKind::Rope => "rope: press on the surface and drag: pulls out by the distance dragged (Shift: pushes in); release keeps it".to_owned(),
        ToolKind::RopeCurve => format!(
            "curve rope: hold and drag along the surface, the tip {mm:.1} mm above it (wheel; Shift: below)"
        ),
        ToolKind::ProbePush | ToolKind::ProbePull => format!(
            "probe: centre {mm:.1} mm below the surface (wheel; negative: above); hold the left button to {}",
            if tool == ToolKind::ProbePush { "carve" } else { "pull" }
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sim_core::grid::GridSpec;

    const R: f64 = 0.05;

    /// A camera at +z looking at a 5 cm sphere at the origin; the mouse at `pixel` of a
    /// 1000 × 1000 point view with 0.1 mm per point at 1 m.
    fn frame(tool: ToolKind, pixel: (f64, f64), pressed: bool, shift: bool) -> MouseFrame {
        let field = ScalarGrid::from_fn(
            GridSpec::covering(DVec3::splat(-0.08), DVec3::splat(0.08), 0.0025),
            |x| x.length() - R,
        );
        let s = 1e-4;
        let origin = DVec3::new(0.0, 0.0, 1.0);
        let dir = DVec3::new((pixel.0 - 500.0) * s, (500.0 - pixel.1) * s, -1.0).normalize();
        MouseFrame {
            tool,
            origin,
            dir,
            forward: DVec3::NEG_Z,
            pixel,
            metres_per_point_per_m: s,
            start_depth: 1.0,
            pressed,
            shift,
            field: Some(Arc::new(field)),
            snapshot: Arc::default(),
            radius: 0.002,
        }
    }

    #[test]
    fn the_cursor_rests_on_the_surface_under_the_mouse_and_a_press_touches_into_it() {
        let mut m = MouseStylus::default();
        let (p, b) = m.update(&frame(ToolKind::Touch, (500.0, 500.0), false, false));
        assert_eq!(b, 0);
        assert!((p - DVec3::new(0.0, 0.0, R)).length() < 1e-4, "{p}");
        let (p, b) = m.update(&frame(ToolKind::Touch, (600.0, 500.0), true, false));
        assert_eq!(b, 1);
        // 1 mm inside the sphere, under the mouse.
        assert!((p.length() - (R - 0.001)).abs() < 2e-4, "{}", p.length());
        assert!(p.x > 0.005);
    }

    #[test]
    fn a_rope_drag_pulls_out_by_the_distance_dragged_and_shift_pushes_in() {
        let mut m = MouseStylus::default();
        m.update(&frame(ToolKind::Rope, (500.0, 500.0), true, false));
        let grab = m.grabbed().unwrap();
        // 100 points at 0.95 m from the eye: 9.5 mm out along the normal (+z).
        let (p, b) = m.update(&frame(ToolKind::Rope, (560.0, 420.0), true, false));
        assert_eq!(b, 1);
        let out = (p - grab.point).dot(grab.normal);
        assert!((out - 100.0 * 1e-4 * (1.0 - R)).abs() < 1e-5, "{out}");
        let (p, _) = m.update(&frame(ToolKind::Rope, (560.0, 420.0), true, true));
        assert!(((p - grab.point).dot(grab.normal) + out).abs() < 1e-9);
        // Released: back on the surface under the mouse, button up.
        let (_, b) = m.update(&frame(ToolKind::Rope, (560.0, 420.0), false, false));
        assert_eq!(b, 0);
        assert!(m.grabbed().is_none());
    }

    #[test]
    fn the_wheel_sets_the_probes_depth_and_a_press_off_the_object_does_nothing() {
        let mut m = MouseStylus::default();
        m.add_depth(ToolKind::ProbePush, 0.003);
        m.add_depth(ToolKind::ProbePush, 1.0); // clamped
        assert_eq!(m.depth(ToolKind::ProbePush), 0.02);
        m.add_depth(ToolKind::ProbePush, -0.017);
        let (p, _) = m.update(&frame(ToolKind::ProbePush, (500.0, 500.0), false, false));
        assert!((p.z - (R - 0.003)).abs() < 1e-4, "{p}");
        // Off the object: no press, the cursor keeps its distance from the eye.
        let (q, b) = m.update(&frame(ToolKind::ProbePush, (10.0, 10.0), true, false));
        assert_eq!(b, 0);
        assert!((q.z - p.z).abs() < 1e-9);
        // Moved onto the object with the button still down: still nothing until released.
        let (_, b) = m.update(&frame(ToolKind::ProbePush, (500.0, 500.0), true, false));
        assert_eq!(b, 0);
        m.update(&frame(ToolKind::ProbePush, (500.0, 500.0), false, false));
        let (_, b) = m.update(&frame(ToolKind::ProbePush, (500.0, 500.0), true, false));
        assert_eq!(b, 1);
    }
}
