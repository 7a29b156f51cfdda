//! Embossing and engraving (003, Fig. 3): a greyscale image mapped onto the surface (planar,
//! cylindrical or spherical mapping) gives a displacement `δ = depth · I(u, v)` along the normal;
//! points move onto the displaced iso-surface `f(x) = δ(x)`; a negative depth engraves.
//!
//! Each point moves to `p + δ(p) n`, then two Newton steps on `g = f − δ` (gradient of `f`
//! only: `δ` varies over pixels, not within a Newton step). Its normal tilts by the surface
//! gradient of `δ` (central differences across the tangent plane): `n' ∝ n − ∇ₛδ`.
//!
//! Detail: an image's edges are steps of `depth` within a pixel, and a surface sampled more
//! coarsely than that shows a jumble instead of the picture. [`detail_insertions`] first adds
//! points on the surface where the displacement changes by more than a quarter of `depth`
//! within a point's spacing, halving the spacing there level by level down to a quarter of the
//! object's (at most ~16× the points near edges, none where the image is flat).
//!
//! Contract: images are non-empty with finite intensities in `[0, 1]` (PNG grey, grey+alpha,
//! RGB, RGBA, 8 or 16 bit: luminance); sampling is bilinear between pixel centres and clamped at
//! the border, so a 1×1 image is a constant and any contrast gives finite results. Points
//! outside the mapping's `[0, 1]²` do not move. The field is *not* updated: refit afterwards.

use glam::DVec3;

use crate::field::GlobalField;
use crate::linalg::tangent_frame;
use crate::tools::{ToolError, finite};

/// A greyscale image, intensities in `[0, 1]`, row 0 at `v = 0`.
#[derive(Debug, Clone, PartialEq)]
pub struct GreyImage {
    width: usize,
    height: usize,
    pixels: Vec<f64>,
}

impl GreyImage {
    /// An image from row-major intensities in `[0, 1]`.
    pub fn new(width: usize, height: usize, pixels: Vec<f64>) -> Result<Self, ToolError> {
        if width == 0 || height == 0 || pixels.len() != width * height {
            return Err(ToolError::Image(format!(
                "{width}×{height} image with {} pixels",
                pixels.len()
            )));
        }
        if let Some(i) = pixels.iter().position(|p| !(0.0..=1.0).contains(p)) {
            return Err(ToolError::Image(format!(
                "pixel {i} is {} (not in [0, 1])",
                pixels[i]
            )));
        }
        Ok(Self {
            width,
            height,
            pixels,
        })
    }

    /// Decode a PNG (any colour type and bit depth; colour is reduced to Rec. 709 luminance).
    pub fn decode_png(bytes: &[u8]) -> Result<Self, ToolError> {
        let mut decoder = png::Decoder::new(bytes);
        decoder.set_transformations(png::Transformations::EXPAND);
        let mut reader = decoder
            .read_info()
            .map_err(|e| ToolError::Image(e.to_string()))?;
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader
            .next_frame(&mut buf)
            .map_err(|e| ToolError::Image(e.to_string()))?;
        let (w, h) = (info.width as usize, info.height as usize);
        let channels = info.color_type.samples();
        let wide = info.bit_depth == png::BitDepth::Sixteen;
        let max = if wide { 65535.0 } else { 255.0 };
        let sample = |k: usize| -> f64 {
            if wide {
                u16::from_be_bytes([buf[2 * k], buf[2 * k + 1]]) as f64 / max
            } else {
                buf[k] as f64 / max
            }
        };
        let pixels = (0..w * h)
            .map(|i| {
                let base = i * channels;
                match channels {
                    1 | 2 => sample(base),
                    _ => {
                        0.2126 * sample(base)
                            + 0.7152 * sample(base + 1)
                            + 0.0722 * sample(base + 2)
                    }
                }
                .clamp(0.0, 1.0)
            })
            .collect();
        Self::new(w, h, pixels)
    }

    /// Width and height in pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Bilinear intensity at `(u, v) ∈ [0, 1]²` (pixel centres at `(i + ½)/width`), clamped.
    pub fn sample(&self, u: f64, v: f64) -> f64 {
        let axis = |t: f64, n: usize| -> (usize, usize, f64) {
            let x = (t.clamp(0.0, 1.0) * n as f64 - 0.5).clamp(0.0, (n - 1) as f64);
            let i = (x.floor() as usize).min(n - 1);
            let j = (i + 1).min(n - 1);
            (i, j, x - i as f64)
        };
        let (x0, x1, fx) = axis(u, self.width);
        let (y0, y1, fy) = axis(v, self.height);
        let at = |x: usize, y: usize| self.pixels[y * self.width + x];
        let top = at(x0, y0) * (1.0 - fx) + at(x1, y0) * fx;
        let bottom = at(x0, y1) * (1.0 - fx) + at(x1, y1) * fx;
        top * (1.0 - fy) + bottom * fy
    }
}

/// How image coordinates are laid onto the surface.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Mapping {
    /// `u = (x−o)·a/‖a‖²`, `v = (x−o)·b/‖b‖²`: the image spans the parallelogram `o + [0,1]a +
    /// [0,1]b` and is projected along `a × b`.
    Planar {
        /// Corner where `(u, v) = (0, 0)`.
        origin: DVec3,
        /// Image width direction and extent (m).
        u_axis: DVec3,
        /// Image height direction and extent (m).
        v_axis: DVec3,
    },
    /// `u` = angle around `axis` from `reference` / 2π, `v = (x−o)·axis/‖axis‖²`.
    Cylindrical {
        /// A point on the axis where `v = 0`.
        origin: DVec3,
        /// Axis direction and height extent (m).
        axis: DVec3,
        /// Direction of angle 0 (any vector not along the axis).
        reference: DVec3,
    },
    /// `u` = longitude from `reference` / 2π, `v` = colatitude from `pole` / π.
    Spherical {
        /// Centre.
        center: DVec3,
        /// Direction of `v = 0`.
        pole: DVec3,
        /// Direction of longitude 0.
        reference: DVec3,
    },
}

impl Mapping {
    /// `Ok` when every point is finite and every direction finite and non-zero.
    pub fn validate(&self) -> Result<(), ToolError> {
        let (point, dirs) = match *self {
            Self::Planar {
                origin,
                u_axis,
                v_axis,
            } => (origin, [u_axis, v_axis]),
            Self::Cylindrical {
                origin,
                axis,
                reference,
            } => (origin, [axis, reference]),
            Self::Spherical {
                center,
                pole,
                reference,
            } => (center, [pole, reference]),
        };
        if point.is_finite() && dirs.iter().all(|d| d.try_normalize().is_some()) {
            Ok(())
        } else {
            Err(ToolError::Param {
                name: "mapping",
                reason: "points must be finite, directions finite and non-zero",
            })
        }
    }

    /// Image coordinates of `x`, `None` outside the image.
    pub fn uv(&self, x: DVec3) -> Option<(f64, f64)> {
        let angle = |d: DVec3, axis: DVec3, reference: DVec3| -> Option<f64> {
            let a = axis.try_normalize()?;
            let r = (reference - a * reference.dot(a)).try_normalize()?;
            let s = a.cross(r);
            let a = d.dot(s).atan2(d.dot(r));
            Some(a.rem_euclid(std::f64::consts::TAU) / std::f64::consts::TAU)
        };
        let (u, v) = match *self {
            Self::Planar {
                origin,
                u_axis,
                v_axis,
            } => {
                let d = x - origin;
                (
                    d.dot(u_axis) / u_axis.length_squared(),
                    d.dot(v_axis) / v_axis.length_squared(),
                )
            }
            Self::Cylindrical {
                origin,
                axis,
                reference,
            } => {
                let d = x - origin;
                (
                    angle(d, axis, reference)?,
                    d.dot(axis) / axis.length_squared(),
                )
            }
            Self::Spherical {
                center,
                pole,
                reference,
            } => {
                let d = (x - center).try_normalize()?;
                let p = pole.try_normalize()?;
                (
                    angle(d, p, reference)?,
                    d.dot(p).clamp(-1.0, 1.0).acos() / std::f64::consts::PI,
                )
            }
        };
        ((0.0..=1.0).contains(&u) && (0.0..=1.0).contains(&v)).then_some((u, v))
    }
}

/// An emboss (depth > 0) or engrave (depth < 0) operation.
#[derive(Debug, Clone, PartialEq)]
pub struct Emboss {
    /// The height map.
    pub image: GreyImage,
    /// How it is laid on the surface.
    pub mapping: Mapping,
    /// Displacement at intensity 1 (m); negative engraves.
    pub depth: f64,
}

impl Emboss {
    /// Displacement at `x` (0 outside the image).
    pub fn displacement(&self, x: DVec3) -> f64 {
        self.mapping
            .uv(x)
            .map_or(0.0, |(u, v)| self.depth * self.image.sample(u, v))
    }
}

/// Move the points (all, or those listed in `only`) onto the displaced iso-surface and tilt
/// their normals; returns how many moved.
pub fn emboss(
    op: &Emboss,
    positions: &mut [DVec3],
    normals: &mut [DVec3],
    field: &GlobalField,
    only: Option<&[u32]>,
) -> Result<usize, ToolError> {
    finite("depth", op.depth)?;
    op.mapping.validate()?;
    let n_all = positions.len();
    let eps = 0.25 * field.scale();
    let mut moved = 0;
    let mut visit = |i: usize| {
        let (p, n) = (positions[i], normals[i]);
        if op.mapping.uv(p).is_none() {
            return;
        }
        let delta = op.displacement(p);
        let mut x = p + n * delta;
        for _ in 0..2 {
            let (f, g) = field.value_and_gradient(x);
            let g2 = g.length_squared();
            let r = f - op.displacement(x);
            if g2 > 1e-24 && r.is_finite() {
                let step = g * (r / g2);
                x -= if step.length() > eps {
                    step * (eps / step.length())
                } else {
                    step
                };
            }
        }
        let (t1, t2) = tangent_frame(n);
        let slope =
            |t: DVec3| (op.displacement(p + t * eps) - op.displacement(p - t * eps)) / (2.0 * eps);
        let tilted = (n - t1 * slope(t1) - t2 * slope(t2))
            .try_normalize()
            .unwrap_or(n);
        if x.is_finite() {
            positions[i] = x;
            normals[i] = tilted;
            moved += 1;
        }
    };
    match only {
        Some(list) => list
            .iter()
            .map(|&i| i as usize)
            .filter(|&i| i < n_all)
            .for_each(&mut visit),
        None => (0..n_all).for_each(&mut visit),
    }
    Ok(moved)
}

/// Levels of [`detail_insertions`]: the spacing near the image's edges halves per level.
pub const DETAIL_LEVELS: u32 = 3;
/// Passes per level (each inserts at most one point per point near an edge).
pub const DETAIL_PASSES: u32 = 3;

/// Points to insert before embossing so the image's edges are resolved (module doc): around the
/// points (of `positions`, unit `normals`, all on `field`'s zero set) where the displacement
/// changes by more than `|depth|/4` within the local spacing `s`, the largest empty tangent
/// circle wider than `s/2` gets a point, projected onto the zero set; `s` halves per level from
/// `spacing` (the object's median nearest-neighbour distance) down to `spacing / 4`. The
/// insertions are returned in order (their `parent` indexes `positions` or an earlier
/// insertion, counting on from `positions.len()`), not applied.
pub fn detail_insertions(
    op: &Emboss,
    positions: &[DVec3],
    normals: &[DVec3],
    field: &GlobalField,
    spacing: f64,
) -> Result<Vec<crate::resample::Insertion>, ToolError> {
    finite("depth", op.depth)?;
    op.mapping.validate()?;
    let mut out: Vec<crate::resample::Insertion> = Vec::new();
    if !(spacing.is_finite() && spacing > 0.0) || op.depth == 0.0 {
        return Ok(out);
    }
    let mut pos = positions.to_vec();
    let mut nrm = normals.to_vec();
    let step = 0.25 * op.depth.abs();
    for level in 0..DETAIL_LEVELS {
        let s = spacing * 0.5f64.powi(level as i32);
        for _ in 0..DETAIL_PASSES {
            // Points where the displacement changes by more than `step` within `s`.
            let edges: Vec<usize> = (0..pos.len())
                .filter(|&i| {
                    let (p, n) = (pos[i], nrm[i]);
                    if op.mapping.uv(p).is_none() {
                        return false;
                    }
                    let (t1, t2) = tangent_frame(n);
                    let d0 = op.displacement(p);
                    [t1, -t1, t2, -t2]
                        .iter()
                        .any(|t| (op.displacement(p + *t * s) - d0).abs() > step)
                })
                .collect();
            let opts = crate::resample::UpsampleOptions {
                max_gap: 0.5 * s,
                k: 16,
            };
            let added = crate::resample::upsample_at(&pos, &nrm, field, &opts, &edges);
            if added.is_empty() {
                break;
            }
            for a in &added {
                pos.push(a.position);
                nrm.push(a.normal);
            }
            out.extend(added);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mappings_place_image_coordinates() {
        let planar = Mapping::Planar {
            origin: DVec3::ZERO,
            u_axis: DVec3::X * 2.0,
            v_axis: DVec3::Y * 4.0,
        };
        assert_eq!(planar.uv(DVec3::new(1.0, 1.0, 5.0)), Some((0.5, 0.25)));
        assert_eq!(planar.uv(DVec3::new(3.0, 1.0, 0.0)), None);
        let cyl = Mapping::Cylindrical {
            origin: DVec3::ZERO,
            axis: DVec3::Z * 2.0,
            reference: DVec3::X,
        };
        let (u, v) = cyl.uv(DVec3::new(0.0, 1.0, 1.0)).unwrap();
        assert!((u - 0.25).abs() < 1e-12 && (v - 0.5).abs() < 1e-12);
        assert_eq!(cyl.uv(DVec3::new(1.0, 0.0, -0.1)), None);
        let sph = Mapping::Spherical {
            center: DVec3::ZERO,
            pole: DVec3::Z,
            reference: DVec3::X,
        };
        let (u, v) = sph.uv(DVec3::new(0.0, -3.0, 0.0)).unwrap();
        assert!((u - 0.75).abs() < 1e-12 && (v - 0.5).abs() < 1e-12);
        assert_eq!(sph.uv(DVec3::ZERO), None);
    }

    #[test]
    fn bilinear_sampling_between_pixel_centres() {
        let img = GreyImage::new(2, 1, vec![0.0, 1.0]).unwrap();
        assert_eq!(img.sample(0.25, 0.5), 0.0);
        assert_eq!(img.sample(0.75, 0.5), 1.0);
        assert!((img.sample(0.5, 0.5) - 0.5).abs() < 1e-12);
        assert_eq!(img.sample(-3.0, 9.0), 0.0);
    }
}
