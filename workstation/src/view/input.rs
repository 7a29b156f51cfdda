//! Input in the scene view: the camera (right-drag orbits, middle-drag or Shift + right-drag
//! pans, Ctrl + wheel zooms; the wheel alone zooms too when a device is connected) and, without
//! a device, the mouse as the device.

use eframe::egui::{self, PointerButton};

use super::app::ViewApp;
use super::orbit::Orbit;

impl ViewApp {
    /// Orbit, pan and zoom from the pointer over the view (`h`: the view's height in points).
    pub(super) fn camera_input(
        &mut self,
        ui: &egui::Ui,
        response: &egui::Response,
        orbit: &mut Orbit,
        h: f64,
    ) {
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
                    // Wheel up pushes the cursor's plane away from the eye.
                    self.depth = (self.depth - scroll * 2e-4 * orbit.distance).clamp(
                        0.05 * orbit.distance,
                        orbit.distance + 3.0 * orbit.scene_radius,
                    );
                } else {
                    orbit.zoom((-scroll * 0.002).exp());
                }
            }
        }
    }

    /// The mouse as the device (when it is): the cursor under the mouse, the left button as the
    /// stylus button. `rect`: the view, `w` × `h` points.
    pub(super) fn mouse_input(
        &mut self,
        ui: &egui::Ui,
        response: &egui::Response,
        orbit: &Orbit,
        rect: egui::Rect,
    ) {
        let Some(hand) = &self.link.mouse else {
            return;
        };
        let (w, h) = (rect.width() as f64, rect.height() as f64);
        let pressed = response.is_pointer_button_down_on()
            && ui.input(|i| i.pointer.button_down(PointerButton::Primary));
        if let Some(p) = response.hover_pos().or(response.interact_pointer_pos()) {
            let q = p - rect.min;
            let at = orbit.point_at_depth(q.x as f64, q.y as f64, w, h, self.depth);
            hand.set(at, u16::from(pressed));
        } else {
            let (at, _) = hand.get();
            hand.set(at, 0);
        }
    }
}
