//! Where the mouse's ray meets the surface: the ray cast behind the mouse as the stylus. Pure
//! geometry, no window: tested here.
//!
//! - [`ray_field`] marches the field snapshot the force thread reads (the sculpting region's
//!   trusted field on its grid) along the ray, clipped to the grid's box, in steps of
//!   [`MARCH_STEP`] cells; at the first sign change from outside (`f > 0`) to inside (`f ≤ 0`)
//!   it bisects to [`BISECTION_TOL_M`]. A ray that enters the box already inside the material
//!   met the surface before the box: not this field's hit.
//! - [`ray_points`] is the fallback where there is no field (outside the region, or no region):
//!   of the points within `radius` of the ray, the nearest to the eye.
//! - [`pick`] takes the field's hit unless a point lies clearly in front of it (another object,
//!   or a part of the sculpted one outside the region).

use glam::DVec3;
use sim_core::grid::ScalarGrid;

use crate::live::points::ChunkedPoints;

/// March step, in grid cells (the field is trilinear per cell: half a cell cannot step over a
/// surface crossing the cell, except a sliver thinner than that).
pub const MARCH_STEP: f64 = 0.5;
/// Bisection stops when the bracket is this short (m).
pub const BISECTION_TOL_M: f64 = 1e-7;
/// Most bisection steps (the bracket halves each: 60 take any box to below 1e-7 m).
pub const MAX_BISECTIONS: usize = 60;

/// Where a ray met the surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// The surface point (m).
    pub point: DVec3,
    /// Unit outward normal there.
    pub normal: DVec3,
    /// Distance from the ray's origin (m).
    pub t: f64,
}

/// The ray's parameter interval inside the box `lo..hi`, from `t ≥ 0`; `None` when it misses.
fn clip(origin: DVec3, dir: DVec3, lo: DVec3, hi: DVec3) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for a in 0..3 {
        if dir[a].abs() < 1e-300 {
            if origin[a] < lo[a] || origin[a] > hi[a] {
                return None;
            }
            continue;
        }
        let (u, v) = ((lo[a] - origin[a]) / dir[a], (hi[a] - origin[a]) / dir[a]);
        t0 = t0.max(u.min(v));
        t1 = t1.min(u.max(v));
    }
    (t0 <= t1).then_some((t0, t1))
}

/// The first place the ray from `origin` along `dir` enters the material of `grid`'s field;
/// see the module doc. `None`: it misses, or enters the grid inside the material.
pub fn ray_field(grid: &ScalarGrid, origin: DVec3, dir: DVec3) -> Option<Hit> {
    let dir = dir.try_normalize()?;
    if !origin.is_finite() {
        return None;
    }
    let spec = grid.spec();
    let (t0, t1) = clip(origin, dir, spec.origin, spec.max_corner())?;
    // Stay a hair inside the box so every sample is inside the grid.
    let eps = 1e-9 * spec.spacing.max(1e-9);
    let (t0, t1) = (t0 + eps, t1 - eps);
    let step = MARCH_STEP * spec.spacing;
    let value = |t: f64| grid.sample(origin + dir * t).map(|s| s.value);
    let mut prev = (t0, value(t0)?);
    if prev.1 <= 0.0 {
        return None;
    }
    let mut t = t0;
    while t < t1 {
        t = (t + step).min(t1);
        let Some(f) = value(t) else { continue };
        if f <= 0.0 {
            // Bracketed between prev.0 (outside) and t (inside).
            let (mut a, mut b) = (prev.0, t);
            for _ in 0..MAX_BISECTIONS {
                if b - a <= BISECTION_TOL_M {
                    break;
                }
                let m = 0.5 * (a + b);
                match value(m) {
                    Some(v) if v > 0.0 => a = m,
                    _ => b = m,
                }
            }
            let t = 0.5 * (a + b);
            let point = origin + dir * t;
            let normal = grid
                .sample(point)
                .and_then(|s| s.gradient.try_normalize())
                .unwrap_or(-dir);
            return Some(Hit { point, normal, t });
        }
        prev = (t, f);
    }
    None
}

/// Of the `points` (with unit `normals`) within `radius` of the ray, the nearest to the eye;
/// `None` when none is.
pub fn ray_points(
    points: &[DVec3],
    normals: &[DVec3],
    origin: DVec3,
    dir: DVec3,
    radius: f64,
) -> Option<Hit> {
    let dir = dir.try_normalize()?;
    let r2 = radius * radius;
    let mut best: Option<(f64, usize)> = None;
    for (i, p) in points.iter().enumerate() {
        let d = *p - origin;
        let t = d.dot(dir);
        if t <= 0.0 || best.is_some_and(|(b, _)| t >= b) {
            continue;
        }
        if d.length_squared() - t * t <= r2 {
            best = Some((t, i));
        }
    }
    let (t, i) = best?;
    let normal = normals
        .get(i)
        .and_then(|n| n.try_normalize())
        .unwrap_or(-dir);
    Some(Hit {
        point: points[i],
        normal,
        t,
    })
}

/// The surface under the ray: the field's hit, unless the points give one more than `radius`
/// in front of it or the field gives none. `radius`: how near the ray a point must be (about
/// the points' spacing).
pub fn pick(
    field: Option<&ScalarGrid>,
    points: &[DVec3],
    normals: &[DVec3],
    origin: DVec3,
    dir: DVec3,
    radius: f64,
) -> Option<Hit> {
    let on_field = field.and_then(|g| ray_field(g, origin, dir));
    let on_points = ray_points(points, normals, origin, dir, radius);
    match (on_field, on_points) {
        (Some(f), Some(p)) if p.t < f.t - 2.0 * radius => Some(p),
        (Some(f), _) => Some(f),
        (None, p) => p,
    }
}

/// [`pick`] against a snapshot's chunked points: the nearest hit over the chunks, O(points).
pub fn pick_chunks(
    field: Option<&ScalarGrid>,
    points: &ChunkedPoints,
    origin: DVec3,
    dir: DVec3,
    radius: f64,
) -> Option<Hit> {
    let on_field = field.and_then(|g| ray_field(g, origin, dir));
    let on_points = points
        .chunks()
        .iter()
        .filter_map(|c| ray_points(&c.positions, &c.normals, origin, dir, radius))
        .min_by(|a, b| a.t.total_cmp(&b.t));
    match (on_field, on_points) {
        (Some(f), Some(p)) if p.t < f.t - 2.0 * radius => Some(p),
        (Some(f), _) => Some(f),
        (None, p) => p,
    }
}

/// [`typical_spacing`] of a snapshot's points from at most 8 chunks spread through them (a
/// big scan's chunks are spatially ordered patches, so their spacing is the scan's).
pub fn typical_spacing_chunks(points: &ChunkedPoints) -> Option<f64> {
    let chunks = points.chunks();
    let stride = chunks.len().div_ceil(8).max(1);
    let some: Vec<DVec3> = chunks
        .iter()
        .step_by(stride)
        .flat_map(|c| c.positions.iter().copied())
        .collect();
    typical_spacing(&some)
}

/// A typical spacing of `points` (m): the median, over up to 32 of them spread through the
/// list, of the distance to their nearest other point. O(32 N): for a pick radius, computed
/// when the point count changes, not per frame. `None` for fewer than 2 points.
pub fn typical_spacing(points: &[DVec3]) -> Option<f64> {
    if points.len() < 2 {
        return None;
    }
    let stride = (points.len() / 32).max(1);
    let mut d: Vec<f64> = (0..points.len())
        .step_by(stride)
        .take(32)
        .map(|i| {
            points
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .map(|(_, q)| q.distance_squared(points[i]))
                .fold(f64::INFINITY, f64::min)
                .sqrt()
        })
        .filter(|d| d.is_finite())
        .collect();
    d.sort_by(f64::total_cmp);
    d.get(d.len() / 2).copied()
}

#[cfg(test)]
mod tests {
    use super::*;
    use sim_core::grid::GridSpec;

    const R: f64 = 0.05;

    /// A sphere of radius `R` at `c` as a signed distance on a 2.5 mm grid over `lo..hi`.
    fn sphere(c: DVec3, lo: DVec3, hi: DVec3) -> ScalarGrid {
        ScalarGrid::from_fn(GridSpec::covering(lo, hi, 0.0025), |x| x.distance(c) - R)
    }

    #[test]
    fn a_ray_into_a_sphere_field_hits_its_surface_facing_the_eye() {
        let c = DVec3::new(0.01, -0.005, 0.002);
        let g = sphere(c, DVec3::splat(-0.08), DVec3::splat(0.08));
        let eye = DVec3::new(0.1, 0.2, 0.3);
        for aim in [
            c,
            c + DVec3::new(0.03, 0.01, 0.0),
            c + DVec3::new(-0.02, 0.035, 0.0),
        ] {
            let hit = ray_field(&g, eye, aim - eye).expect("the ray hits");
            // On the sphere, within the trilinear interpolation's error of a 2.5 mm grid.
            let r = hit.point.distance(c);
            assert!((r - R).abs() < 1e-4, "|hit − c| = {r} for aim {aim}");
            // The near side: the normal faces the eye.
            assert!(hit.normal.dot(eye - hit.point) > 0.0);
            assert!((hit.normal - (hit.point - c) / r).length() < 0.05);
            assert!((hit.point.distance(eye) - hit.t).abs() < 1e-9);
        }
    }

    #[test]
    fn a_ray_past_the_sphere_or_away_from_it_misses() {
        let c = DVec3::ZERO;
        let g = sphere(c, DVec3::splat(-0.08), DVec3::splat(0.08));
        let eye = DVec3::new(0.0, 0.0, 0.3);
        // Beside the sphere, through the grid.
        assert_eq!(ray_field(&g, eye, DVec3::new(0.07, 0.0, -0.3)), None);
        // Away from the grid.
        assert_eq!(ray_field(&g, eye, DVec3::Z), None);
        // Degenerate rays.
        assert_eq!(ray_field(&g, eye, DVec3::ZERO), None);
        assert_eq!(ray_field(&g, DVec3::NAN, DVec3::NEG_Z), None);
    }

    #[test]
    fn a_ray_entering_the_grid_inside_the_material_is_not_the_fields_hit() {
        // The grid covers the sphere's upper half only; a ray from below enters it inside.
        let g = sphere(
            DVec3::ZERO,
            DVec3::new(-0.08, 0.0, -0.08),
            DVec3::splat(0.08),
        );
        let eye = DVec3::new(0.0, -0.3, 0.0);
        assert_eq!(ray_field(&g, eye, DVec3::Y), None);
        // From above it hits the top.
        let hit = ray_field(&g, DVec3::new(0.0, 0.3, 0.0), DVec3::NEG_Y).unwrap();
        assert!((hit.point - DVec3::new(0.0, R, 0.0)).length() < 1e-4);
    }

    fn sphere_points(c: DVec3, n: usize) -> (Vec<DVec3>, Vec<DVec3>) {
        // A Fibonacci sphere.
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let normals: Vec<DVec3> = (0..n)
            .map(|i| {
                let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - y * y).sqrt();
                let a = golden * i as f64;
                DVec3::new(r * a.cos(), y, r * a.sin())
            })
            .collect();
        (normals.iter().map(|n| c + *n * R).collect(), normals)
    }

    #[test]
    fn without_a_field_the_nearest_point_to_the_eye_near_the_ray_is_the_hit() {
        let (p, n) = sphere_points(DVec3::ZERO, 4000);
        let h = typical_spacing(&p).unwrap();
        assert!((0.001..0.005).contains(&h), "spacing {h}");
        let eye = DVec3::new(0.0, 0.0, 0.3);
        let hit = pick(None, &p, &n, eye, DVec3::new(0.01, 0.02, -0.3), h).unwrap();
        assert!((hit.point.length() - R).abs() < 1e-12);
        assert!(hit.point.z > 0.0, "the near side: {}", hit.point);
        assert!(hit.normal.z > 0.0);
        assert_eq!(pick(None, &p, &n, eye, DVec3::new(0.1, 0.0, -0.3), h), None);
    }

    #[test]
    fn a_point_clearly_in_front_of_the_fields_hit_wins() {
        let g = sphere(DVec3::ZERO, DVec3::splat(-0.08), DVec3::splat(0.08));
        let eye = DVec3::new(0.0, 0.0, 0.3);
        let dir = DVec3::NEG_Z;
        // A point on the field's surface: the field's (more precise) hit stays.
        let on = [DVec3::new(0.0, 0.0005, R)];
        let up = [DVec3::Z];
        let hit = pick(Some(&g), &on, &up, eye, dir, 0.002).unwrap();
        assert!((hit.point.z - R).abs() < 1e-4 && hit.point.y.abs() < 1e-9);
        // Another object's point 2 cm in front of it wins.
        let front = [DVec3::new(0.0, 0.0005, R + 0.02)];
        let hit = pick(Some(&g), &front, &up, eye, dir, 0.002).unwrap();
        assert_eq!(hit.point, front[0]);
    }
}
