//! A perspective camera looking from `eye` at `target`.

use glam::{Mat4, Vec3, Vec4Swizzles};

use crate::RenderError;

/// A right-handed perspective camera; depth maps `near..far` to `0..1` (wgpu's convention).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position in metres.
    pub eye: [f32; 3],
    /// The point looked at (the centre of the image).
    pub target: [f32; 3],
    /// Approximate up direction; must not be parallel to `target - eye`.
    pub up: [f32; 3],
    /// Vertical field of view in degrees, in (0, 180).
    pub fov_y_deg: f32,
    /// Distance to the near clipping plane, > 0.
    pub near: f32,
    /// Distance to the far clipping plane, > `near`.
    pub far: f32,
}

impl Camera {
    /// Vertical field of view [`Camera::framing`] uses, in degrees.
    pub const FRAMING_FOV_Y_DEG: f32 = 40.0;

    /// A camera looking along `view_dir` at the centre of the box `min..max`, far enough that
    /// the box's bounding sphere fits the vertical field of view with a 5 % margin (so it fits
    /// any target at least as wide as it is tall). Up is +Y, or +Z when looking along ±Y.
    /// Near and far leave room for overlays up to twice the box's size around it.
    pub fn framing(min: [f32; 3], max: [f32; 3], view_dir: [f32; 3]) -> Self {
        let (min, max) = (Vec3::from(min), Vec3::from(max));
        let center = 0.5 * (min + max);
        let radius = (0.5 * (max - min).length())
            .max(1e-6 * center.length())
            .max(1e-9);
        let dir = Vec3::from(view_dir).try_normalize().unwrap_or(Vec3::NEG_Z);
        let up = if dir.y.abs() > 0.99 { Vec3::Z } else { Vec3::Y };
        let half_fov = (0.5 * Self::FRAMING_FOV_Y_DEG).to_radians();
        let distance = 1.05 * radius / half_fov.sin();
        Self {
            eye: (center - distance * dir).into(),
            target: center.into(),
            up: up.into(),
            fov_y_deg: Self::FRAMING_FOV_Y_DEG,
            near: (distance - 3.0 * radius).max(0.01 * distance),
            far: distance + 3.0 * radius,
        }
    }

    /// Checks the camera can make a projection: finite values, a field of view in (0°, 180°),
    /// `0 < near < far`, eye distinct from target and up not parallel to the view direction.
    pub fn validate(&self) -> Result<(), RenderError> {
        let finite = self
            .eye
            .iter()
            .chain(&self.target)
            .chain(&self.up)
            .all(|v| v.is_finite())
            && self.fov_y_deg.is_finite()
            && self.near.is_finite()
            && self.far.is_finite();
        if !finite {
            return Err(RenderError::InvalidCamera("a value is not finite"));
        }
        if !(self.fov_y_deg > 0.0 && self.fov_y_deg < 180.0) {
            return Err(RenderError::InvalidCamera("fov_y_deg must be in (0, 180)"));
        }
        if !(self.near > 0.0 && self.far > self.near) {
            return Err(RenderError::InvalidCamera("needs 0 < near < far"));
        }
        let forward = Vec3::from(self.target) - Vec3::from(self.eye);
        let Some(forward) = forward.try_normalize() else {
            return Err(RenderError::InvalidCamera("eye and target coincide"));
        };
        if forward.cross(Vec3::from(self.up)).try_normalize().is_none() {
            return Err(RenderError::InvalidCamera(
                "up is zero or parallel to the view direction",
            ));
        }
        Ok(())
    }

    /// World-to-view matrix (right-handed, looking down −Z).
    pub(crate) fn view(&self) -> Mat4 {
        Mat4::look_at_rh(self.eye.into(), self.target.into(), self.up.into())
    }

    /// View-to-clip matrix for an image `aspect = width / height`.
    pub(crate) fn projection(&self, aspect: f32) -> Mat4 {
        Mat4::perspective_rh(self.fov_y_deg.to_radians(), aspect, self.near, self.far)
    }

    /// Where world point `p` lands in a `width × height` image, in pixels (x right, y down, pixel
    /// `(i, j)` covering `[i, i+1) × [j, j+1)`), or `None` if it is behind the near plane or the
    /// camera is invalid. Points outside the image are returned too.
    pub fn project(&self, p: [f32; 3], width: u32, height: u32) -> Option<[f32; 2]> {
        self.validate().ok()?;
        let clip =
            self.projection(width as f32 / height as f32) * self.view() * Vec3::from(p).extend(1.0);
        if clip.z < 0.0 || clip.w <= 0.0 {
            return None;
        }
        let ndc = clip.xy() / clip.w;
        Some([
            (ndc.x + 1.0) * 0.5 * width as f32,
            (1.0 - ndc.y) * 0.5 * height as f32,
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn framing_keeps_every_box_corner_in_the_image() {
        let (min, max) = ([-0.1, 0.2, 0.3], [0.4, 0.3, 0.9]);
        for dir in [
            [0.0, 0.0, -1.0],
            [1.0, -0.5, 0.2],
            [0.0, -1.0, 0.0],
            [0.0, 1.0, 0.0],
        ] {
            let cam = Camera::framing(min, max, dir);
            cam.validate().unwrap();
            for i in 0..8 {
                let c = [
                    if i & 1 == 0 { min[0] } else { max[0] },
                    if i & 2 == 0 { min[1] } else { max[1] },
                    if i & 4 == 0 { min[2] } else { max[2] },
                ];
                let [x, y] = cam.project(c, 640, 480).expect("in front of the camera");
                assert!(
                    (0.0..640.0).contains(&x) && (0.0..480.0).contains(&y),
                    "{dir:?} {c:?}"
                );
            }
            let [x, y] = cam.project(cam.target, 640, 480).unwrap();
            assert!((x - 320.0).abs() < 1e-3 && (y - 240.0).abs() < 1e-3);
        }
    }

    #[test]
    fn up_is_up_in_the_image() {
        let cam = Camera::framing([-1.0; 3], [1.0; 3], [0.0, 0.0, -1.0]);
        let [_, y_top] = cam.project([0.0, 0.5, 0.0], 100, 100).unwrap();
        let [x_right, _] = cam.project([0.5, 0.0, 0.0], 100, 100).unwrap();
        assert!(y_top < 50.0 && x_right > 50.0);
    }

    #[test]
    fn invalid_cameras_are_named() {
        let ok = Camera::framing([0.0; 3], [1.0; 3], [0.0, 0.0, -1.0]);
        let bad = [
            Camera { near: 0.0, ..ok },
            Camera { far: ok.near, ..ok },
            Camera {
                fov_y_deg: 180.0,
                ..ok
            },
            Camera {
                eye: ok.target,
                ..ok
            },
            Camera {
                up: [0.0, 0.0, 1.0],
                eye: [0.5, 0.5, 3.0],
                target: [0.5, 0.5, 0.5],
                ..ok
            },
            Camera {
                eye: [f32::NAN, 0.0, 0.0],
                ..ok
            },
        ];
        for cam in bad {
            assert!(
                matches!(cam.validate(), Err(RenderError::InvalidCamera(_))),
                "{cam:?}"
            );
        }
    }
}
