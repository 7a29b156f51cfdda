//! The software renderer's overlays: the same meshes and wide-line quads the GPU draws, clipped
//! at the near plane and rasterised at pixel centres with screen-linear depth and perspective-
//! correct normals, shaded as `shaders.wgsl` shades them.

use glam::{Mat3, Mat4, Vec2, Vec3, Vec4, Vec4Swizzles};

use crate::{
    ewa::FrameParams,
    geometry::{
        LineInstance, Mesh, MeshInstance, OverlayInstances, SLOT_ARROW_HEAD, SLOT_CONTACT,
        SLOT_CURSOR, SLOT_PROBE,
    },
    scene::Lighting,
};

/// How a triangle's pixels are coloured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Kind {
    /// Lit, opaque (cursor, contact, arrow head).
    Opaque,
    /// Flat colour (lines).
    Flat,
    /// Lit, alpha-blended with the rim term, no depth write (the probe).
    Translucent,
}

/// A vertex after projection: pixel position, NDC depth, 1/w, and world position and normal
/// divided by w (for perspective-correct interpolation).
#[derive(Clone, Copy, Debug, Default)]
struct ScreenVertex {
    pos: Vec2,
    z: f32,
    inv_w: f32,
    world_w: Vec3,
    normal_w: Vec3,
}

/// One triangle ready to rasterise.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Tri {
    v: [ScreenVertex; 3],
    /// 1 / (twice the signed area).
    inv_area: f32,
    bbox: Vec4,
    kind: Kind,
    color: Vec4,
}

/// A clip-space vertex with its attributes.
#[derive(Clone, Copy, Debug)]
struct ClipVertex {
    clip: Vec4,
    world: Vec3,
    normal: Vec3,
}

impl ClipVertex {
    fn lerp(self, o: Self, t: f32) -> Self {
        Self {
            clip: self.clip.lerp(o.clip, t),
            world: self.world.lerp(o.world, t),
            normal: self.normal.lerp(o.normal, t),
        }
    }
}

/// Builds the triangles of every overlay in the GPU's order (opaque meshes, lines, probe).
pub(crate) fn build(
    out: &mut Vec<Tri>,
    inst: &OverlayInstances,
    sphere: &Mesh,
    cone: &Mesh,
    f: &FrameParams,
) {
    out.clear();
    let mesh = |out: &mut Vec<Tri>, m: &Mesh, slot: u32, kind: Kind| {
        if !inst.used[slot as usize] {
            return;
        }
        let MeshInstance {
            model,
            normal,
            color,
        } = inst.meshes[slot as usize];
        let model = Mat4::from_cols_array_2d(&model);
        let nm = Mat3::from_cols(
            Vec4::from(normal[0]).xyz(),
            Vec4::from(normal[1]).xyz(),
            Vec4::from(normal[2]).xyz(),
        );
        for t in m.indices.chunks(3) {
            let v = [t[0], t[1], t[2]].map(|i| {
                let mv = &m.vertices[i as usize];
                let world = model.transform_point3(Vec3::from(mv.position));
                ClipVertex {
                    clip: f.view_proj * world.extend(1.0),
                    world,
                    normal: nm * Vec3::from(mv.normal),
                }
            });
            push_clipped(out, v, kind, Vec4::from(color), true, f);
        }
    };
    mesh(out, sphere, SLOT_CURSOR, Kind::Opaque);
    mesh(out, sphere, SLOT_CONTACT, Kind::Opaque);
    mesh(out, cone, SLOT_ARROW_HEAD, Kind::Opaque);
    for l in &inst.lines[..inst.line_count as usize] {
        line(out, l, f);
    }
    mesh(out, sphere, SLOT_PROBE, Kind::Translucent);
}

/// `vs_line`: the segment clipped to the near plane and widened in screen space.
fn line(out: &mut Vec<Tri>, l: &LineInstance, f: &FrameParams) {
    let mut ca = f.view_proj * Vec4::from(l.a).xyz().extend(1.0);
    let mut cb = f.view_proj * Vec4::from(l.b).xyz().extend(1.0);
    if ca.z < 0.0 && cb.z < 0.0 {
        return;
    }
    if ca.z < 0.0 {
        ca = ca.lerp(cb, ca.z / (ca.z - cb.z));
    } else if cb.z < 0.0 {
        cb = cb.lerp(ca, cb.z / (cb.z - ca.z));
    }
    let half_px = 0.5 * f.size;
    let sa = ca.xy() / ca.w * half_px;
    let sb = cb.xy() / cb.w * half_px;
    let d = sb - sa;
    let len = d.length();
    let dir = if len > 1e-6 { d / len } else { Vec2::X };
    let perp = Vec2::new(-dir.y, dir.x);
    let corner = |vi: u32| {
        let c = Vec2::new((vi & 1) as f32, (vi >> 1) as f32) * 2.0 - 1.0;
        let end = if c.x > 0.0 { cb } else { ca };
        let offset = 0.5 * l.a[3] * (perp * c.y + dir * c.x);
        ClipVertex {
            clip: end + (offset / half_px * end.w).extend(0.0).extend(0.0),
            world: Vec3::ZERO,
            normal: Vec3::ZERO,
        }
    };
    let q = [0, 1, 2, 3].map(corner);
    let color = Vec4::from(l.color);
    push_clipped(out, [q[0], q[1], q[2]], Kind::Flat, color, false, f);
    push_clipped(out, [q[2], q[1], q[3]], Kind::Flat, color, false, f);
}

/// Clips a triangle to `z ≥ 0` (a fan of at most two), culls back faces if asked, projects.
fn push_clipped(
    out: &mut Vec<Tri>,
    v: [ClipVertex; 3],
    kind: Kind,
    color: Vec4,
    cull_back: bool,
    f: &FrameParams,
) {
    let mut poly = [v[0]; 4];
    let mut n = 0;
    for i in 0..3 {
        let (a, b) = (v[i], v[(i + 1) % 3]);
        if a.clip.z >= 0.0 {
            poly[n] = a;
            n += 1;
        }
        if (a.clip.z >= 0.0) != (b.clip.z >= 0.0) {
            poly[n] = a.lerp(b, a.clip.z / (a.clip.z - b.clip.z));
            n += 1;
        }
    }
    let project = |c: &ClipVertex| {
        let inv_w = 1.0 / c.clip.w;
        let ndc = c.clip.xyz() * inv_w;
        ScreenVertex {
            pos: Vec2::new(
                (ndc.x + 1.0) * 0.5 * f.size.x,
                (1.0 - ndc.y) * 0.5 * f.size.y,
            ),
            z: ndc.z,
            inv_w,
            world_w: c.world * inv_w,
            normal_w: c.normal * inv_w,
        }
    };
    for k in 1..n.saturating_sub(1) {
        let sv = [project(&poly[0]), project(&poly[k]), project(&poly[k + 1])];
        let (a, b, c) = (sv[0].pos, sv[1].pos, sv[2].pos);
        // Twice the signed area in pixel space (y down): negative for counter-clockwise in NDC.
        let area = (b - a).perp_dot(c - a);
        if area == 0.0 || !area.is_finite() || (cull_back && area > 0.0) {
            continue;
        }
        let lo = a.min(b).min(c);
        let hi = a.max(b).max(c);
        out.push(Tri {
            v: sv,
            inv_area: 1.0 / area,
            bbox: Vec4::new(lo.x, lo.y, hi.x, hi.y),
            kind,
            color,
        });
    }
}

/// Rasterises `tris` into rows `y0..y0 + rows` of a `width`-wide band of linear RGBA `color`
/// and NDC `depth` (LessEqual test, as the GPU pipelines).
#[allow(clippy::too_many_arguments)] // the band (two buffers, its rows) and the frame
pub(crate) fn draw_band(
    tris: &[Tri],
    color: &mut [Vec4],
    depth: &mut [f32],
    width: u32,
    y0: u32,
    rows: u32,
    f: &FrameParams,
    light: &Lighting,
) {
    let w = width as i32;
    for t in tris {
        let ys = ((t.bbox.y - 0.5).ceil() as i32).max(y0 as i32);
        let ye = ((t.bbox.w - 0.5).ceil() as i32).min((y0 + rows) as i32);
        let xs = ((t.bbox.x - 0.5).ceil() as i32).max(0);
        let xe = ((t.bbox.z - 0.5).ceil() as i32).min(w);
        let [v0, v1, v2] = t.v;
        for y in ys..ye {
            for x in xs..xe {
                let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                // Barycentric weights from the edge functions (all of the area's sign inside).
                let b0 = (v2.pos - v1.pos).perp_dot(p - v1.pos) * t.inv_area;
                let b1 = (v0.pos - v2.pos).perp_dot(p - v2.pos) * t.inv_area;
                let b2 = 1.0 - b0 - b1;
                if b0 < 0.0 || b1 < 0.0 || b2 < 0.0 {
                    continue;
                }
                let z = b0 * v0.z + b1 * v1.z + b2 * v2.z;
                let i = ((y - y0 as i32) * w + x) as usize;
                if !(0.0..=1.0).contains(&z) || z > depth[i] {
                    continue;
                }
                if t.kind == Kind::Flat {
                    color[i] = t.color;
                    depth[i] = z;
                    continue;
                }
                let iw = b0 * v0.inv_w + b1 * v1.inv_w + b2 * v2.inv_w;
                let world = (b0 * v0.world_w + b1 * v1.world_w + b2 * v2.world_w) / iw;
                let n = ((b0 * v0.normal_w + b1 * v1.normal_w + b2 * v2.normal_w) / iw).normalize();
                let l = (f.eye - world).normalize();
                let d = n.dot(l).abs().min(1.0);
                let lit = Vec3::from(light.shade(t.color.xyz().to_array(), d));
                if t.kind == Kind::Opaque {
                    color[i] = lit.extend(1.0);
                    depth[i] = z;
                } else {
                    let rim = (1.0 - d).powi(3);
                    let a = t.color.w + (1.0 - t.color.w) * 0.6 * rim;
                    let dst = color[i];
                    color[i] = (lit * a + dst.xyz() * (1.0 - a)).extend(a + dst.w * (1.0 - a));
                }
            }
        }
    }
}
