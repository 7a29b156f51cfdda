//! Sharp creases in the mesh. The blend rounds a crease over about a support radius: every
//! local fit near it sees both faces. Where the points around a vertex fall into two groups
//! whose normals differ by more than [`CREASE_ANGLE_COS`] allows, and the *wedge* of the two
//! groups' planes (their intersection at a convex crease, their union at a concave one)
//! explains every point to within [`WEDGE_FIT`] of their support radius, the vertex moves to
//! the wedge's nearest point: on a face it lands on the face's plane, across the crease on the
//! crease line, as dual contouring places vertices from the planes of a cell's crossings. It
//! moves only part way where the wedge fits the points less well (beyond half the tolerance)
//! or lies farther than half its reach, so neighbouring vertices that judge a crease a little
//! differently do not leave a step between them.
//!
//! A rounded edge is left as the blend makes it: its points lie on the arc, inside the
//! wedge, and the wedge does not explain them. So is a corner of three faces and the top of a
//! thin blade: some normal there lies off the great circle through the two faces' normals.
//! So is a wedge whose crease line passes far from every point ([`CREASE_NEAR`]): at a narrow
//! face sampled only along its two edges, each edge's normals are averages across it, and one
//! edge's row can pass for a face tilted halfway to the next one, meeting the other face out
//! in the air.
//! Where vertices sit on a crease line, the mesher's choice of each quad's diagonal (the one
//! whose triangles face like their corners) keeps the crease from being cut across.
//!
//! Contract: [`sharpen`] is allocation-free (at most [`MAX_NEIGHBOURS`] points are
//! considered); a vertex moves by less than the `reach` its caller gives; `None` leaves it
//! where it was. [`unfold`] is a pass over the finished mesh.

use glam::DVec3;

use super::TriMesh;
use crate::field::{GlobalField, SupportList};

/// Points considered around a vertex (the nearest by blending weight are kept).
pub(crate) const MAX_NEIGHBOURS: usize = 64;

/// Two normal groups whose closest members are farther apart than this cosine (35°) make a
/// crease candidate.
const CREASE_ANGLE_COS: f64 = 0.82;

/// Faces whose normals are more than this far apart (cosine; 150°) are the two sides of a
/// thin part, not a crease.
const OPPOSED_COS: f64 = -0.87;

/// A normal off the great circle through the two faces' normals by more than this (sine,
/// 15°) belongs to a third face.
const ARC_SIN: f64 = 0.26;

/// Points whose blending weight at the vertex is below this hardly shape the blend there and
/// are left out (they may lie on a third face beyond the crease).
const MIN_WEIGHT: f64 = 0.1;

/// A point belongs to a face's group when its normal is within this cosine (15°) of the
/// group's; points between the groups (a scanned crease's own points, whose normals bisect
/// it) are only checked against the wedge.
const GROUP_COS: f64 = 0.966;

/// The wedge must explain every point to within this fraction of the mean support radius.
const WEDGE_FIT: f64 = 0.04;

/// The crease line must pass within this fraction of the mean support radius of a point (a
/// sampled crease has points on it; faces sampled in rows beside it, within half a spacing).
/// On the fandisk at resolution 200 with `--creases`, 0.1–0.3 leave the same eight of 28,490
/// vertices unmoved, the ones a blade's end face pulled out; 0.5 moves them.
const CREASE_NEAR: f64 = 0.25;

/// A vertex moves at most this many cells (as the projection may).
const REACH_CELLS: f64 = 2.0;

/// A point around a vertex: where it is, its normal, its blending weight there and its
/// support radius.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Neighbour {
    pub centre: DVec3,
    pub normal: DVec3,
    pub weight: f64,
    pub radius: f64,
}

/// A plane `n · x = offset`.
#[derive(Debug, Clone, Copy)]
struct Plane {
    n: DVec3,
    offset: f64,
}

impl Plane {
    fn distance(&self, x: DVec3) -> f64 {
        self.n.dot(x) - self.offset
    }
}

/// Where the vertex of the cell `cell`, projected onto the zero set at `p` with gradient
/// `gradient`, belongs on a crease ([`wedge_point`] over the points whose supports hold `p`,
/// from `supports`, a list gathered for a box holding `p`); it moves at most
/// [`REACH_CELLS`] cells.
pub(crate) fn sharpen(
    field: &GlobalField,
    p: DVec3,
    gradient: DVec3,
    cell: (DVec3, DVec3),
    supports: &SupportList,
) -> Option<(DVec3, DVec3)> {
    let mut around = [Neighbour::default(); MAX_NEIGHBOURS];
    let mut count = 0;
    field.for_each_support_near(p, supports, |centre, normal, weight, radius| {
        let q = Neighbour {
            centre,
            normal,
            weight,
            radius,
        };
        if count < around.len() {
            around[count] = q;
            count += 1;
        } else if let Some(least) = around
            .iter_mut()
            .min_by(|a, b| a.weight.total_cmp(&b.weight))
            && least.weight < weight
        {
            *least = q;
        }
    });
    wedge_point(
        p,
        gradient,
        cell,
        &around[..count],
        REACH_CELLS * (cell.1 - cell.0).x,
    )
}

/// Move back the sharpened vertices (`(id, where it was, its normal)`) of triangles that
/// moving them turned over (against their vertices' normals), in up to four rounds; returns
/// how many moved back. Surface nets joins neighbouring cells' vertices, and two vertices
/// pulled onto different planes of a crease can fold the triangle between them.
pub(crate) fn unfold(mesh: &mut TriMesh, sharpened: &[(u32, DVec3, DVec3)]) -> usize {
    if sharpened.is_empty() {
        return 0;
    }
    let mut original = std::collections::HashMap::with_capacity(sharpened.len());
    for &(id, p, n) in sharpened {
        original.insert(id, (p, n));
    }
    let mut restored = 0;
    for _ in 0..4 {
        let mut back = Vec::new();
        for t in &mesh.triangles {
            if !t.iter().any(|v| original.contains_key(v)) {
                continue;
            }
            let [a, b, c] = t.map(|v| mesh.vertices[v as usize]);
            let normal = t.iter().map(|&v| mesh.normals[v as usize]).sum::<DVec3>();
            if (b - a).cross(c - a).dot(normal) <= 0.0 {
                back.extend(t.iter().copied().filter(|v| original.contains_key(v)));
            }
        }
        if back.is_empty() {
            break;
        }
        for v in back {
            if let Some((p, n)) = original.remove(&v) {
                mesh.vertices[v as usize] = p;
                mesh.normals[v as usize] = n;
                restored += 1;
            }
        }
    }
    restored
}

/// Where the vertex of the cell `cell` (its corners' box), now at `p` with the zero set's
/// normal `normal`, belongs on a crease, and the normal there: if the points facing the same
/// side (normals within 90° of `normal`; the far side of a thin part is the blend's own
/// business) make a crease the wedge explains, on the crease line where that crosses the cell
/// (its point nearest `p`), else the wedge's nearest point to `p`; within `reach` of `p`, and
/// part way by how well the wedge fits and how far it is (see the module doc).
pub(crate) fn wedge_point(
    p: DVec3,
    normal: DVec3,
    cell: (DVec3, DVec3),
    around: &[Neighbour],
    reach: f64,
) -> Option<(DVec3, DVec3)> {
    let mut kept = [Neighbour::default(); MAX_NEIGHBOURS];
    let mut count = 0;
    for q in around
        .iter()
        .filter(|q| q.weight >= MIN_WEIGHT && q.normal.dot(normal) > 0.0)
    {
        if count < kept.len() {
            kept[count] = *q;
            count += 1;
        }
    }
    let points = &kept[..count];
    if points.len() < 6 {
        return None;
    }
    // The two most different normals seed the groups.
    let (mut a, mut b, mut least) = (0, 0, f64::INFINITY);
    for i in 0..points.len() {
        for j in i + 1..points.len() {
            let d = points[i].normal.dot(points[j].normal);
            if d < least {
                (a, b, least) = (i, j, d);
            }
        }
    }
    if least > CREASE_ANGLE_COS {
        return None; // smooth
    }
    let (mut na, mut nb) = (points[a].normal, points[b].normal);
    // Which face a normal is nearer: 0 (`na`'s) or 1 (`nb`'s).
    let face_of = |n: DVec3, na: DVec3, nb: DVec3| usize::from(n.dot(nb) > n.dot(na));
    let mut planes = [Plane { n: na, offset: 0.0 }; 2];
    for _ in 0..3 {
        let mut sum = [(DVec3::ZERO, DVec3::ZERO, 0.0); 2];
        for q in points {
            if q.normal.dot(na).max(q.normal.dot(nb)) < GROUP_COS {
                continue;
            }
            let g = face_of(q.normal, na, nb);
            sum[g].0 += q.normal * q.weight;
            sum[g].1 += q.centre * q.weight;
            sum[g].2 += q.weight;
        }
        for (g, (n, c, w)) in sum.into_iter().enumerate() {
            if w <= 0.0 {
                return None;
            }
            let n = n.try_normalize()?;
            planes[g] = Plane {
                n,
                offset: n.dot(c / w),
            };
        }
        (na, nb) = (planes[0].n, planes[1].n);
    }
    if na.dot(nb) > CREASE_ANGLE_COS || na.dot(nb) < OPPOSED_COS {
        return None;
    }
    // The crease's direction: between 35° and 150° apart, the two normals are far from
    // parallel (|na × nb|² > 0.24).
    let direction = na.cross(nb);
    let denominator = direction.length_squared();
    // Every normal lies on the arc between the two faces': a third face (a corner, the far
    // side of a thin blade) is not a wedge of two.
    let across = direction / denominator.sqrt();
    if points.iter().any(|q| q.normal.dot(across).abs() > ARC_SIN) {
        return None;
    }
    let mean_radius = points.iter().map(|q| q.radius).sum::<f64>() / points.len() as f64;
    // The crease line must pass near the points: where each face's group is one row along
    // an edge whose normals are averaged across it (a mesh's vertex normals at the rim of a
    // narrow face), the groups' planes, tilted halfway to the next faces, meet out in the air.
    let on_line = (nb * planes[0].offset - na * planes[1].offset).cross(direction) / denominator;
    let nearest = points
        .iter()
        .map(|q| (q.centre - on_line).reject_from_normalized(across).length())
        .fold(f64::INFINITY, f64::min);
    // `f64::min` skips NaN: no point, or none at a finite distance, leaves infinity.
    if nearest > CREASE_NEAR * mean_radius {
        return None;
    }
    // Convex when each face's points lie behind the other's plane (on it counts neither way).
    let convex = points
        .iter()
        .map(|q| {
            let d = planes[1 - face_of(q.normal, na, nb)].distance(q.centre);
            q.weight * f64::from(i8::from(d > 0.0) - i8::from(d < 0.0))
        })
        .sum::<f64>()
        < 0.0;
    let wedge = |x: DVec3| {
        let (da, db) = (planes[0].distance(x), planes[1].distance(x));
        if convex { da.max(db) } else { da.min(db) }
    };
    // How well the wedge explains the points: fully within WEDGE_FIT/2 of a support radius,
    // not at all beyond WEDGE_FIT, linearly between (so neighbouring vertices that judge a
    // crease a little differently move a little differently, not all or nothing).
    let worst = points
        .iter()
        .map(|q| wedge(q.centre).abs())
        .fold(0.0, f64::max)
        / (WEDGE_FIT * mean_radius);
    let fit = (2.0 - 2.0 * worst).clamp(0.0, 1.0);
    if fit <= 0.0 {
        return None;
    }
    // Moved part way by how well the wedge fits and how far it is (fully within half the reach).
    let partly = |x: DVec3, n: DVec3| {
        let far = (x - p).length() / reach;
        let w = fit * (2.0 - 2.0 * far).clamp(0.0, 1.0);
        let turned = (normal.normalize_or_zero() * (1.0 - w) + n * w).normalize_or(n);
        (w > 0.0).then(|| (p + (x - p) * w, turned))
    };
    // The crease line (`on_line`, its direction) where it crosses the cell.
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for a in 0..3 {
        let (o, d) = (on_line[a], direction[a]);
        if d.abs() < 1e-300 {
            if o < cell.0[a] || o > cell.1[a] {
                (t0, t1) = (1.0, 0.0);
            }
        } else {
            let (u, v) = ((cell.0[a] - o) / d, (cell.1[a] - o) / d);
            (t0, t1) = (t0.max(u.min(v)), t1.min(u.max(v)));
        }
    }
    if t0 <= t1 {
        let t = ((p - on_line).dot(direction) / denominator).clamp(t0, t1);
        let x = on_line + direction * t;
        return partly(x, (na + nb).normalize());
    }
    // The wedge's nearest point: on a plane where the other does not cut it off.
    let mut best: Option<(DVec3, DVec3)> = None;
    let mut consider = |x: DVec3, n: DVec3| {
        if wedge(x).abs() <= 1e-9 * mean_radius.max(1e-300)
            && best.is_none_or(|(y, _)| (x - p).length_squared() < (y - p).length_squared())
        {
            best = Some((x, n));
        }
    };
    for plane in planes {
        consider(p - plane.n * plane.distance(p), plane.n);
    }
    best.and_then(|(x, n)| partly(x, n))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points on the two faces of a 90° convex edge along y (faces z = 0, x ≤ 0 and x = 0,
    /// z ≤ 0), spacing 0.1, with support radius 0.3.
    fn edge_points(round: f64) -> Vec<Neighbour> {
        let mut out = Vec::new();
        for i in 0..4 {
            for j in -2..=2 {
                let (s, y) = (i as f64 * 0.1, j as f64 * 0.1);
                let top = DVec3::new(-s, y, 0.0);
                let side = DVec3::new(0.0, y, -s);
                out.push((top, DVec3::Z));
                if i > 0 {
                    out.push((side, DVec3::X));
                }
            }
        }
        out.into_iter()
            .map(|(c, n)| {
                // A rounded edge: points near it pulled in onto a quarter circle of radius round.
                let (c, n) = if round > 0.0 && c.x > -round && c.z > -round {
                    let centre = DVec3::new(-round, c.y, -round);
                    let d = (DVec3::new(c.x, c.y, c.z) - centre).with_y(0.0).normalize();
                    (centre + d * round, d)
                } else {
                    (c, n)
                };
                Neighbour {
                    centre: c,
                    normal: n,
                    weight: 1.0,
                    radius: 0.3,
                }
            })
            .collect()
    }

    #[test]
    fn a_vertex_on_a_rounded_surface_near_a_sharp_edge_moves_onto_the_edge_or_a_face() {
        let points = edge_points(0.0);
        let cell = |lo: DVec3| (lo, lo + DVec3::splat(0.05));
        // In a cell the edge crosses, just inside the corner (where a blend rounds it): to the
        // edge line.
        let p = DVec3::new(-0.02, 0.05, -0.02);
        let (x, n) = wedge_point(
            p,
            DVec3::new(1.0, 0.0, 1.0),
            cell(DVec3::new(-0.04, 0.03, -0.04)),
            &points,
            0.1,
        )
        .unwrap();
        assert!((x - DVec3::new(0.0, 0.05, 0.0)).length() < 1e-12, "{x}");
        assert!((n - DVec3::new(1.0, 0.0, 1.0).normalize()).length() < 1e-12);
        // Below the top face in a cell away from the edge: onto the face.
        let p = DVec3::new(-0.2, 0.0, -0.01);
        let (x, n) = wedge_point(
            p,
            DVec3::new(1.0, 0.0, 1.0),
            cell(DVec3::new(-0.22, -0.02, -0.04)),
            &points,
            0.1,
        )
        .unwrap();
        assert!((x - DVec3::new(-0.2, 0.0, 0.0)).length() < 1e-12, "{x}");
        assert_eq!(n, DVec3::Z);
        // Beyond reach: left where it is.
        let p = DVec3::new(-0.3, 0.0, -0.3);
        assert!(
            wedge_point(
                p,
                DVec3::new(1.0, 0.0, 1.0),
                cell(DVec3::new(-0.32, -0.02, -0.32)),
                &points,
                0.1
            )
            .is_none()
        );
    }

    #[test]
    fn a_corner_of_three_faces_is_left_to_the_blend() {
        // A cube's corner at the origin: faces x = 0, y = 0 and z = 0 (the solid below each).
        let mut points = Vec::new();
        for i in 0..4 {
            for j in 0..4 {
                let (s, t) = (-(i as f64) * 0.1, -(j as f64) * 0.1);
                for (centre, normal) in [
                    (DVec3::new(0.0, s, t), DVec3::X),
                    (DVec3::new(s, 0.0, t), DVec3::Y),
                    (DVec3::new(s, t, 0.0), DVec3::Z),
                ] {
                    points.push(Neighbour {
                        centre,
                        normal,
                        weight: 1.0,
                        radius: 0.3,
                    });
                }
            }
        }
        let p = DVec3::splat(-0.02);
        let cell = (DVec3::splat(-0.04), DVec3::splat(0.01));
        assert!(wedge_point(p, DVec3::ONE, cell, &points, 0.1).is_none());
        // Two of its faces alone are a crease.
        let two: Vec<Neighbour> = points
            .iter()
            .copied()
            .filter(|q| q.normal != DVec3::Y)
            .collect();
        let (q, n) = (p.with_y(-0.2), DVec3::new(1.0, 0.0, 1.0));
        let cell = (q - 0.02, q + 0.03);
        let (x, _) = wedge_point(q, n, cell, &two, 0.1).unwrap();
        assert!((x - DVec3::new(0.0, -0.2, 0.0)).length() < 1e-12, "{x}");
    }

    #[test]
    fn a_narrow_face_sampled_only_at_its_edges_is_not_taken_for_a_face() {
        // The end of a blade 0.2 thick: its top face z = 0 (x ≤ 0) sampled in rows, its end
        // face x = 0 only along its two edges, whose normals (a mesh's vertex normals) are
        // averaged across them, as on the fandisk's thin end face. The lower edge's row, one
        // line of points with one tilted normal, would pass for a face whose plane, tilted 45°,
        // meets the top face 0.2 out, where no point is, and pulls the vertex out of the end
        // face.
        let mut points = Vec::new();
        let tilt = |z: f64| DVec3::new(1.0, 0.0, z).normalize();
        for j in -2..=2 {
            let y = j as f64 * 0.1;
            for i in 1..4 {
                points.push((DVec3::new(-0.1 * i as f64, y, 0.0), DVec3::Z));
            }
            points.push((DVec3::new(0.0, y, 0.0), tilt(1.0)));
            points.push((DVec3::new(0.0, y, -0.2), tilt(-1.0)));
        }
        let points: Vec<Neighbour> = points
            .into_iter()
            .map(|(centre, normal)| Neighbour {
                centre,
                normal,
                weight: 1.0,
                radius: 0.3,
            })
            .collect();
        // A vertex the blend left 0.03 proud of the end face, its normal tilted up.
        let p = DVec3::new(0.03, 0.0, -0.1);
        let cell = (p - 0.025, p + 0.025);
        let moved = wedge_point(p, DVec3::new(0.95, 0.0, 0.3), cell, &points, 0.1);
        assert!(
            moved.is_none_or(|(x, _)| x.x.abs() <= p.x),
            "moved away from the end face, to {:?}",
            moved.map(|m| m.0)
        );
        // One row of a real face meeting the top face at the upper edge, where the crease
        // line runs through the upper edge's points: a crease, and the vertex goes onto that
        // face.
        let mut wedge: Vec<Neighbour> = points
            .iter()
            .copied()
            .filter(|q| q.centre.z == 0.0)
            .collect();
        for q in wedge.iter_mut().filter(|q| q.centre.x == 0.0) {
            q.normal = (DVec3::Z + tilt(1.0)).normalize();
        }
        for j in -2..=2 {
            wedge.push(Neighbour {
                centre: DVec3::new(0.1, j as f64 * 0.1, -0.1),
                normal: tilt(1.0),
                ..points[0]
            });
        }
        let q = DVec3::new(0.06, 0.0, -0.04);
        let (x, n) = wedge_point(q, tilt(1.0), (q - 0.025, q + 0.025), &wedge, 0.1).unwrap();
        assert!((x - DVec3::new(0.05, 0.0, -0.05)).length() < 1e-12, "{x}");
        assert!((n - tilt(1.0)).length() < 1e-12, "{n}");
    }

    #[test]
    fn a_rounded_edge_and_a_smooth_patch_are_left_to_the_blend() {
        // The edge rounded with radius 0.15: the arc's points lie inside the wedge.
        let cell = (DVec3::splat(-0.04), DVec3::splat(0.01));
        let p = DVec3::new(-0.02, 0.0, -0.02);
        assert!(wedge_point(p, DVec3::new(1.0, 0.0, 1.0), cell, &edge_points(0.15), 0.1).is_none());
        // A plane: no crease.
        let flat: Vec<Neighbour> = edge_points(0.0)
            .into_iter()
            .map(|q| Neighbour {
                centre: q.centre.with_z(0.0),
                normal: DVec3::Z,
                ..q
            })
            .collect();
        let p = DVec3::new(-0.1, 0.0, -0.01);
        assert!(wedge_point(p, DVec3::Z, (p - 0.02, p + 0.02), &flat, 0.1).is_none());
    }
}
