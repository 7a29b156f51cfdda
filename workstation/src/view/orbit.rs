//! The window's camera: orbit around a target, pan, zoom, frame a box; the mouse's rays into
//! the scene and where a point is seen. Pure math, no window: tested here.

use glam::{DVec3, Vec3};
use render::Camera;

/// An orbiting camera: looks at `target` from `distance` along the direction given by `yaw`
/// (about +Y) and `pitch` (above the horizon).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Orbit {
    /// The point looked at (m).
    pub target: DVec3,
    /// Eye distance from the target (m).
    pub distance: f64,
    /// Radians about +Y.
    pub yaw: f64,
    /// Radians above the horizon, within ±89°.
    pub pitch: f64,
    /// Radius of the framed scene (m): sets near/far and the pan and depth steps.
    pub scene_radius: f64,
}

impl Orbit {
    /// Vertical field of view (degrees).
    pub const FOV_Y_DEG: f64 = 40.0;
    const MAX_PITCH: f64 = 89.0 * std::f64::consts::PI / 180.0;

    /// A camera looking along `view_dir` at the box `lo..hi`, which fills the view (as
    /// [`Camera::framing`]).
    pub fn framing(lo: DVec3, hi: DVec3, view_dir: DVec3) -> Self {
        let d = view_dir.try_normalize().unwrap_or(DVec3::NEG_Z);
        let radius = (0.5 * (hi - lo).length()).max(1e-6);
        let half = (0.5 * Self::FOV_Y_DEG).to_radians();
        let back = -d; // from the target towards the eye
        Self {
            target: 0.5 * (lo + hi),
            distance: 1.05 * radius / half.sin(),
            yaw: back.x.atan2(back.z),
            pitch: back
                .y
                .clamp(-1.0, 1.0)
                .asin()
                .clamp(-Self::MAX_PITCH, Self::MAX_PITCH),
            scene_radius: radius,
        }
    }

    /// Unit vector from the target to the eye.
    pub fn back(&self) -> DVec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        DVec3::new(sy * cp, sp, cy * cp)
    }

    /// The eye (m).
    pub fn eye(&self) -> DVec3 {
        self.target + self.distance * self.back()
    }

    /// Unit view direction (eye → target).
    pub fn forward(&self) -> DVec3 {
        -self.back()
    }

    /// Right and up unit vectors of the image.
    pub fn right_up(&self) -> (DVec3, DVec3) {
        let f = self.forward();
        let right = f.cross(DVec3::Y).try_normalize().unwrap_or(DVec3::X);
        (right, right.cross(f))
    }

    /// Turn by `dx`, `dy` radians (drag right: the scene turns right; drag up: it tilts up).
    pub fn orbit(&mut self, dx: f64, dy: f64) {
        self.yaw -= dx;
        self.pitch = (self.pitch + dy).clamp(-Self::MAX_PITCH, Self::MAX_PITCH);
    }

    /// Move the target by a drag of (`dx`, `dy`) pixels in a view `height` pixels tall, so the
    /// point under the mouse at the target's depth stays under it.
    pub fn pan(&mut self, dx: f64, dy: f64, height: f64) {
        let per_px = self.metres_per_pixel(height);
        let (right, up) = self.right_up();
        self.target += (-dx * right + dy * up) * per_px;
    }

    /// Scale the distance by `factor` (< 1 comes closer), kept within 1e-3…100 scene radii.
    pub fn zoom(&mut self, factor: f64) {
        if factor.is_finite() && factor > 0.0 {
            self.distance =
                (self.distance * factor).clamp(1e-3 * self.scene_radius, 100.0 * self.scene_radius);
        }
    }

    /// Metres per pixel at the target's depth.
    pub fn metres_per_pixel(&self, height: f64) -> f64 {
        2.0 * self.distance * (0.5 * Self::FOV_Y_DEG).to_radians().tan() / height.max(1.0)
    }

    /// The renderer's camera (near and far leave room for the scene and overlays around it).
    pub fn camera(&self) -> Camera {
        let r = self.scene_radius;
        let near = (self.distance - 4.0 * r).max(1e-3 * self.distance.max(r));
        Camera {
            eye: self.eye().as_vec3().to_array(),
            target: self.target.as_vec3().to_array(),
            up: if self.pitch.abs() > 88f64.to_radians() {
                Vec3::Z.to_array()
            } else {
                Vec3::Y.to_array()
            },
            fov_y_deg: Self::FOV_Y_DEG as f32,
            near: near as f32,
            far: (self.distance + 4.0 * r) as f32,
        }
    }

    /// The ray through pixel (`x`, `y`) of a `width × height` view: origin (the eye) and unit
    /// direction.
    pub fn ray(&self, x: f64, y: f64, width: f64, height: f64) -> (DVec3, DVec3) {
        let t = (0.5 * Self::FOV_Y_DEG).to_radians().tan();
        let aspect = width / height.max(1.0);
        let ndc_x = 2.0 * x / width.max(1.0) - 1.0;
        let ndc_y = 1.0 - 2.0 * y / height.max(1.0);
        let (right, up) = self.right_up();
        let d = self.forward() + right * (ndc_x * t * aspect) + up * (ndc_y * t);
        (self.eye(), d.normalize())
    }

    /// Metres per pixel at 1 m from the eye in a view `height` pixels tall (at depth `z`:
    /// `z` times this).
    pub fn metres_per_pixel_per_metre(&self, height: f64) -> f64 {
        2.0 * (0.5 * Self::FOV_Y_DEG).to_radians().tan() / height.max(1.0)
    }

    /// The pixel (`x`, `y`) of a `width × height` view where `p` is seen; `None` behind the
    /// eye. The inverse of [`Orbit::ray`].
    pub fn project(&self, p: DVec3, width: f64, height: f64) -> Option<(f64, f64)> {
        let d = p - self.eye();
        let z = d.dot(self.forward());
        if z.is_nan() || z <= 1e-9 {
            return None;
        }
        let t = (0.5 * Self::FOV_Y_DEG).to_radians().tan();
        let aspect = width / height.max(1.0);
        let (right, up) = self.right_up();
        let ndc_x = d.dot(right) / (z * t * aspect);
        let ndc_y = d.dot(up) / (z * t);
        Some((
            0.5 * (ndc_x + 1.0) * width.max(1.0),
            0.5 * (1.0 - ndc_y) * height.max(1.0),
        ))
    }

    /// Where the ray through pixel (`x`, `y`) meets the plane facing the camera at `depth`
    /// metres from the eye (the mouse cursor's plane).
    pub fn point_at_depth(&self, x: f64, y: f64, width: f64, height: f64, depth: f64) -> DVec3 {
        let (o, d) = self.ray(x, y, width, height);
        let along = d.dot(self.forward()).max(1e-6);
        o + d * (depth / along)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn orbit() -> Orbit {
        Orbit::framing(
            DVec3::splat(-0.05),
            DVec3::splat(0.05),
            DVec3::new(0.0, 0.0, -1.0),
        )
    }

    #[test]
    fn framing_looks_along_the_view_direction_at_the_centre() {
        let o = orbit();
        assert!((o.forward() - DVec3::NEG_Z).length() < 1e-9);
        assert!(o.target.length() < 1e-12);
        // The box's bounding sphere fits the vertical field of view.
        let r = 0.05 * 3f64.sqrt();
        assert!(o.distance * (0.5 * Orbit::FOV_Y_DEG).to_radians().sin() >= r);
        let c = o.camera();
        c.validate().unwrap();
        assert!(c.near > 0.0 && c.near < (o.distance - r) as f32);
        assert!(c.far > (o.distance + r) as f32);
    }

    #[test]
    fn the_centre_pixel_ray_hits_the_target_and_corners_spread() {
        let o = orbit();
        let p = o.point_at_depth(400.0, 300.0, 800.0, 600.0, o.distance);
        assert!((p - o.target).length() < 1e-9, "{p}");
        // The right edge at the target's depth is half the view width to the right.
        let right = o.point_at_depth(800.0, 300.0, 800.0, 600.0, o.distance);
        let half_w = 0.5 * 800.0 * o.metres_per_pixel(600.0);
        assert!((right.x - half_w).abs() < 1e-9, "{right} vs {half_w}");
        let top = o.point_at_depth(400.0, 0.0, 800.0, 600.0, o.distance);
        assert!(top.y > 0.0, "screen up is +Y");
    }

    #[test]
    fn projecting_a_point_gives_the_pixel_whose_ray_passes_through_it() {
        let mut o = orbit();
        o.orbit(0.4, 0.3);
        let p = DVec3::new(0.02, -0.01, 0.03);
        let (x, y) = o.project(p, 800.0, 600.0).unwrap();
        let (eye, d) = o.ray(x, y, 800.0, 600.0);
        let off = (p - eye) - d * (p - eye).dot(d);
        assert!(off.length() < 1e-12, "{off}");
        assert_eq!(o.project(o.eye() + o.back(), 800.0, 600.0), None);
        let per_m = o.metres_per_pixel_per_metre(600.0);
        assert!((per_m * o.distance - o.metres_per_pixel(600.0)).abs() < 1e-15);
    }

    #[test]
    fn orbit_pan_and_zoom_keep_the_camera_valid() {
        let mut o = orbit();
        o.orbit(0.3, 10.0); // pitch clamps below the pole
        assert!(o.pitch < 89.1f64.to_radians());
        o.camera().validate().unwrap();
        let t = o.target;
        o.pan(100.0, 0.0, 600.0);
        let moved = (o.target - t).length();
        assert!((moved - 100.0 * o.metres_per_pixel(600.0)).abs() < 1e-12);
        let d = o.distance;
        o.zoom(0.5);
        assert!((o.distance - 0.5 * d).abs() < 1e-12);
        o.zoom(f64::NAN);
        o.zoom(1e-9);
        assert!(o.distance >= 1e-3 * o.scene_radius);
        o.camera().validate().unwrap();
    }
}
