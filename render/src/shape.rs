//! The shape of a splat from its neighbours: a pure function the caller runs per point after its
//! own k-nearest-neighbour search (this crate does no neighbour search).

use glam::{DVec2, DVec3};

/// Most neighbours [`splat_shape`] reads; further ones are ignored.
pub const MAX_SHAPE_NEIGHBOURS: usize = 32;
/// Smallest minor/major ratio [`splat_shape`] returns (no needles from collinear neighbours).
pub const MIN_SPLAT_ASPECT: f32 = 0.6;
/// The ellipse also reaches this many nearest neighbours (see [`splat_shape`]).
pub const COVER_NEIGHBOURS: usize = 6;
/// Factor on the ellipse through the farthest ring neighbour (see [`splat_shape`]).
pub const SPLAT_OVERLAP: f32 = 1.0;

/// Major axis, semi-axes and curvature of one splat, as [`splat_shape`] computes them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SplatShape {
    /// Unit tangent of the major axis (any tangent when the neighbours are isotropic).
    pub axis: [f32; 3],
    /// Major semi-axis in metres.
    pub radius: f32,
    /// Minor semi-axis in metres (≤ `radius`).
    pub minor_radius: f32,
    /// The surface's normal curvatures in the frame `(axis, normal × axis)`, 1/m
    /// ([`Splat::curvature`](crate::Splat::curvature)).
    pub curvature: [f32; 3],
    /// Factor ≥ 1 on both semi-axes that reaches the corners of the point's Voronoi cell
    /// ([`Splat::cell_growth`](crate::Splat::cell_growth)).
    pub cell_growth: f32,
}

/// The elliptical splat of the point `position` with unit `normal`, from the positions of its
/// nearest neighbours (any order; the point itself, if among them, is skipped; pass 10–16:
/// anisotropic sampling needs the neighbours in the sparse direction to be among them; and
/// only those on the point's own side of a part thinner than their spacing: the far side's
/// heights would read as a curvature of one over the thickness).
///
/// The rule, in the tangent plane of `normal`:
/// 1. the **ring**: neighbours taken nearest first, each kept unless a kept one lies inside or on
///    the circle whose diameter joins it to the point (the Gabriel criterion): the
///    neighbours across each gap, not the second and third ones along a dense row;
/// 2. the **shape**: principal axes of the ring's offsets (their 2×2 second moment about the
///    point): the major axis along the larger spread, aspect `sqrt(λ₂/λ₁)` clamped to
///    [`MIN_SPLAT_ASPECT`]..1 (isotropic when exactly 1);
/// 3. the **size**: the smallest ellipse of that shape containing every ring neighbour, times
///    [`SPLAT_OVERLAP`]; and the factor ([`SplatShape::cell_growth`], at most
///    [`MAX_CELL_GROWTH`]) by which it must grow to reach the corners of the point's Voronoi
///    cell among all the neighbours with [`CORNER_MARGIN`], which the renderer applies where
///    the splat faces the eye. Every corner of a cell is a corner of its neighbours' cells
///    too, so the grown splats cover the gaps between random samples (a 6,000-point random
///    sphere showed the back of the object through a few of them). The midpoint to each ring
///    neighbour is at elliptical
///    distance ≈ 0.71 from both splats (weight ≈ 0.27 each, see [`GAUSS_K`](crate::GAUSS_K)),
///    so neighbouring splats overlap across every gap of the ring; larger factors cover more
///    but make the tangent ellipses protrude further past silhouettes (a bulge of r²/2R on a
///    surface of curvature radius R), which is what dominated the sparse-vs-dense error in
///    the measurements (docs/BENCHMARKS.md, "Headless renderer").
///
/// 4. the **curvature**: the least-squares quadric `h = −½(k_aa x² + 2k_ab xy + k_bb y²)` of
///    the neighbours' heights `h` above the tangent plane at their tangent offsets `(x, y)`
///    (positions only: the normals of scans are too noisy to differentiate); zero when the
///    neighbours do not determine it (fewer than three, or all on a line).
///
/// `None` when the normal is zero or not finite, or no neighbour is off the point in the
/// tangent plane.
pub fn splat_shape(
    position: [f32; 3],
    normal: [f32; 3],
    neighbours: &[[f32; 3]],
) -> Option<SplatShape> {
    let p = DVec3::from(position.map(f64::from));
    let n = DVec3::from(normal.map(f64::from)).try_normalize()?;
    let (t1, t2) = n.any_orthonormal_pair();
    let mut offsets = [DVec2::ZERO; MAX_SHAPE_NEIGHBOURS];
    let mut heights = [0.0; MAX_SHAPE_NEIGHBOURS];
    let mut count = 0;
    for q in neighbours.iter().take(MAX_SHAPE_NEIGHBOURS) {
        let d = DVec3::from(q.map(f64::from)) - p;
        let u = DVec2::new(d.dot(t1), d.dot(t2));
        if u.is_finite() && u.length_squared() > 0.0 && d.dot(n).is_finite() {
            offsets[count] = u;
            heights[count] = d.dot(n);
            count += 1;
        }
    }
    let curvature = fit_curvature(&offsets[..count], &heights[..count]);
    let all = offsets;
    let offsets_all = &all[..count];
    let offsets = &mut offsets[..count];
    offsets.sort_by(|a, b| a.length_squared().total_cmp(&b.length_squared()));
    let mut nearest = [DVec2::ZERO; COVER_NEIGHBOURS];
    let n_nearest = offsets.len().min(COVER_NEIGHBOURS);
    nearest[..n_nearest].copy_from_slice(&offsets[..n_nearest]);
    // 1. The Gabriel ring, compacted to the front of `offsets`.
    let mut ring = 0;
    for j in 0..offsets.len() {
        let q = offsets[j];
        let hidden = offsets[..ring].iter().any(|&k| k.dot(k - q) <= 0.0);
        if !hidden {
            offsets[ring] = q;
            ring += 1;
        }
    }
    let ring = &offsets[..ring];
    if ring.is_empty() {
        return None;
    }
    // 2. Principal axes of the second moment about the point.
    let (mut cxx, mut cxy, mut cyy) = (0.0, 0.0, 0.0);
    for u in ring {
        cxx += u.x * u.x;
        cxy += u.x * u.y;
        cyy += u.y * u.y;
    }
    let half_diff = 0.5 * (cxx - cyy);
    let root = half_diff.hypot(cxy);
    let mean = 0.5 * (cxx + cyy);
    let (l1, l2) = (mean + root, (mean - root).max(0.0));
    let isotropic = root <= 1e-12 * mean;
    let angle = 0.5 * cxy.atan2(half_diff);
    let e1 = DVec2::new(angle.cos(), angle.sin());
    let e2 = e1.perp();
    let aspect = if isotropic {
        1.0
    } else {
        (l2 / l1).sqrt().clamp(f64::from(MIN_SPLAT_ASPECT), 1.0)
    };
    // 3. The smallest ellipse of that shape holding the ring, grown to the point's Voronoi
    // cell's corners.
    let elliptic = |u: DVec2| u.dot(e1).hypot(u.dot(e2) / aspect);
    let reach = ring
        .iter()
        .chain(&nearest[..n_nearest])
        .map(|&u| elliptic(u))
        .fold(0.0, f64::max);
    let corners = voronoi_corners(offsets_all)
        .map(elliptic)
        .fold(0.0, f64::max);
    let cell_growth = if reach > 0.0 {
        (CORNER_MARGIN * corners / reach).clamp(1.0, MAX_CELL_GROWTH)
    } else {
        1.0
    };
    let radius = f64::from(SPLAT_OVERLAP) * reach;
    // The curvature is expressed in the ellipse's frame, so the axis is kept even when the
    // ellipse is round (then `e1` is `t1`).
    let axis = e1.x * t1 + e1.y * t2;
    // In the renderer's frame (axis, normal × axis), whatever the handedness of (t1, t2).
    let across = n.cross(axis);
    let b = DVec2::new(across.dot(t1), across.dot(t2));
    let [kxx, kxy, kyy] = curvature;
    let form =
        |p: DVec2, q: DVec2| kxx * p.x * q.x + kxy * (p.x * q.y + p.y * q.x) + kyy * p.y * q.y;
    let (k_aa, k_ab, k_bb) = (form(e1, e1), form(e1, b), form(b, b));
    Some(SplatShape {
        axis: axis.as_vec3().to_array(),
        radius: radius as f32,
        minor_radius: (radius * aspect) as f32,
        curvature: [k_aa as f32, k_ab as f32, k_bb as f32],
        cell_growth: cell_growth as f32,
    })
}

/// At most this factor on the ring's ellipse when growing it to the Voronoi cell's corners
/// (a cell open towards a boundary, or whose far neighbours are not among those given, has
/// corners far out).
pub const MAX_CELL_GROWTH: f64 = 1.3;
/// A cell's corners are reached with this margin: the weight falls to zero at the ellipse's
/// edge, and a corner exactly on it would stay a pixel-sized hole.
pub const CORNER_MARGIN: f64 = 1.05;

/// Most corners a clipped cell keeps (a cell among 32 neighbours has at most 32).
const MAX_CELL_CORNERS: usize = MAX_SHAPE_NEIGHBOURS + 4;

/// The corners of the point's tangent-plane Voronoi cell among `neighbours` (offsets from the
/// point): a square around the point clipped by the bisector of each neighbour; corners still
/// on the square (the cell is open there, at a boundary, or the neighbours do not reach) are
/// left out.
fn voronoi_corners(neighbours: &[DVec2]) -> impl Iterator<Item = DVec2> {
    let far = 2.0 * neighbours.iter().map(|u| u.length()).fold(0.0, f64::max);
    let mut cell = [DVec2::ZERO; MAX_CELL_CORNERS];
    let mut next = [DVec2::ZERO; MAX_CELL_CORNERS];
    cell[..4].copy_from_slice(&[
        DVec2::new(-far, -far),
        DVec2::new(far, -far),
        DVec2::new(far, far),
        DVec2::new(-far, far),
    ]);
    let mut n = if far > 0.0 { 4 } else { 0 };
    for &u in neighbours {
        // Keep x·u ≤ |u|²/2 (Sutherland–Hodgman against one half-plane).
        let (h, mut m) = (0.5 * u.length_squared(), 0);
        for k in 0..n {
            let (a, b) = (cell[k], cell[(k + 1) % n]);
            let (da, db) = (a.dot(u) - h, b.dot(u) - h);
            if da <= 0.0 && m < MAX_CELL_CORNERS {
                next[m] = a;
                m += 1;
            }
            if (da < 0.0) != (db < 0.0) && da != db && m < MAX_CELL_CORNERS {
                next[m] = a + (b - a) * (da / (da - db));
                m += 1;
            }
        }
        cell[..m].copy_from_slice(&next[..m]);
        n = m;
    }
    let open = 0.99 * far;
    (0..n)
        .map(move |k| cell[k])
        .filter(move |c| c.x.abs().max(c.y.abs()) < open)
}

/// `(k_xx, k_xy, k_yy)` of the least-squares fit `h ≈ −½(k_xx x² + 2k_xy xy + k_yy y²)` to
/// heights `h` at tangent offsets `(x, y)`; zeros when the system is singular.
fn fit_curvature(offsets: &[DVec2], heights: &[f64]) -> [f64; 3] {
    // Normal equations of h = a·(−½x², −xy, −½y²).
    let mut m = glam::DMat3::ZERO;
    let mut rhs = DVec3::ZERO;
    for (u, &h) in offsets.iter().zip(heights) {
        let row = DVec3::new(-0.5 * u.x * u.x, -u.x * u.y, -0.5 * u.y * u.y);
        m += glam::DMat3::from_cols(row * row.x, row * row.y, row * row.z);
        rhs += row * h;
    }
    let scale = m.col(0).x + m.col(2).z;
    let det = m.determinant().abs();
    if offsets.len() < 3 || det.is_nan() || det <= 1e-9 * scale * scale * scale {
        return [0.0; 3];
    }
    let k = m.inverse() * rhs;
    if k.is_finite() {
        k.to_array()
    } else {
        [0.0; 3]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A grid in the z = 0 plane with spacings `hx`, `hy`, its point (0, 0) and the `k` nearest.
    fn grid_neighbours(hx: f32, hy: f32, k: usize) -> Vec<[f32; 3]> {
        let mut pts: Vec<[f32; 3]> = (-6..=6)
            .flat_map(|i| (-6..=6).map(move |j| [i as f32 * hx, j as f32 * hy, 0.0]))
            .filter(|p| p != &[0.0; 3])
            .collect();
        pts.sort_by(|a, b| (a[0].hypot(a[1])).total_cmp(&b[0].hypot(b[1])));
        pts.truncate(k);
        pts
    }

    /// Whether the splat's ellipse (in the z = 0 plane) holds point `q`.
    fn holds(s: &SplatShape, q: [f32; 3]) -> bool {
        let a = glam::Vec2::new(s.axis[0], s.axis[1]);
        let u = glam::Vec2::new(q[0], q[1]);
        (u.dot(a) / s.radius).hypot(u.perp_dot(a) / s.minor_radius) <= 1.0 + 1e-5
    }

    #[test]
    fn anisotropic_grid_gives_an_ellipse_along_the_sparse_direction() {
        // 4× denser along y: the 8 nearest are all on the y column, but the ring reaches x.
        let nb = grid_neighbours(1.0, 0.25, 16);
        let s = splat_shape([0.0; 3], [0.0, 0.0, 1.0], &nb).unwrap();
        assert!(s.axis[0].abs() > 0.99, "major axis along x: {s:?}");
        assert!(
            (s.minor_radius / s.radius - MIN_SPLAT_ASPECT).abs() < 1e-5,
            "aspect clamped: {s:?}"
        );
        // The ring and the nearest, scaled by the overlap factor, are inside.
        for q in [[1.0, 0.0, 0.0], [0.0, 0.25, 0.0], [0.0, 0.75, 0.0]] {
            assert!(holds(&s, q.map(|c| c * SPLAT_OVERLAP)), "{q:?} {s:?}");
        }
        let nb = grid_neighbours(1.0, 0.7, 16);
        let s = splat_shape([0.0; 3], [0.0, 0.0, 1.0], &nb).unwrap();
        assert!(s.axis[0].abs() > 0.99, "{s:?}");
        assert!(
            (s.minor_radius / s.radius - 0.7).abs() < 0.05,
            "aspect follows the spacing: {s:?}"
        );
    }

    #[test]
    fn square_grid_is_round_and_reaches_its_neighbours() {
        let nb = grid_neighbours(0.1, 0.1, 12);
        let s = splat_shape([0.0; 3], [0.0, 0.0, 1.0], &nb).unwrap();
        assert!((s.radius - s.minor_radius).abs() < 1e-6, "{s:?}");
        let k = SPLAT_OVERLAP;
        assert!(s.radius >= 0.1 * k - 1e-6 && s.radius <= 0.1 * k * 2f32.sqrt() + 1e-6);
    }

    #[test]
    fn tilted_plane_axis_is_tangent() {
        let n = glam::Vec3::new(1.0, 1.0, 1.0).normalize();
        let (a, b) = n.any_orthonormal_pair();
        let nb: Vec<[f32; 3]> = grid_neighbours(1.0, 0.5, 16)
            .iter()
            .map(|q| (q[0] * a + q[1] * b + glam::Vec3::splat(2.0)).to_array())
            .collect();
        let s = splat_shape([2.0; 3], n.to_array(), &nb).unwrap();
        let axis = glam::Vec3::from(s.axis);
        assert!(axis.dot(n).abs() < 1e-5 && (axis.length() - 1.0).abs() < 1e-5);
        assert!(axis.dot(a).abs() > 0.99, "{s:?}");
    }

    #[test]
    fn curvature_of_a_sphere_and_a_cylinder() {
        // Neighbours on a sphere of radius 2 around its top (normal +z): k = 1/2 both ways.
        let on_sphere = |x: f32, y: f32| [x, y, (4.0 - x * x - y * y).sqrt() - 2.0];
        let nb: Vec<[f32; 3]> = grid_neighbours(0.1, 0.1, 16)
            .iter()
            .map(|q| on_sphere(q[0], q[1]))
            .collect();
        let s = splat_shape([0.0; 3], [0.0, 0.0, 1.0], &nb).unwrap();
        for k in [s.curvature[0], s.curvature[2]] {
            assert!((k - 0.5).abs() < 0.01, "{s:?}");
        }
        assert!(s.curvature[1].abs() < 0.01, "{s:?}");
        // A cylinder of radius 0.5 along y, sampled densely along y: the ellipse's major
        // axis is along x (the sparse direction), where the curvature is 2; along y, 0.
        let nb: Vec<[f32; 3]> = grid_neighbours(0.1, 0.05, 16)
            .iter()
            .map(|q| [q[0], q[1], (0.25 - q[0] * q[0]).sqrt() - 0.5])
            .collect();
        let s = splat_shape([0.0; 3], [0.0, 0.0, 1.0], &nb).unwrap();
        assert!(s.axis[0].abs() > 0.99, "{s:?}");
        assert!((s.curvature[0] - 2.0).abs() < 0.05, "{s:?}");
        assert!(
            s.curvature[1].abs() < 0.02 && s.curvature[2].abs() < 0.02,
            "{s:?}"
        );
        // A plane: zero.
        let s = splat_shape([0.0; 3], [0.0, 0.0, 1.0], &grid_neighbours(0.1, 0.1, 12)).unwrap();
        assert!(s.curvature.iter().all(|k| k.abs() < 1e-6), "{s:?}");
    }

    #[test]
    fn degenerate_inputs_are_none() {
        assert_eq!(splat_shape([0.0; 3], [0.0; 3], &[[1.0, 0.0, 0.0]; 3]), None);
        assert_eq!(
            splat_shape([0.0; 3], [0.0, 0.0, 1.0], &[[0.0; 3], [0.0, 0.0, 1.0]]),
            None
        );
        let one = splat_shape([0.0; 3], [0.0, 0.0, 1.0], &[[1.0, 0.0, 0.0]]).unwrap();
        assert!((one.radius - SPLAT_OVERLAP).abs() < 1e-6);
    }
}
