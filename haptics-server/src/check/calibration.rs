//! Device-to-scene calibration: the workspace a device declares and the range it was seen
//! to cover, and the scene transform that maps either onto a region of the scene.
//!
//! The workstation maps `x_scene = translation + scale · R(rotation_deg) · x_device`
//! (`workstation/src/live/transform.rs`), read from a scene file's `[device]` table with
//! fields `scale`, `translation = [x, y, z]` and `rotation_deg = [x, y, z]` (XYZ Euler angles
//! in degrees, `glam`'s `EulerRot::XYZ`; `workstation/src/live/scene_file.rs`). Scenes are
//! y-up, z toward the viewer. [`frame`] knows each backend's axes: the OpenHaptics convention
//! (x right, y up, z toward the user) is the scene's; Force Dimension's (x toward the user,
//! y right, z up) needs a rotation.
//!
//! The scale is uniform. `cover` (the default) makes the whole region reachable: the largest
//! ratio of region extent to device extent over the axes, so the workspace's image contains
//! the region; `inside` keeps the image inside the region (the smallest ratio).

use glam::{DMat3, DQuat, DVec3, EulerRot};
use serde::Serialize;

use crate::config::DeviceKind;

/// A box, m.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Aabb {
    /// Lower corner.
    pub min: [f64; 3],
    /// Upper corner.
    pub max: [f64; 3],
}

impl Aabb {
    /// From two corners.
    pub fn new(min: DVec3, max: DVec3) -> Self {
        Self {
            min: min.to_array(),
            max: max.to_array(),
        }
    }

    fn lo(&self) -> DVec3 {
        DVec3::from(self.min)
    }

    fn hi(&self) -> DVec3 {
        DVec3::from(self.max)
    }

    /// Parse `MINX,MINY,MINZ,MAXX,MAXY,MAXZ` (metres; every max above its min).
    pub fn parse(text: &str) -> Result<Self, String> {
        let v: Vec<f64> = text
            .split(',')
            .map(|s| {
                s.trim()
                    .parse::<f64>()
                    .map_err(|e| format!("{:?}: {e}", s.trim()))
            })
            .collect::<Result<_, _>>()?;
        let [a, b, c, d, e, f] = v[..] else {
            return Err(format!(
                "{text:?}: expected six numbers MINX,MINY,MINZ,MAXX,MAXY,MAXZ (metres), got {}",
                v.len()
            ));
        };
        let (min, max) = (DVec3::new(a, b, c), DVec3::new(d, e, f));
        if !(min.is_finite() && max.is_finite() && max.cmpgt(min).all()) {
            return Err(format!(
                "{text:?}: every max must be finite and above its min"
            ));
        }
        Ok(Self::new(min, max))
    }
}

/// How a backend's device frame sits against the scene's (y up, z toward the viewer).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// The axes in words.
    pub description: &'static str,
    /// Device axes in scene coordinates: columns are the images of device x, y, z.
    pub to_scene: DMat3,
}

/// The frame of `kind`'s devices.
pub fn frame(kind: DeviceKind) -> Frame {
    match kind {
        DeviceKind::Dhd => Frame {
            description: "Force Dimension: x toward the user, y right, z up",
            to_scene: DMat3::from_cols(DVec3::Z, DVec3::X, DVec3::Y),
        },
        DeviceKind::Openhaptics => Frame {
            description: "OpenHaptics: x right, y up, z toward the user (the scene's axes)",
            to_scene: DMat3::IDENTITY,
        },
        DeviceKind::Hid => Frame {
            description: "as the HID profile reports (assumed x right, y up, z toward the user)",
            to_scene: DMat3::IDENTITY,
        },
        DeviceKind::Fake | DeviceKind::Replay => Frame {
            description: "x right, y up, z toward the user (the scene's axes)",
            to_scene: DMat3::IDENTITY,
        },
    }
}

/// How to choose the uniform scale.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Fit {
    /// The whole region is reachable (the workspace's image contains it).
    Cover,
    /// The workspace's image stays inside the region.
    Inside,
}

/// A scene file's `[device]` table.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SceneTransform {
    /// Which device box was mapped: `declared` or `seen`.
    pub from: String,
    /// The device box, m (device frame).
    pub device_box: Aabb,
    /// The region, m (scene frame).
    pub region: Aabb,
    /// How the scale was chosen.
    pub fit: Fit,
    /// Scene metres per device metre.
    pub scale: f64,
    /// Scene position of the device origin, m.
    pub translation: [f64; 3],
    /// XYZ Euler angles, degrees.
    pub rotation_deg: [f64; 3],
    /// The table as a scene file takes it.
    pub toml: String,
}

/// The transform mapping `device_box` (device frame `frame`) onto `region`.
pub fn transform(
    from: &str,
    device_box: Aabb,
    frame: &Frame,
    region: Aabb,
    fit: Fit,
) -> SceneTransform {
    let r = DQuat::from_mat3(&frame.to_scene).normalize();
    // The device box turned into the scene's axes (a signed permutation keeps it a box).
    let (a, b) = (r * device_box.lo(), r * device_box.hi());
    let (dmin, dmax) = (a.min(b), a.max(b));
    let dext = (dmax - dmin).max(DVec3::splat(1e-9));
    let rext = region.hi() - region.lo();
    let ratios = rext / dext;
    let scale = match fit {
        Fit::Cover => ratios.max_element(),
        Fit::Inside => ratios.min_element(),
    };
    let dcenter = (dmin + dmax) * 0.5;
    let rcenter = (region.lo() + region.hi()) * 0.5;
    let translation = rcenter - scale * dcenter;
    let (x, y, z) = r.to_euler(EulerRot::XYZ);
    let rotation_deg = [x, y, z].map(|a| clean(a.to_degrees()));
    let translation = translation.to_array().map(clean);
    let scale = clean(scale);
    let toml = format!(
        "[device]\nscale = {}\ntranslation = [{}, {}, {}]\nrotation_deg = [{}, {}, {}]\n",
        num(scale),
        num(translation[0]),
        num(translation[1]),
        num(translation[2]),
        num(rotation_deg[0]),
        num(rotation_deg[1]),
        num(rotation_deg[2]),
    );
    SceneTransform {
        from: from.into(),
        device_box,
        region,
        fit,
        scale,
        translation,
        rotation_deg,
        toml,
    }
}

/// Round to 9 significant decimals so 89.99999999 prints as 90 and -0 as 0.
fn clean(v: f64) -> f64 {
    let r = (v * 1e9).round() / 1e9;
    if r == 0.0 { 0.0 } else { r }
}

/// A TOML float: always with a decimal point.
fn num(v: f64) -> String {
    let s = format!("{v}");
    if s.contains('.') || s.contains('e') || s.contains("inf") || s.contains("NaN") {
        s
    } else {
        format!("{s}.0")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn apply(t: &SceneTransform, p: DVec3) -> DVec3 {
        let [x, y, z] = t.rotation_deg.map(f64::to_radians);
        let r = DQuat::from_euler(EulerRot::XYZ, x, y, z);
        DVec3::from(t.translation) + t.scale * (r * p)
    }

    #[test]
    fn a_phantom_workspace_covers_the_demo_region() {
        let dev = Aabb::new(DVec3::splat(-0.08), DVec3::splat(0.08));
        let region = Aabb::parse("-0.05,0,-0.05,0.05,0.06,0.05").unwrap();
        let t = transform(
            "declared",
            dev,
            &frame(DeviceKind::Openhaptics),
            region,
            Fit::Cover,
        );
        assert_eq!(t.rotation_deg, [0.0, 0.0, 0.0]);
        assert!((t.scale - 0.625).abs() < 1e-12, "{}", t.scale);
        assert_eq!(t.translation, [0.0, 0.03, 0.0]);
        assert!(
            t.toml
                .contains("scale = 0.625\ntranslation = [0.0, 0.03, 0.0]\n")
        );
        let inside = transform(
            "declared",
            dev,
            &frame(DeviceKind::Fake),
            region,
            Fit::Inside,
        );
        assert!((inside.scale - 0.375).abs() < 1e-12);
    }

    #[test]
    fn a_force_dimension_frame_is_turned_z_up_to_y_up() {
        let dev = Aabb::new(DVec3::new(-0.05, -0.1, -0.02), DVec3::new(0.05, 0.1, 0.02));
        let region = Aabb::parse("0,0,0,0.2,0.04,0.1").unwrap();
        let t = transform("seen", dev, &frame(DeviceKind::Dhd), region, Fit::Cover);
        // Device z (up) goes to scene y; device x (toward the user) to scene z; y to x.
        let up = apply(&t, DVec3::Z) - apply(&t, DVec3::ZERO);
        assert!((up.normalize() - DVec3::Y).length() < 1e-9, "{up}");
        let toward = apply(&t, DVec3::X) - apply(&t, DVec3::ZERO);
        assert!((toward.normalize() - DVec3::Z).length() < 1e-9, "{toward}");
        // Centres meet and the region is covered: extents 0.2/0.04/0.1 over 0.2/0.04/0.1.
        let c = apply(&t, DVec3::ZERO);
        assert!((c - DVec3::new(0.1, 0.02, 0.05)).length() < 1e-9, "{c}");
        assert!((t.scale - 1.0).abs() < 1e-9);
        assert!(t.toml.starts_with("[device]\nscale = 1.0\n"), "{}", t.toml);
    }

    #[test]
    fn regions_are_checked() {
        assert!(
            Aabb::parse("0,0,0,1,1")
                .unwrap_err()
                .contains("six numbers")
        );
        assert!(
            Aabb::parse("0,0,0,1,-1,1")
                .unwrap_err()
                .contains("above its min")
        );
        assert!(Aabb::parse("0,0,0,1,x,1").is_err());
    }
}
