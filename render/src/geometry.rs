//! CPU-side geometry: the unit sphere and cone meshes, and the per-frame overlay instances.

use bytemuck::{Pod, Zeroable};
use glam::{Mat3, Mat4, Quat, Vec3};

use crate::{Camera, Ellipsoid, Overlay, RenderError, Style, scene::color_linear};

/// A mesh vertex: position and outward unit normal.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct MeshVertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
}

/// One instance of a mesh: model matrix, normal matrix (columns padded to vec4), linear RGBA.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub(crate) struct MeshInstance {
    pub model: [[f32; 4]; 4],
    pub normal: [[f32; 4]; 3],
    pub color: [f32; 4],
}

/// One line segment: ends `a`, `b` (w of `a` is the width in pixels), linear RGBA.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub(crate) struct LineInstance {
    pub a: [f32; 4],
    pub b: [f32; 4],
    pub color: [f32; 4],
}

/// An indexed triangle list, counter-clockwise seen from outside.
#[derive(Debug)]
pub(crate) struct Mesh {
    pub vertices: Vec<MeshVertex>,
    pub indices: Vec<u16>,
}

/// The unit sphere as `stacks × slices` quads of latitude and longitude.
pub(crate) fn unit_sphere(stacks: u16, slices: u16) -> Mesh {
    let mut vertices = Vec::new();
    for i in 0..=stacks {
        let theta = std::f32::consts::PI * i as f32 / stacks as f32;
        for j in 0..=slices {
            let phi = std::f32::consts::TAU * j as f32 / slices as f32;
            let p = [
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            ];
            vertices.push(MeshVertex {
                position: p,
                normal: p,
            });
        }
    }
    let row = slices + 1;
    let mut indices = Vec::new();
    for i in 0..stacks {
        for j in 0..slices {
            let (a, b) = (i * row + j, (i + 1) * row + j);
            let (c, d) = (b + 1, a + 1);
            // The first row's a and d are both the north pole, the last row's b and c the
            // south pole: skip the degenerate triangle there.
            if i + 1 != stacks {
                indices.extend([a, b, c]);
            }
            if i != 0 {
                indices.extend([a, c, d]);
            }
        }
    }
    Mesh { vertices, indices }
}

/// The unit cone: base disk of radius 1 at z = 0, apex at z = 1, with its base cap.
pub(crate) fn unit_cone(slices: u16) -> Mesh {
    let mut vertices = Vec::new();
    let mut indices = Vec::new();
    let ring = |j: u16| {
        let phi = std::f32::consts::TAU * j as f32 / slices as f32;
        (phi.cos(), phi.sin())
    };
    let side_normal = |(c, s): (f32, f32)| Vec3::new(c, s, 1.0).normalize().to_array();
    for j in 0..slices {
        let (p0, p1) = (ring(j), ring(j + 1));
        let mid = ring(j).0 + ring(j + 1).0;
        let mid = (mid, ring(j).1 + ring(j + 1).1);
        let base = vertices.len() as u16;
        vertices.push(MeshVertex {
            position: [p0.0, p0.1, 0.0],
            normal: side_normal(p0),
        });
        vertices.push(MeshVertex {
            position: [p1.0, p1.1, 0.0],
            normal: side_normal(p1),
        });
        vertices.push(MeshVertex {
            position: [0.0, 0.0, 1.0],
            normal: side_normal(mid),
        });
        indices.extend([base, base + 1, base + 2]);
    }
    let center = vertices.len() as u16;
    let down = [0.0, 0.0, -1.0];
    vertices.push(MeshVertex {
        position: [0.0; 3],
        normal: down,
    });
    for j in 0..=slices {
        let (c, s) = ring(j);
        vertices.push(MeshVertex {
            position: [c, s, 0.0],
            normal: down,
        });
    }
    for j in 0..slices {
        indices.extend([center, center + 2 + j, center + 1 + j]);
    }
    Mesh { vertices, indices }
}

/// Fixed slots of the overlay mesh instance buffer.
pub(crate) const SLOT_CURSOR: u32 = 0;
pub(crate) const SLOT_ARROW_HEAD: u32 = 1;
pub(crate) const SLOT_PROBE: u32 = 2;
pub(crate) const SLOT_CONTACT: u32 = 3;
pub(crate) const MESH_SLOTS: usize = 4;
/// Most line segments a frame draws: 12 box edges and the arrow's shaft.
pub(crate) const MAX_LINES: usize = 13;

/// The overlay as GPU instances: which mesh slots are in use, and the line segments.
#[derive(Debug, Default)]
pub(crate) struct OverlayInstances {
    pub meshes: [MeshInstance; MESH_SLOTS],
    pub used: [bool; MESH_SLOTS],
    pub lines: [LineInstance; MAX_LINES],
    pub line_count: u32,
}

fn finite(values: &[f32], what: &'static str) -> Result<(), RenderError> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(RenderError::NonFinite { what, index: 0 })
    }
}

fn instance(model: Mat4, color: [f32; 4]) -> MeshInstance {
    let n = Mat3::from_mat4(model).inverse().transpose();
    MeshInstance {
        model: model.to_cols_array_2d(),
        normal: [
            n.x_axis.extend(0.0),
            n.y_axis.extend(0.0),
            n.z_axis.extend(0.0),
        ]
        .map(|c| c.to_array()),
        color,
    }
}

impl OverlayInstances {
    /// Builds the instances of `overlay` seen by `camera` in an image `height` pixels tall.
    /// Checks every value first; on error `self` is left unchanged.
    pub fn build(
        &mut self,
        overlay: &Overlay,
        camera: &Camera,
        height: u32,
        style: &Style,
    ) -> Result<(), RenderError> {
        if let Some(p) = &overlay.probe {
            let Ellipsoid {
                center,
                rotation,
                semi_axes,
            } = p;
            finite(&[center.as_slice(), rotation, semi_axes].concat(), "probe")?;
        }
        if let Some(c) = &overlay.cursor {
            finite(c, "cursor")?;
        }
        if let Some(c) = &overlay.contact {
            finite(c, "contact")?;
        }
        if let Some((a, b)) = &overlay.region {
            finite(&[*a, *b].concat(), "region")?;
        }
        if let Some((a, b)) = &overlay.force {
            finite(&[*a, *b].concat(), "force")?;
        }

        self.used = [false; MESH_SLOTS];
        self.line_count = 0;
        let eye = Vec3::from(camera.eye);
        let forward = (Vec3::from(camera.target) - eye).normalize();
        let px_per_unit_depth = height as f32 / (2.0 * (0.5 * camera.fov_y_deg.to_radians()).tan());

        // Spheres of a constant screen size: the cursor and the contact point.
        let marker = |c: [f32; 3], px: f32, color: [u8; 3]| {
            let c = Vec3::from(c);
            let depth = (c - eye).dot(forward).max(camera.near);
            let r = px * depth / px_per_unit_depth;
            let model = Mat4::from_translation(c) * Mat4::from_scale(Vec3::splat(r));
            instance(model, color_linear(color, 1.0))
        };
        if let Some(c) = overlay.cursor {
            self.set(
                SLOT_CURSOR,
                marker(c, style.cursor_radius_px, style.cursor_color),
            );
        }
        if let Some(c) = overlay.contact {
            self.set(
                SLOT_CONTACT,
                marker(c, style.contact_radius_px, style.contact_color),
            );
        }
        if let Some(p) = overlay.probe {
            let q = Quat::from_array(p.rotation);
            let q = if q.length_squared() > 1e-12 {
                q.normalize()
            } else {
                Quat::IDENTITY
            };
            let scale = Vec3::from(p.semi_axes).abs().max(Vec3::splat(1e-9));
            let model = Mat4::from_scale_rotation_translation(scale, q, p.center.into());
            let [r, g, b, a] = style.probe_color;
            self.set(
                SLOT_PROBE,
                instance(model, color_linear([r, g, b], a as f32 / 255.0)),
            );
        }
        if let Some((min, max)) = overlay.region {
            let (min, max) = (Vec3::from(min), Vec3::from(max));
            let corner = |i: usize| {
                Vec3::select(
                    glam::BVec3::new(i & 1 != 0, i & 2 != 0, i & 4 != 0),
                    max,
                    min,
                )
            };
            let color = color_linear(style.region_color, 1.0);
            for i in 0..8 {
                for bit in [1, 2, 4] {
                    if i & bit == 0 {
                        self.push_line(corner(i), corner(i | bit), style.region_width_px, color);
                    }
                }
            }
        }
        if let Some((origin, vector)) = overlay.force {
            let (o, v) = (Vec3::from(origin), Vec3::from(vector));
            let len = v.length();
            if len > 0.0 {
                let dir = v / len;
                let head = 0.22 * len;
                let color = color_linear(style.force_color, 1.0);
                self.push_line(o, o + dir * (len - 0.5 * head), style.force_width_px, color);
                let model = Mat4::from_translation(o + dir * (len - head))
                    * Mat4::from_quat(Quat::from_rotation_arc(Vec3::Z, dir))
                    * Mat4::from_scale(Vec3::new(0.35 * head, 0.35 * head, head));
                self.set(SLOT_ARROW_HEAD, instance(model, color));
            }
        }
        Ok(())
    }

    fn set(&mut self, slot: u32, inst: MeshInstance) {
        self.meshes[slot as usize] = inst;
        self.used[slot as usize] = true;
    }

    fn push_line(&mut self, a: Vec3, b: Vec3, width_px: f32, color: [f32; 4]) {
        self.lines[self.line_count as usize] = LineInstance {
            a: a.extend(width_px).into(),
            b: b.extend(0.0).into(),
            color,
        };
        self.line_count += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn assert_outward_ccw(mesh: &Mesh, center: Vec3) {
        for t in mesh.indices.chunks(3) {
            let [a, b, c] =
                [t[0], t[1], t[2]].map(|i| Vec3::from(mesh.vertices[i as usize].position));
            let n = (b - a).cross(c - a);
            assert!(n.length() > 1e-6, "degenerate triangle {t:?}");
            assert!(
                n.dot((a + b + c) / 3.0 - center) > 0.0,
                "triangle {t:?} faces inward"
            );
        }
    }

    /// Every directed edge (by position: seams duplicate vertices) has exactly one opposite.
    fn assert_closed(mesh: &Mesh) {
        let key = |i: u16| {
            Vec3::from(mesh.vertices[i as usize].position)
                .map(|c| (c * 1e4).round())
                .as_ivec3()
                .to_array()
        };
        let mut edges = std::collections::HashMap::new();
        for t in mesh.indices.chunks(3) {
            for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                *edges.entry((key(a), key(b))).or_insert(0) += 1;
            }
        }
        for (&(a, b), &n) in &edges {
            assert_eq!(n, 1, "edge {a:?}->{b:?} used {n} times");
            assert_eq!(
                edges.get(&(b, a)),
                Some(&1),
                "edge {a:?}->{b:?} has no opposite: a hole"
            );
        }
    }

    #[test]
    fn sphere_is_closed_unit_and_counter_clockwise() {
        let s = unit_sphere(8, 12);
        for v in &s.vertices {
            assert!((Vec3::from(v.position).length() - 1.0).abs() < 1e-6);
        }
        assert_eq!(s.indices.len(), 3 * 2 * 12 * (8 - 1));
        assert_outward_ccw(&s, Vec3::ZERO);
        assert_closed(&s);
    }

    #[test]
    fn cone_is_counter_clockwise() {
        let cone = unit_cone(16);
        assert_outward_ccw(&cone, Vec3::new(0.0, 0.0, 0.25));
        assert_closed(&cone);
    }

    #[test]
    fn overlay_makes_12_box_edges_and_an_arrow() {
        let cam = Camera::framing([-1.0; 3], [1.0; 3], [0.0, 0.0, -1.0]);
        let overlay = Overlay {
            region: Some(([-1.0; 3], [1.0; 3])),
            force: Some(([0.0; 3], [0.0, 0.5, 0.0])),
            cursor: Some([0.2, 0.0, 0.0]),
            contact: Some([0.1, 0.0, 0.0]),
            ..Default::default()
        };
        let mut inst = OverlayInstances::default();
        inst.build(&overlay, &cam, 100, &Style::default()).unwrap();
        assert_eq!(inst.line_count, 13);
        for l in &inst.lines[..12] {
            let d = Vec3::from_slice(&l.b[..3]) - Vec3::from_slice(&l.a[..3]);
            assert_eq!(
                d.length(),
                2.0,
                "box edges are axis-aligned, length 2: {l:?}"
            );
        }
        // Cursor, arrow head and contact point; no probe.
        assert_eq!(inst.used, [true, true, false, true]);
        let contact = Mat4::from_cols_array_2d(&inst.meshes[SLOT_CONTACT as usize].model)
            .transform_point3(Vec3::ZERO);
        assert!((contact - Vec3::new(0.1, 0.0, 0.0)).length() < 1e-6);
        let tip = Mat4::from_cols_array_2d(&inst.meshes[SLOT_ARROW_HEAD as usize].model)
            .transform_point3(Vec3::Z);
        assert!(
            (tip - Vec3::new(0.0, 0.5, 0.0)).length() < 1e-6,
            "arrow tip at origin + vector"
        );
    }

    #[test]
    fn non_finite_overlay_is_named() {
        let cam = Camera::framing([-1.0; 3], [1.0; 3], [0.0, 0.0, -1.0]);
        let overlay = Overlay {
            force: Some(([0.0; 3], [f32::NAN, 0.0, 0.0])),
            ..Default::default()
        };
        let err = OverlayInstances::default().build(&overlay, &cam, 100, &Style::default());
        assert!(matches!(
            err,
            Err(RenderError::NonFinite { what: "force", .. })
        ));
    }
}
