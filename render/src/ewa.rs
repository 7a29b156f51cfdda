//! The surface-splatting math both backends share: per-frame parameters, per-splat setup (its
//! projected ellipse as a homography, its screen bounding box) and the per-pixel weight and
//! depths. `shaders.wgsl` (`ewa_setup`, `ewa_eval`) is a line-by-line copy of this file in
//! WGSL: change one, change the other.
//!
//! Pixel space: x right, y down, pixel `(i, j)` covers `[i, i+1) × [j, j+1)` and is sampled at
//! its centre. A splat is the ellipse `c + û·U + v̂·V`, `û² + v̂² ≤ 1`, with `U`, `V` its semi-axis
//! vectors. The map from `(û, v̂, 1)` to homogeneous pixel coordinates is a 3×3 homography `H`;
//! taken relative to the projected centre `(cx, cy)` it is `[[ux, vx, 0], [uy, vy, 0],
//! [uz, vz, wc]]` (`wc` the centre's view depth), whose inverse is closed-form: for a pixel at
//! `(dx, dy)` from the centre, `g = A⁻¹·(dx, dy)` with `A = [[ux, vx], [uy, vy]]`, the ray meets
//! the splat's plane at `(û, v̂) = w·g` and view depth `w = wc / (1 − (uz, vz)·g)`: exact
//! per-pixel ray casting, with no large coordinates cancelling.

use glam::{Mat4, Vec2, Vec3, Vec4, Vec4Swizzles};

use crate::{Camera, Splat, Style, scene::srgb_to_linear};

/// The weight of a splat at elliptical distance `d` (1 at the edge) is the Gaussian
/// `exp(-GAUSS_K · d²)` (σ = radius/2) truncated at the edge and lowered by its value there,
/// e^-2 ≈ 0.135, then scaled back to 1 at the centre: `(exp(-K d²) − e^-K) / (1 − e^-K)`.
/// Continuous at the edge, so a splat's outline leaves no step in the blend.
pub const GAUSS_K: f32 = 2.0;
/// `exp(-GAUSS_K)`: the Gaussian at the ellipse's edge, subtracted so weights fall to 0 there.
const EDGE_WEIGHT: f32 = 0.135_335_28;
/// The visibility pass pushes each splat's depth back by this fraction of its major radius
/// (in view depth, metres); fragments within that of the front blend.
pub const EPS_FRACTION: f32 = 1.0;
/// The push-back also adds this many pixel footprints (at the splat's depth): the pre-filter's
/// pixels take the centre's depth, off the surface by up to a pixel times the tilt's tangent.
pub const EPS_PX: f32 = 2.0;
/// Screen-space pre-filter radius in pixels: a pixel within this of a splat's projected centre
/// takes its screen distance when it is smaller than the object-space one, so every splat keeps
/// at least this footprint (never vanishes between pixel centres).
pub const PREFILTER_PX: f32 = 2.0;
/// The silhouette cut keeps distances this factor beyond the osculating paraboloid's outline
/// ([`silhouette`]): curvatures estimated from a few neighbours are noisy, and an
/// over-estimate would cut into the surface (a notch in its outline).
pub const CUT_SLACK: f32 = 1.0;
/// A splat seen from its back turns its normal towards the eye (so scans with unoriented
/// normals blend consistently) only when the eye is more than this (cosine) behind its plane.
/// Near the outline it keeps its own: turned, a splat just behind the outline blends with the
/// front's splats into a normal facing the eye (the light flecks along outlines: sparse/dense
/// gradient energy over the torus's frame 1.47, against 1.26 when kept).
pub const TURN_BELOW: f32 = 0.3;
/// [`Splat::cell_growth`] applies in full where the cosine between the splat's normal and the
/// eye is at least `GROW_FULL`, not at all below `GROW_FROM`, smoothly between.
pub const GROW_FROM: f32 = 0.6;
/// See [`GROW_FROM`].
pub const GROW_FULL: f32 = 0.9;

/// The factor on `s`'s semi-axes seen at cosine `c` between its normal and the eye.
#[inline]
pub(crate) fn growth(cell_growth: f32, c: f32) -> f32 {
    let t = ((c - GROW_FROM) / (GROW_FULL - GROW_FROM)).clamp(0.0, 1.0);
    1.0 + (cell_growth.max(1.0) - 1.0) * t * t * (3.0 - 2.0 * t)
}

/// A pixel next to the background whose blended normal is within this (cosine) of grazing is
/// on an outline: it takes the grazing normal ([`graze_normal`]), as the surface's is there.
pub const CONTOUR_BELOW: f32 = 0.5;

/// Pixels whose summed weight is below this show the background (a covered pixel has ≥ e^-2).
pub const MIN_WEIGHT: f32 = 1e-5;

/// Per-frame constants: the camera as pixel-space rows, the ray basis, depth mapping, style.
#[derive(Clone, Copy, Debug)]
pub(crate) struct FrameParams {
    pub view_proj: Mat4,
    /// Rows giving homogeneous pixel coordinates `(x·w, y·w, w)` of a world point `(p, 1)`.
    pub row_x: Vec4,
    pub row_y: Vec4,
    pub row_w: Vec4,
    pub eye: Vec3,
    pub forward: Vec3,
    /// Camera right and up, scaled by the half-extents of the image plane at unit depth.
    pub right_t: Vec3,
    pub up_t: Vec3,
    pub right: Vec3,
    pub up: Vec3,
    pub size: Vec2,
    /// NDC depth of view depth `w` is `depth_a + depth_b / w`.
    pub depth_a: f32,
    pub depth_b: f32,
    pub near: f32,
    /// World size of a pixel at unit view depth.
    pub px_per_depth: f32,
    pub cull: bool,
}

impl FrameParams {
    /// The parameters of `camera` (validated by the caller) for a `width × height` target.
    pub fn new(camera: &Camera, (width, height): (u32, u32), style: &Style) -> Self {
        let (w, h) = (width as f32, height as f32);
        let aspect = w / h;
        let view_proj = camera.projection(aspect) * camera.view();
        let (r0, r1, r3) = (view_proj.row(0), view_proj.row(1), view_proj.row(3));
        let eye = Vec3::from(camera.eye);
        let forward = (Vec3::from(camera.target) - eye).normalize();
        let right = forward.cross(Vec3::from(camera.up)).normalize();
        let up = right.cross(forward);
        let tan = (0.5 * camera.fov_y_deg.to_radians()).tan();
        let (near, far) = (camera.near, camera.far);
        Self {
            view_proj,
            row_x: 0.5 * w * (r0 + r3),
            row_y: 0.5 * h * (r3 - r1),
            row_w: r3,
            eye,
            forward,
            right_t: right * (tan * aspect),
            up_t: up * tan,
            right,
            up,
            size: Vec2::new(w, h),
            depth_a: far / (far - near),
            depth_b: -far * near / (far - near),
            near,
            px_per_depth: 2.0 * tan / h,
            cull: style.cull_back_facing,
        }
    }

    /// Unit vector from the surface seen at pixel centre `(px, py)` towards the eye.
    pub fn eye_dir(&self, px: f32, py: f32) -> Vec3 {
        let nx = px / self.size.x * 2.0 - 1.0;
        let ny = 1.0 - py / self.size.y * 2.0;
        -(self.forward + nx * self.right_t + ny * self.up_t).normalize()
    }
}

/// One splat ready to rasterise.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct SplatSetup {
    /// Projected centre in pixels.
    pub center: Vec2,
    /// `A⁻¹`, row-major.
    pub ainv: Vec4,
    /// `(uz, vz)`.
    pub k: Vec2,
    /// The centre's view depth.
    pub wc: f32,
    /// Depth push-back of the visibility pass (view depth).
    pub eps: f32,
    /// Whether the object-space term exists (false when the splat is seen edge-on).
    pub obj: bool,
    /// Silhouette cut: the object-space hit `(û, v̂)` counts only where
    /// `1 + cut.xy·(û, v̂) − (cut.zw·(û, v̂))² ≥ 0` (zero: no cut; see [`silhouette`]).
    pub cut: Vec4,
    /// Pixel-space box `(x0, y0, x1, y1)` holding every pixel centre of positive weight.
    pub bbox: Vec4,
    /// Linear albedo.
    pub albedo: Vec3,
    /// Unit normal; turned towards the eye when seen from well behind ([`TURN_BELOW`]).
    pub normal: Vec3,
    /// How the surface normal changes per unit `û` and `v̂` across the splat (`K·u`, `K·v`,
    /// turned with `normal`): the attribute pass blends `normal + û·dn_u + v̂·dn_v`, the normal
    /// of the curved surface the splat stands for, not its plane's (Phong splatting).
    pub dn_u: Vec3,
    pub dn_v: Vec3,
    /// The hit on the curved surface ([`Silhouette`]): `bend` is `S·K·t / c`, `quad` the
    /// curvature's quadratic form in `(û, v̂)`; zeros where there is no cut.
    pub bend: Vec3,
    pub quad: Vec3,
}

/// Builds the setup of `s`, or `None` when it draws nothing (zero radius, culled, or reaching
/// behind half the near plane).
pub(crate) fn setup(s: &Splat, f: &FrameParams) -> Option<SplatSetup> {
    let p = Vec3::from(s.position);
    let raw_n = Vec3::from(s.normal);
    let to_eye = f.eye - p;
    let len2 = raw_n.dot(raw_n);
    let (n, t1, t2) = if len2 > 1e-12 {
        let n = raw_n / len2.sqrt();
        // Orthonormal tangent basis without branches on the axis (Duff et al. 2017).
        let sgn = if n.z >= 0.0 { 1.0 } else { -1.0 };
        let a = -1.0 / (sgn + n.z);
        let b = n.x * n.y * a;
        (
            n,
            Vec3::new(1.0 + sgn * n.x * n.x * a, sgn * b, -sgn * n.x),
            Vec3::new(b, sgn + n.y * n.y * a, -n.y),
        )
    } else {
        (to_eye.normalize(), f.right, f.up)
    };
    let facing = n.dot(to_eye);
    if f.cull && len2 > 1e-12 && facing < 0.0 {
        return None;
    }
    let turned = facing < -TURN_BELOW * to_eye.length();
    let grow = growth(s.cell_growth, facing.abs() / to_eye.length().max(1e-30));
    let a = s.radius * grow;
    let axis = Vec3::from(s.axis);
    let ax = axis - n * axis.dot(n);
    let ax2 = ax.dot(ax);
    let (du, dv, b) = if ax2 > 1e-12 {
        let t = ax / ax2.sqrt();
        (t, n.cross(t), s.minor_radius * grow)
    } else {
        (t1, t2, a)
    };
    if !(a > 0.0 && b > 0.0) {
        return None;
    }
    let (sil, dn_u, dn_v) = if ax2 > 1e-12 {
        let [kaa, kab, kbb] = s.curvature;
        let turn = if turned { -1.0 } else { 1.0 };
        (
            silhouette(s.curvature, n, du * a, dv * b, to_eye),
            turn * a * (kaa * du + kab * dv),
            turn * b * (kab * du + kbb * dv),
        )
    } else {
        (Silhouette::NONE, Vec3::ZERO, Vec3::ZERO)
    };
    let (u, v) = (du * a, dv * b);
    let pc = p.extend(1.0);
    let wc = f.row_w.dot(pc);
    let cx = f.row_x.dot(pc) / wc;
    let cy = f.row_y.dot(pc) / wc;
    let hu = Vec3::new(
        f.row_x.xyz().dot(u),
        f.row_y.xyz().dot(u),
        f.row_w.xyz().dot(u),
    );
    let hv = Vec3::new(
        f.row_x.xyz().dot(v),
        f.row_y.xyz().dot(v),
        f.row_w.xyz().dot(v),
    );
    let (ux, uy, uz) = (hu.x - cx * hu.z, hu.y - cy * hu.z, hu.z);
    let (vx, vy, vz) = (hv.x - cx * hv.z, hv.y - cy * hv.z, hv.z);
    // The nearest point of the ellipse must be in front of half the near plane.
    if wc - (uz * uz + vz * vz).sqrt() < 0.5 * f.near {
        return None;
    }
    // Tangents x = const to the projected ellipse: roots of a quadratic, relative to the centre.
    let qa = wc * wc - uz * uz - vz * vz;
    let extent = |pu: f32, pv: f32| {
        let qb = -(pu * uz + pv * vz);
        let qc = -(pu * pu + pv * pv);
        let r = (qb * qb - qa * qc).max(0.0).sqrt();
        ((qb - r) / qa, (qb + r) / qa)
    };
    let (xl, xh) = extent(ux, vx);
    let (yl, yh) = extent(uy, vy);
    let bbox = Vec4::new(
        cx + xl.min(-PREFILTER_PX),
        cy + yl.min(-PREFILTER_PX),
        cx + xh.max(PREFILTER_PX),
        cy + yh.max(PREFILTER_PX),
    );
    let det = ux * vy - vx * uy;
    let obj = det.abs() > 1e-4 * (ux * ux + uy * uy).sqrt() * (vx * vx + vy * vy).sqrt();
    let ainv = if obj {
        Vec4::new(vy, -vx, -uy, ux) / det
    } else {
        Vec4::ZERO
    };
    let albedo = Vec3::new(
        srgb_to_linear(s.color[0]),
        srgb_to_linear(s.color[1]),
        srgb_to_linear(s.color[2]),
    );
    Some(SplatSetup {
        center: Vec2::new(cx, cy),
        ainv,
        k: Vec2::new(uz, vz),
        wc,
        eps: EPS_FRACTION * a + EPS_PX * f.px_per_depth * wc,
        obj,
        cut: sil.cut,
        bbox,
        albedo,
        normal: if turned { -n } else { n },
        dn_u,
        dn_v,
        bend: sil.bend,
        quad: sil.quad,
    })
}

/// The cut of a splat with semi-axis vectors `u`, `v`, unit normal `n` and normal curvatures
/// `k` (in the frame of `u`, `v`; [`Splat::curvature`]) seen from `to_eye`: `(l, m)` such that
/// the plane point `û·u + v̂·v` is kept where `1 + l·(û, v̂) − (m·(û, v̂))² ≥ 0` (zeros: no cut).
///
/// A flat splat stands for a surface that bends away from its plane, and seen obliquely it
/// reaches past that surface's outline (by up to r²/2R). Take the eye direction
/// `e = c·n + S·t` (`t` the tangent direction towards the eye, `c = |n·e|`, `S = √(1 − c²)`)
/// and the surface as the osculating paraboloid `h = ½ xᵀKx` below the plane. The ray from the
/// eye through the plane point at `a` along `t` and `b` along `s = n × t` meets the
/// paraboloid iff its discriminant `D = c² + 2Sc(κ_t a + κ_ts b) + S²(κ_ts² − κ_t κ_s) b²` is
/// non-negative (exact for a paraboloid, to second order for the surface; `c = n·e` signed, so
/// a splat just behind the outline, seen from its back, is cut on its side towards the eye);
/// points with `D < 0` lie beyond the outline and are cut. Facing the eye (`S → 0`) nothing is
/// cut; where the surface is concave along `t` nothing either (concave parts have no outline
/// seen from outside, and there the paraboloid would wrap the eye); the quadratic term is
/// kept only where it cuts (convex both ways). Distances are stretched by [`CUT_SLACK`]
/// against noisy curvatures.
///
/// The same ray meets the paraboloid first at `s* = q(x) / (B + √D)` behind the plane point
/// (`B = c + S·(Kx)·t`, `q(x) = xᵀKx`, the stable root of `½S²κ_t s² − B s + ½q = 0`), at
/// `x − s*·S·t` along the surface, where the curved normal is `n + Kx − s*·S·K·t`: at the
/// outline (`D = 0`) it is exactly perpendicular to the eye, as the surface's normal there is.
/// [`hit_normal`] uses it (for splats facing the eye; zeros otherwise): outline pixels take
/// the dark grazing normal a dense sampling shows, not the lighter one of the plane point.
pub(crate) fn silhouette(k: [f32; 3], n: Vec3, u: Vec3, v: Vec3, to_eye: Vec3) -> Silhouette {
    let e = to_eye.normalize_or_zero();
    let ne = n.dot(e);
    let t = e - n * ne;
    let tl = t.length();
    let (ul, vl) = (u.length(), v.length());
    if !(tl > 1e-6 && ul > 0.0 && vl > 0.0) {
        return Silhouette::NONE;
    }
    let t = t / tl;
    let sd = n.cross(t);
    // The curvature in the (t, s) frame.
    let (du, dv) = (u / ul, v / vl);
    let form = |p: Vec3, q: Vec3| {
        let (px, py, qx, qy) = (p.dot(du), p.dot(dv), q.dot(du), q.dot(dv));
        k[0] * px * qx + k[1] * (px * qy + py * qx) + k[2] * py * qy
    };
    let (kt, kts, ks) = (form(t, t), form(t, sd), form(sd, sd));
    // Not convex along t, or not a number: no cut.
    if kt.is_nan() || kt <= 0.0 {
        return Silhouette::NONE;
    }
    // Signed: a splat just behind the outline (seen from its back) reaches past it too, on
    // the side towards the eye, which the sign of c turns the cut to.
    let c = if ne < 0.0 { -1.0 } else { 1.0 } * ne.abs().max(1e-4);
    let sn = (1.0 - c * c).max(0.0).sqrt();
    // a = (û, v̂)·(u·t, v·t), b = (û, v̂)·(u·s, v·s).
    let (at, bs) = (
        Vec2::new(u.dot(t), v.dot(t)),
        Vec2::new(u.dot(sd), v.dot(sd)),
    );
    let l = 2.0 * sn * (kt * at + kts * bs) / (c * CUT_SLACK);
    let q = sn * sn * (kts * kts - kt * ks) / (c * c);
    let m = if q < 0.0 {
        bs * ((-q).sqrt() / CUT_SLACK)
    } else {
        Vec2::ZERO
    };
    let cut = Vec4::new(l.x, l.y, m.x, m.y);
    if ne <= 0.0 {
        return Silhouette {
            cut,
            ..Silhouette::NONE
        };
    }
    // K·t in world space, and K's quadratic form in (û, v̂).
    let (tu, tv) = (t.dot(du), t.dot(dv));
    let kt_world = (k[0] * tu + k[1] * tv) * du + (k[1] * tu + k[2] * tv) * dv;
    Silhouette {
        cut,
        bend: kt_world * (sn / c),
        quad: Vec3::new(k[0] * ul * ul, k[1] * ul * vl, k[2] * vl * vl),
    }
}

/// What [`silhouette`] computes for a splat seen from one eye.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Silhouette {
    /// `(l, m)`: the plane point `g = (û, v̂)` is kept where `1 + l·g − (m·g)² ≥ 0`.
    pub cut: Vec4,
    /// `S·K·t / c`: the curved normal at the ray's hit is `n + Kx − σ(g)·bend`.
    pub bend: Vec3,
    /// `(Kuu, Kuv, Kvv)`: `q(x) = quad.x·û² + 2·quad.y·û·v̂ + quad.z·v̂²`.
    pub quad: Vec3,
}

impl Silhouette {
    /// No cut, no bend.
    pub const NONE: Self = Self {
        cut: Vec4::ZERO,
        bend: Vec3::ZERO,
        quad: Vec3::ZERO,
    };
}

/// The unnormalised normal the attribute pass blends for `s` at the plane point `uv` (zero
/// from the pre-filter): the curved surface's normal where the eye's ray meets it
/// ([`silhouette`]), `n + û·dn_u + v̂·dn_v − σ·bend` with
/// `σ = q(g) / (1 + ½L·g + √(1 + L·g − (M·g)²))` (`L`, `M` the cut without its slack), the
/// correction at most as long as the normal itself.
#[inline]
pub(crate) fn hit_normal(s: &SplatSetup, uv: Vec2) -> Vec3 {
    let plane = s.normal + uv.x * s.dn_u + uv.y * s.dn_v;
    let q = s.quad.x * uv.x * uv.x + 2.0 * s.quad.y * uv.x * uv.y + s.quad.z * uv.y * uv.y;
    if q == 0.0 {
        return plane;
    }
    let lg = CUT_SLACK * (s.cut.x * uv.x + s.cut.y * uv.y);
    let mg = CUT_SLACK * (s.cut.z * uv.x + s.cut.w * uv.y);
    let sigma = q / (1.0 + 0.5 * lg + (1.0 + lg - mg * mg).max(0.0).sqrt());
    let bend = sigma * s.bend;
    let len = bend.length();
    if !(len.is_finite() && sigma > 0.0) {
        return plane;
    }
    plane - if len > 1.0 { bend / len } else { bend }
}

/// A splat's contribution at a pixel centre: Gaussian weight, then NDC depth of the attribute
/// pass and of the visibility pass (pushed back by ε).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Sample {
    pub weight: f32,
    pub depth: f32,
    pub depth_pushed: f32,
    /// `(û, v̂)` of the ray's hit on the splat's plane; zero where the screen-space pre-filter
    /// gave the weight (there the splat's centre normal is blended: bringing the hit back onto
    /// the ellipse's edge instead darkened outlines, frame gradient energy 1.75 → 2.03 on the
    /// torus; cutting those pixels at silhouettes too left 50–70 holes).
    pub uv: Vec2,
    /// The pre-filter gave the weight at a point the silhouette cut removes: the pixel lies
    /// beyond the splat's outline, and blends the grazing normal there ([`graze_normal`]).
    pub graze: bool,
}

/// The normal a pixel beyond a splat's outline blends (its pre-filter covers it, its cut does
/// not): the splat's normal turned perpendicular to the eye `e` at that pixel, as the surface's
/// normal is at an outline. With the splat's centre normal instead, such pixels (the outermost
/// ring of every silhouette of a sparse sampling) were lighter than a dense sampling's
/// outline: sparse-vs-dense PSNR torus 40.5 → 41.5 dB, ellipsoids 40.2/40.9 → 41.5/42.0 dB,
/// the far torus at 160×90 28.3 → 30.8 dB.
#[inline]
pub(crate) fn graze_normal(n: Vec3, e: Vec3) -> Vec3 {
    (n - n.dot(e) * e).try_normalize().unwrap_or(n)
}

/// The sample of splat `s` at pixel centre `(px, py)`, or `None` outside its footprint or the
/// depth range.
#[inline]
pub(crate) fn eval(s: &SplatSetup, f: &FrameParams, px: f32, py: f32) -> Option<Sample> {
    let dx = px - s.center.x;
    let dy = py - s.center.y;
    let gx = s.ainv.x * dx + s.ainv.y * dy;
    let gy = s.ainv.z * dx + s.ainv.w * dy;
    let den = 1.0 - (s.k.x * gx + s.k.y * gy);
    let d2_scr = (dx * dx + dy * dy) * (1.0 / (PREFILTER_PX * PREFILTER_PX));
    let mut d2 = d2_scr;
    let mut w = s.wc;
    let mut uv = Vec2::ZERO;
    let mut graze = false;
    if s.obj && den > 1e-6 {
        let scale = s.wc / den;
        let d2_obj = (gx * gx + gy * gy) * (scale * scale);
        let (cu, cv) = (gx * scale, gy * scale);
        let across = s.cut.z * cu + s.cut.w * cv;
        let kept = 1.0 + s.cut.x * cu + s.cut.y * cv - across * across >= 0.0;
        if kept && d2_obj <= d2_scr {
            d2 = d2_obj;
            w = scale;
            uv = Vec2::new(cu, cv);
        } else if !kept {
            graze = true;
        }
    }
    if d2 > 1.0 {
        return None;
    }
    let depth = f.depth_a + f.depth_b / w;
    if !(0.0..=1.0).contains(&depth) {
        return None;
    }
    Some(Sample {
        weight: ((-GAUSS_K * d2).exp() - EDGE_WEIGHT) * (1.0 / (1.0 - EDGE_WEIGHT)),
        depth,
        depth_pushed: (f.depth_a + f.depth_b / (w + s.eps)).min(1.0),
        uv,
        graze,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame() -> (Camera, FrameParams) {
        let cam = Camera::framing([-1.0; 3], [1.0; 3], [0.0, 0.0, -1.0]);
        let f = FrameParams::new(&cam, (640, 480), &Style::default());
        (cam, f)
    }

    #[test]
    fn centre_projects_where_the_camera_says_and_weighs_one() {
        let (cam, f) = frame();
        let s = Splat::disk([0.3, -0.2, 0.1], [0.0, 0.0, 1.0], 0.05, [255; 4]);
        let st = setup(&s, &f).unwrap();
        let want = cam.project(s.position, 640, 480).unwrap();
        assert!((st.center - Vec2::from(want)).length() < 1e-3);
        let at = eval(&st, &f, st.center.x, st.center.y).unwrap();
        assert!((at.weight - 1.0).abs() < 1e-6);
        assert!(at.depth_pushed > at.depth);
    }

    #[test]
    fn weight_follows_the_ellipse_and_box_holds_it() {
        let (cam, f) = frame();
        // Major axis along x (0.2 m), minor along y (0.05 m), facing the camera.
        let s = Splat::ellipse(
            [0.0; 3],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 0.0],
            0.2,
            0.05,
            [255; 4],
        );
        let st = setup(&s, &f).unwrap();
        let c = Vec2::from(cam.project([0.0; 3], 640, 480).unwrap());
        let half = Vec2::from(cam.project([0.1, 0.0, 0.0], 640, 480).unwrap()) - c;
        let w = eval(&st, &f, c.x + half.x, c.y).unwrap().weight;
        let want = ((-GAUSS_K * 0.25).exp() - EDGE_WEIGHT) / (1.0 - EDGE_WEIGHT);
        assert!((w - want).abs() < 1e-3, "{w}");
        assert!((EDGE_WEIGHT - (-GAUSS_K).exp()).abs() < 1e-7);
        let side = Vec2::from(cam.project([0.0, 0.06, 0.0], 640, 480).unwrap());
        assert!(
            eval(&st, &f, side.x, side.y).is_none(),
            "beyond the minor axis"
        );
        let tip = Vec2::from(cam.project([0.199, 0.0, 0.0], 640, 480).unwrap());
        assert!(
            tip.x <= st.bbox.z && st.bbox.z < tip.x + 1.0,
            "{:?}",
            st.bbox
        );
    }

    #[test]
    fn the_shader_cuts_and_grows_with_the_same_constants() {
        let wgsl = include_str!("shaders.wgsl");
        for (name, value) in [
            ("GROW_FROM", GROW_FROM),
            ("GROW_FULL", GROW_FULL),
            ("CONTOUR_BELOW", CONTOUR_BELOW),
        ] {
            assert!(
                wgsl.contains(&format!("const {name}: f32 = {value:?};")),
                "shaders.wgsl's {name} differs from ewa::{name}"
            );
        }
        assert!(
            wgsl.contains(&format!("const CUT_SLACK: f32 = {CUT_SLACK:?};")),
            "shaders.wgsl's CUT_SLACK differs from ewa::CUT_SLACK"
        );
        assert!(
            wgsl.contains(&format!("const TURN_BELOW: f32 = {TURN_BELOW:?};")),
            "shaders.wgsl's TURN_BELOW differs from ewa::TURN_BELOW"
        );
    }

    /// The camera looks along −z from +z. A splat at the centre of the view standing for a
    /// sphere of radius 1 (curvature 1, radius 0.3, centre −n), its normal `n` tilted 80° from
    /// the eye: the splat, its setup, `n` and its semi-axis vectors `u`, `v`.
    fn near_the_outline(f: &FrameParams) -> (Splat, SplatSetup, Vec3, Vec3, Vec3) {
        let tilt = 80f32.to_radians();
        let n = Vec3::new(tilt.sin(), 0.0, tilt.cos());
        let mut s = Splat::ellipse([0.0; 3], n.to_array(), [0.0, 1.0, 0.0], 0.3, 0.3, [255; 4]);
        s.curvature = [1.0, 0.0, 1.0];
        let st = setup(&s, f).unwrap();
        (s, st, n, Vec3::Y * 0.3, n.cross(Vec3::Y) * 0.3)
    }

    #[test]
    fn a_curved_splat_is_cut_only_beyond_the_outline_near_a_silhouette() {
        let (_, f) = frame();
        let (s, st, n, u, v) = near_the_outline(&f);
        let cut = silhouette(s.curvature, n, u, v, f.eye).cut;
        assert!(
            (cut - st.cut).length() < 1e-5 * cut.length(),
            "{cut} vs {}",
            st.cut
        );
        // The tangent towards the eye, t, and the unit-ellipse coordinates of t·d.
        let e = f.eye.normalize();
        let t = (e - n * n.dot(e)).normalize();
        let at = |d: Vec3| Vec2::new(d.dot(u) / 0.09, d.dot(v) / 0.09);
        let kept =
            |g: Vec2| 1.0 + cut.x * g.x + cut.y * g.y - (cut.z * g.x + cut.w * g.y).powi(2) >= 0.0;
        // Along −t the sphere's outline is R·tan(φ/2) away, φ = 90° − 80° seen from the eye
        // (orthographic to within the eye's distance): kept just inside it, cut beyond.
        let c = n.dot(e);
        let limit = c / (1.0 + (1.0 - c * c).sqrt());
        assert!(
            kept(at(-t * 0.98 * limit)) && !kept(at(-t * 1.02 * limit)),
            "{limit}"
        );
        // Towards the eye nothing is cut; sideways the outline bends in: cut past c/√(1 − c²)·R.
        assert!(kept(at(t * 0.3)));
        let side = n.cross(t);
        assert!(kept(at(side * 0.9 * c)) && !kept(at(side * 0.3)));
        // Facing the eye, flat, or concave: no cut.
        let facing = silhouette([1.0, 0.0, 1.0], Vec3::Z, Vec3::X, Vec3::Y, Vec3::Z * 5.0);
        assert_eq!(facing, Silhouette::NONE);
        assert_eq!(silhouette([0.0; 3], n, u, v, f.eye), Silhouette::NONE);
        assert_eq!(
            silhouette([-1.0, 0.0, -1.0], n, u, v, f.eye),
            Silhouette::NONE
        );
    }

    #[test]
    fn at_the_outline_the_blended_normal_is_perpendicular_to_the_eye() {
        let (_, f) = frame();
        let (s, st, n, u, v) = near_the_outline(&f);
        let e = f.eye.normalize();
        let t = (e - n * n.dot(e)).normalize();
        let at = |d: Vec3| Vec2::new(d.dot(u) / 0.09, d.dot(v) / 0.09);
        let c = n.dot(e);
        let limit = c / (1.0 + (1.0 - c * c).sqrt());
        // On the outline (the cut's edge along −t) the plane's normal still faces the eye a
        // little (the lighter flecks); the hit's normal is grazing, as the sphere's is there.
        let edge = at(-t * 0.999 * limit);
        let plane = st.normal + edge.x * st.dn_u + edge.y * st.dn_v;
        let hit = hit_normal(&st, edge).normalize();
        assert!(
            plane.normalize().dot(e) > 0.05,
            "{}",
            plane.normalize().dot(e)
        );
        assert!(hit.dot(e).abs() < 0.02, "{}", hit.dot(e));
        // Half way to the outline: the sphere's normal where the eye's ray through the plane
        // point meets it (the camera is far: rays parallel to −e).
        for k in [0.3, 0.6] {
            let g = at(-t * k * limit);
            let x = g.x * u + g.y * v;
            let centre = -n;
            let (oc, b) = (x - centre, -e);
            let (pb, cc) = (oc.dot(b), oc.length_squared() - 1.0);
            let along = -pb - (pb * pb - cc).sqrt();
            let truth = (x + along * b - centre).normalize();
            let got = hit_normal(&st, g).normalize();
            let plane = (st.normal + g.x * st.dn_u + g.y * st.dn_v).normalize();
            assert!(
                got.angle_between(truth) < 0.5 * plane.angle_between(truth),
                "{k}: hit {:.3} rad off, plane {:.3} rad off",
                got.angle_between(truth),
                plane.angle_between(truth)
            );
        }
        // Facing the eye, the hit is the plane point: no bend.
        let mut flat = s;
        flat.normal = [0.0, 0.0, 1.0];
        let st = setup(&flat, &f).unwrap();
        assert_eq!(st.bend, Vec3::ZERO);
    }

    #[test]
    fn the_blended_normal_is_the_curved_surfaces() {
        // A splat facing the camera, standing for a sphere of radius 0.5 (curvature 2): half
        // way to its edge along its axis (x), the surface's normal leans out by r/R = 0.1.
        let (cam, f) = frame();
        let mut s = Splat::ellipse(
            [0.0; 3],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 0.0],
            0.1,
            0.1,
            [255; 4],
        );
        s.curvature = [2.0, 0.0, 2.0];
        let st = setup(&s, &f).unwrap();
        let p = Vec2::from(cam.project([0.05, 0.0, 0.0], 640, 480).unwrap());
        let sm = eval(&st, &f, p.x, p.y).unwrap();
        assert!((sm.uv - Vec2::new(0.5, 0.0)).length() < 0.02, "{:?}", sm.uv);
        let n = st.normal + sm.uv.x * st.dn_u + sm.uv.y * st.dn_v;
        assert!((n.x / n.z - 0.1).abs() < 0.003 && n.y.abs() < 1e-4, "{n}");
        // Flat: the plane's normal everywhere.
        s.curvature = [0.0; 3];
        let st = setup(&s, &f).unwrap();
        assert_eq!((st.dn_u, st.dn_v), (Vec3::ZERO, Vec3::ZERO));
    }

    #[test]
    fn edge_on_and_tiny_splats_keep_a_pixel() {
        let (_, f) = frame();
        for s in [
            Splat::disk([0.0; 3], [1.0, 0.0, 0.0], 0.1, [255; 4]),
            Splat::disk([0.0; 3], [0.0, 0.0, 1.0], 1e-6, [255; 4]),
        ] {
            let st = setup(&s, &f).unwrap();
            let hit = eval(&st, &f, st.center.x + 0.5, st.center.y + 0.5);
            assert!(hit.is_some_and(|h| h.weight > 0.3), "{s:?}");
        }
    }
}
