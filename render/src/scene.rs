//! What the caller hands the renderer each frame (splats, overlays) and once (style).

use bytemuck::{Pod, Zeroable};

/// One surface splat: an ellipse centred at `position` in the plane whose unit normal is `normal`,
/// blended with its neighbours by a Gaussian of its elliptical distance (see the crate doc).
///
/// 64 bytes, `#[repr(C)]` and `Pod`: a slice of splats is uploaded to the GPU as it is. The
/// ellipse's major semi-axis is `radius` metres along `axis` (a tangent direction; it is made
/// orthogonal to the normal before use) and its minor semi-axis `minor_radius` along
/// `normal × axis`. A zero `axis` makes an isotropic disk of `radius` (`minor_radius` is then
/// ignored). Radii come from the local spacing, computed by the caller (see [`splat_shape`]);
/// a radius of 0 draws nothing. A normal of (near) zero length draws the splat facing the
/// camera. `color` is sRGB, alpha ignored (splats are opaque). `curvature` is the surface's
/// second fundamental form in the ellipse's frame (see the field), used only near silhouettes:
/// a flat splat seen at a grazing angle reaches past the curved surface it stands for (by up
/// to r²/2R), and the part beyond the surface's outline is cut off (zero: no cut).
///
/// [`splat_shape`]: crate::splat_shape
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Splat {
    /// Centre of the ellipse.
    pub position: [f32; 3],
    /// Unit normal of the ellipse's plane (normalised again before use).
    pub normal: [f32; 3],
    /// Major semi-axis in metres (≥ 0), along `axis`; the radius of a disk.
    pub radius: f32,
    /// sRGB colour; alpha is ignored.
    pub color: [u8; 4],
    /// Direction of the major axis in the tangent plane; zero for an isotropic disk.
    pub axis: [f32; 3],
    /// Minor semi-axis in metres (≥ 0), along `normal × axis`; ignored when `axis` is zero.
    pub minor_radius: f32,
    /// Normal curvatures `(k_aa, k_ab, k_bb)`, 1/m, in the frame `(axis, normal × axis)`:
    /// the surface at tangent offset `x·axis + y·(normal × axis)` lies
    /// `½(k_aa x² + 2 k_ab x y + k_bb y²)` below the splat's plane (positive: it bends away
    /// from the normal, as a convex surface with outward normals). Ignored when `axis` is zero.
    pub curvature: [f32; 3],
    /// Factor on both semi-axes where the splat faces the eye (1, or 0: none): enough to
    /// reach the corners of its point's Voronoi cell, so the gaps of a random sampling are
    /// covered ([`splat_shape`](crate::splat_shape)). Applied fully where the eye is within ~53° of the normal and
    /// not at all beyond ~73° (the `ewa` module): grown splats near an outline would reach
    /// further past it. Keeps the struct 64 bytes, four 16-byte rows for the GPU.
    pub cell_growth: f32,
}

impl Splat {
    /// An isotropic (circular) splat of `radius` metres.
    pub fn disk(position: [f32; 3], normal: [f32; 3], radius: f32, color: [u8; 4]) -> Self {
        Self {
            position,
            normal,
            radius,
            color,
            axis: [0.0; 3],
            minor_radius: radius,
            curvature: [0.0; 3],
            cell_growth: 1.0,
        }
    }

    /// An elliptical splat: semi-axes `radius` along the tangent `axis` and `minor_radius`
    /// across it (a zero `axis` gives a disk of `radius`).
    pub fn ellipse(
        position: [f32; 3],
        normal: [f32; 3],
        axis: [f32; 3],
        radius: f32,
        minor_radius: f32,
        color: [u8; 4],
    ) -> Self {
        Self {
            position,
            normal,
            radius,
            color,
            axis,
            minor_radius,
            curvature: [0.0; 3],
            cell_growth: 1.0,
        }
    }

    /// A splat of the `shape` [`splat_shape`](crate::splat_shape) computed for this point.
    pub fn with_shape(
        position: [f32; 3],
        normal: [f32; 3],
        shape: crate::SplatShape,
        color: [u8; 4],
    ) -> Self {
        Self {
            curvature: shape.curvature,
            cell_growth: shape.cell_growth,
            ..Self::ellipse(
                position,
                normal,
                shape.axis,
                shape.radius,
                shape.minor_radius,
                color,
            )
        }
    }

    /// Whether every field is finite and no radius is negative.
    pub fn is_valid(&self) -> bool {
        self.position
            .iter()
            .chain(&self.normal)
            .chain(&self.axis)
            .chain(&self.curvature)
            .all(|v| v.is_finite())
            && self.radius.is_finite()
            && self.radius >= 0.0
            && self.minor_radius.is_finite()
            && self.minor_radius >= 0.0
            && self.cell_growth.is_finite()
    }
}

/// An ellipsoid: a unit sphere scaled by `semi_axes`, rotated by `rotation`, moved to `center`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ellipsoid {
    /// Centre in metres.
    pub center: [f32; 3],
    /// Orientation as a unit quaternion `[x, y, z, w]` (normalised before use).
    pub rotation: [f32; 4],
    /// Semi-axes along the ellipsoid's local x, y, z, in metres.
    pub semi_axes: [f32; 3],
}

/// The non-point parts of the scene; every part is optional.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Overlay {
    /// The sculpting probe, drawn translucent in [`Style::probe_color`].
    pub probe: Option<Ellipsoid>,
    /// The haptic cursor's position: a sphere of [`Style::cursor_radius_px`] pixels.
    pub cursor: Option<[f32; 3]>,
    /// The sculpting region as an axis-aligned box `(min, max)`: 12 lines.
    pub region: Option<([f32; 3], [f32; 3])>,
    /// The contact point on the surface: a sphere of [`Style::contact_radius_px`] pixels.
    pub contact: Option<[f32; 3]>,
    /// The contact force as an arrow `(origin, vector)` in metres (the caller scales newtons to
    /// a length); a zero vector draws nothing.
    pub force: Option<([f32; 3], [f32; 3])>,
}

/// The headlight model: `albedo · (ambient + diffuse·|n·l|) + specular·|n·l|^shininess`, in linear
/// colour, with `l` the unit vector from the surface point to the eye.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lighting {
    /// Fraction of the albedo lit regardless of orientation.
    pub ambient: f32,
    /// Weight of the Lambert term.
    pub diffuse: f32,
    /// Weight of the white specular highlight.
    pub specular: f32,
    /// Exponent of the specular highlight.
    pub shininess: f32,
}

impl Default for Lighting {
    fn default() -> Self {
        Self {
            ambient: 0.22,
            diffuse: 0.78,
            specular: 0.12,
            shininess: 40.0,
        }
    }
}

impl Lighting {
    /// The shaded colour (linear RGB) of a surface of linear `albedo` at `n_dot_l = |n·l|`: what
    /// the shaders compute, for tests and for callers that want to predict a pixel.
    pub fn shade(&self, albedo: [f32; 3], n_dot_l: f32) -> [f32; 3] {
        let d = n_dot_l.abs().min(1.0);
        let s = self.specular * d.powf(self.shininess);
        albedo.map(|a| a * (self.ambient + self.diffuse * d) + s)
    }
}

/// How things look: colours (sRGB), sizes in pixels, lighting. Set once with
/// [`Renderer::set_style`](crate::Renderer::set_style).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Style {
    /// Background colour (sRGB; alpha is written as given).
    pub background: [u8; 4],
    /// Probe colour (sRGB) and opacity (alpha, at the probe's centre; more towards its rim).
    pub probe_color: [u8; 4],
    /// Cursor colour (sRGB).
    pub cursor_color: [u8; 3],
    /// Cursor radius in pixels (the sphere keeps its screen size at any distance).
    pub cursor_radius_px: f32,
    /// Contact point colour (sRGB).
    pub contact_color: [u8; 3],
    /// Contact point radius in pixels.
    pub contact_radius_px: f32,
    /// Region box colour (sRGB).
    pub region_color: [u8; 3],
    /// Region box line width in pixels.
    pub region_width_px: f32,
    /// Force arrow colour (sRGB).
    pub force_color: [u8; 3],
    /// Force arrow shaft width in pixels.
    pub force_width_px: f32,
    /// The headlight.
    pub lighting: Lighting,
    /// Skip splats whose normal faces away from the eye (`n·(eye − p) < 0`). Right for closed
    /// surfaces with consistently outward normals (DESIGN §2 orients them), where the far side
    /// is hidden anyway: about half the splats and fragments less. Off by default, so
    /// inconsistent normals or open sheets still draw both sides.
    pub cull_back_facing: bool,
}

impl Default for Style {
    fn default() -> Self {
        Self {
            background: [24, 26, 32, 255],
            probe_color: [120, 190, 255, 90],
            cursor_color: [255, 220, 40],
            cursor_radius_px: 6.0,
            contact_color: [40, 230, 120],
            contact_radius_px: 4.0,
            region_color: [200, 200, 210],
            region_width_px: 2.0,
            force_color: [255, 40, 200],
            force_width_px: 4.0,
            lighting: Lighting::default(),
            cull_back_facing: false,
        }
    }
}

/// sRGB-encoded byte to linear intensity (the exact piecewise curve).
pub fn srgb_to_linear(c: u8) -> f32 {
    let c = c as f32 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear intensity to an sRGB-encoded byte (what an sRGB render target stores).
pub fn linear_to_srgb(v: f32) -> u8 {
    let v = v.clamp(0.0, 1.0);
    let s = if v <= 0.003_130_8 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

/// Buckets of the [`SrgbEncoder`]'s first guess.
const SRGB_BUCKETS: usize = 4096;

/// [`linear_to_srgb`] by table, the same byte for every `f32` (tested), without its `powf`:
/// the smallest linear value of each byte (found by bisection on [`linear_to_srgb`] itself)
/// and, per 1/4096 of the range, the byte its start encodes to; a value steps up from there
/// past at most one or two thresholds. A quarter of a software frame was the `powf` and the
/// rounding of this encoding.
pub(crate) struct SrgbEncoder {
    /// `thresholds[k]`: the smallest `f32` that encodes to `k` or more (`k ≥ 1`).
    thresholds: [f32; 256],
    start: [u8; SRGB_BUCKETS + 1],
}

impl SrgbEncoder {
    fn new() -> Self {
        let mut thresholds = [0.0f32; 256];
        for (k, t) in thresholds.iter_mut().enumerate().skip(1) {
            // Bisection over the bit patterns of non-negative floats (ordered as integers).
            let (mut lo, mut hi) = (0u32, 1.0f32.to_bits());
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if linear_to_srgb(f32::from_bits(mid)) as usize >= k {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            *t = f32::from_bits(lo);
        }
        let mut start = [0u8; SRGB_BUCKETS + 1];
        for (b, s) in start.iter_mut().enumerate() {
            *s = linear_to_srgb(b as f32 / SRGB_BUCKETS as f32);
        }
        Self { thresholds, start }
    }

    /// The shared table.
    pub(crate) fn get() -> &'static Self {
        static TABLE: std::sync::OnceLock<SrgbEncoder> = std::sync::OnceLock::new();
        TABLE.get_or_init(Self::new)
    }

    /// `linear_to_srgb(v)`.
    #[inline]
    pub(crate) fn encode(&self, v: f32) -> u8 {
        let v = v.clamp(0.0, 1.0);
        let mut k = self.start[(v * SRGB_BUCKETS as f32) as usize];
        while k < 255 && v >= self.thresholds[k as usize + 1] {
            k += 1;
        }
        k
    }
}

/// sRGB bytes to linear RGBA (alpha is linear already).
pub(crate) fn color_linear(c: [u8; 3], alpha: f32) -> [f32; 4] {
    [
        srgb_to_linear(c[0]),
        srgb_to_linear(c[1]),
        srgb_to_linear(c[2]),
        alpha,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splat_is_64_bytes() {
        // Four 16-byte rows: `shaders.wgsl` reads `splats[4u * i + 0..3]`.
        assert_eq!(std::mem::size_of::<Splat>(), 64);
    }

    /// The table encodes every float in [0, 1] (and beyond, and NaN) as the formula does.
    #[test]
    fn the_srgb_table_encodes_every_float_as_the_formula() {
        let table = SrgbEncoder::get();
        let mut checked = 0u64;
        for bits in (0..=1.0f32.to_bits()).step_by(7) {
            let v = f32::from_bits(bits);
            assert_eq!(table.encode(v), linear_to_srgb(v), "{v:e}");
            checked += 1;
        }
        for &t in &table.thresholds[1..] {
            for v in [t, f32::from_bits(t.to_bits() - 1)] {
                assert_eq!(table.encode(v), linear_to_srgb(v), "{v:e}");
            }
        }
        for v in [-1.0, 2.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            assert_eq!(table.encode(v), linear_to_srgb(v), "{v}");
        }
        assert!(checked > 100_000_000);
    }

    #[test]
    fn srgb_round_trips_every_byte() {
        for c in 0..=255u8 {
            assert_eq!(linear_to_srgb(srgb_to_linear(c)), c);
        }
    }

    #[test]
    fn invalid_splats_are_caught() {
        let ok = Splat::disk([0.0; 3], [0.0, 0.0, 1.0], 1.0, [255; 4]);
        assert!(ok.is_valid());
        assert!(!Splat { radius: -1.0, ..ok }.is_valid());
        assert!(
            !Splat {
                position: [f32::NAN, 0.0, 0.0],
                ..ok
            }
            .is_valid()
        );
        assert!(
            !Splat {
                normal: [0.0, f32::INFINITY, 0.0],
                ..ok
            }
            .is_valid()
        );
        assert!(
            !Splat {
                minor_radius: -0.5,
                ..ok
            }
            .is_valid()
        );
        assert!(
            !Splat {
                axis: [f32::NAN, 0.0, 0.0],
                ..ok
            }
            .is_valid()
        );
    }

    #[test]
    fn lighting_head_on_is_albedo_plus_highlight() {
        let l = Lighting::default();
        let c = l.shade([0.5, 0.25, 0.0], 1.0);
        let k = l.ambient + l.diffuse;
        assert!((c[0] - (0.5 * k + l.specular)).abs() < 1e-6);
        assert!((c[2] - l.specular).abs() < 1e-6);
        assert!(l.shade([0.5; 3], 0.2)[0] < c[0]);
    }
}
