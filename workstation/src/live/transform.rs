//! The device-to-scene transform with workspace scaling (DESIGN §1):
//! `x_scene = t + s · R · x_device`.
//!
//! Forces keep their newtons and turn with `R⁻¹`; a local contact model moves into the device
//! frame with its stiffness and damping multiplied by `s` (one device metre is `s` scene metres,
//! so a scene spring `k` feels like `k·s` at the hand) and its validity radius divided by `s`.

use glam::{DQuat, DVec3};
use sim_core::haptic::HapticOutput;

/// `x_scene = translation + scale · rotation · x_device`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeviceTransform {
    rotation: DQuat,
    translation: DVec3,
    scale: f64,
}

impl Default for DeviceTransform {
    fn default() -> Self {
        Self::new(DQuat::IDENTITY, DVec3::ZERO, 1.0)
    }
}

impl DeviceTransform {
    /// A transform; `scale` must be positive and finite (the scene file checks it).
    pub fn new(rotation: DQuat, translation: DVec3, scale: f64) -> Self {
        Self {
            rotation: rotation.normalize(),
            translation,
            scale,
        }
    }

    /// Scene metres per device metre.
    pub fn scale(&self) -> f64 {
        self.scale
    }

    /// A device position in the scene.
    pub fn point_to_scene(&self, p: DVec3) -> DVec3 {
        self.translation + self.scale * (self.rotation * p)
    }

    /// A device velocity in the scene.
    pub fn vector_to_scene(&self, v: DVec3) -> DVec3 {
        self.scale * (self.rotation * v)
    }

    /// A device orientation in the scene.
    pub fn rotation_to_scene(&self, q: DQuat) -> DQuat {
        (self.rotation * q).normalize()
    }

    /// A scene position in the device frame.
    pub fn point_to_device(&self, p: DVec3) -> DVec3 {
        self.rotation.inverse() * ((p - self.translation) / self.scale)
    }

    /// A scene force (N) in the device frame (N).
    pub fn force_to_device(&self, f: DVec3) -> DVec3 {
        self.rotation.inverse() * f
    }

    /// A force and its local model, computed in the scene, as the device must render them.
    pub fn output_to_device(&self, out: &HapticOutput) -> HapticOutput {
        let mut o = *out;
        o.force = self.force_to_device(out.force);
        o.model.point = self.point_to_device(out.model.point);
        o.model.normal = self.force_to_device(out.model.normal);
        o.model.stiffness *= self.scale;
        o.model.damping *= self.scale;
        o.model.validity_radius /= self.scale;
        o
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sim_core::haptic::{ContactModel, HapticOutput};

    #[test]
    fn round_trip_and_scaled_stiffness() {
        let t = DeviceTransform::new(DQuat::from_rotation_y(0.7), DVec3::new(0.1, -0.2, 0.3), 2.5);
        let p = DVec3::new(0.01, 0.02, -0.03);
        let back = t.point_to_device(t.point_to_scene(p));
        assert!((back - p).length() < 1e-12);
        // A scene wall of stiffness k, entered by δ device metres = s·δ scene metres.
        let out = HapticOutput {
            force: DVec3::new(1.0, 0.0, 0.0),
            model: ContactModel {
                stiffness: 400.0,
                damping: 1.0,
                validity_radius: 0.01,
                ..ContactModel::none(0.05)
            },
        };
        let dev = t.output_to_device(&out);
        assert!((dev.force.length() - 1.0).abs() < 1e-12, "newtons are kept");
        assert!((dev.model.stiffness - 1000.0).abs() < 1e-9);
        assert!((dev.model.validity_radius - 0.004).abs() < 1e-12);
        let f_scene = t.vector_to_scene(dev.force) / t.scale();
        assert!((f_scene - out.force).length() < 1e-12, "direction is kept");
    }
}
