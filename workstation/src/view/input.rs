//! Input in the scene view: the camera (right-drag orbits, middle-drag or Shift + right-drag
//! pans, Ctrl + wheel zooms; the wheel alone zooms too when a device drives the cursor) and,
//! without a device, the mouse as the stylus ([`super::stylus`]: the left button presses,
//! Shift turns the rope inward, the wheel sets the tool's depth).

use std::sync::Arc;

use eframe::egui::{self, PointerButton};

use super::app::ViewApp;
use super::orbit::Orbit;
use super::pick::typical_spacing_chunks;
use super::stylus::{DEPTH_PER_SCROLL_POINT_M, MouseFrame};
use crate::live::shared::RenderSnapshot;

impl ViewApp {
    /// Orbit, pan and zoom from the pointer over the view; the wheel sets the mouse stylus's
    /// depth when the mouse is the device.
    pub(super) fn camera_input(
        &mut self,
        ui: &egui::Ui,
        response: &egui::Response,
        orbit: &mut Orbit,
        snap: &RenderSnapshot,
    ) {
        let h = response.rect.height() as f64;
        let shift = ui.input(|i| i.modifiers.shift);
        if response.dragged_by(PointerButton::Middle)
            || (shift && response.dragged_by(PointerButton::Secondary))
        {
            let d = response.drag_delta();
            orbit.pan(d.x as f64, d.y as f64, h);
        } else if response.dragged_by(PointerButton::Secondary) {
            let d = response.drag_delta();
            orbit.orbit(d.x as f64 * 0.01, d.y as f64 * 0.01);
        }
        let (scroll, zoom) = ui.input(|i| (i.smooth_scroll_delta.y as f64, i.zoom_delta() as f64));
        if response.hovered() {
            if zoom != 1.0 {
                orbit.zoom(1.0 / zoom);
            }
            if scroll != 0.0 {
                if self.link.mouse.is_some() {
                    // Wheel up takes the tool deeper (away from the eye).
                    let tool = snap.tool.unwrap_or(self.panel.tool);
                    self.stylus
                        .add_depth(tool, scroll * DEPTH_PER_SCROLL_POINT_M);
                } else {
                    orbit.zoom((-scroll * 0.002).exp());
                }
            }
        }
    }

    /// The mouse as the device (when it is): the stylus's cursor for the mouse over `rect`,
    /// streamed by the mouse thread.
    pub(super) fn mouse_input(
        &mut self,
        ui: &egui::Ui,
        response: &egui::Response,
        orbit: &Orbit,
        rect: egui::Rect,
        snap: &Arc<RenderSnapshot>,
    ) {
        let Some(hand) = self.link.mouse.clone() else {
            return;
        };
        let pointer = response.hover_pos().or(response.interact_pointer_pos());
        self.pointer = pointer.map(|p| p * ui.ctx().pixels_per_point());
        let Some(p) = pointer else {
            let (at, buttons) = self.stylus.leave();
            hand.set(at, buttons);
            return;
        };
        let (w, h) = (rect.width() as f64, rect.height() as f64);
        let q = p - rect.min;
        let (x, y) = (q.x as f64, q.y as f64);
        let (origin, dir) = orbit.ray(x, y, w, h);
        let per_m = orbit.metres_per_pixel_per_metre(h);
        // Points are hit within about their spacing (measured when their count changes), and
        // never less than two pixels at the target.
        let n = snap.points.len();
        if self.pick_spacing.is_none_or(|(m, _)| m != n) {
            self.pick_spacing = typical_spacing_chunks(&snap.points).map(|s| (n, s));
        }
        let spacing = self.pick_spacing.map_or(0.0, |(_, s)| s);
        let frame = MouseFrame {
            tool: snap.tool.unwrap_or(self.panel.tool),
            origin,
            dir,
            forward: orbit.forward(),
            pixel: (x, y),
            metres_per_point_per_m: per_m,
            start_depth: orbit.distance,
            pressed: response.is_pointer_button_down_on()
                && ui.input(|i| i.pointer.button_down(PointerButton::Primary)),
            shift: ui.input(|i| i.modifiers.shift),
            field: self.link.shared.field.load_full(),
            snapshot: Arc::clone(snap),
            radius: spacing.max(2.0 * per_m * orbit.distance),
        };
        let (at, buttons) = self.stylus.update(&frame);
        hand.set(at, buttons);
    }
}
