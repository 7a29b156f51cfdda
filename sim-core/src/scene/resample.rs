//! Region resampling (DESIGN §3 "dynamic sampling", §6b "holes and stray disks are sampling
//! problems"): after a stroke commits, or an operation replaced the sculpted object, the
//! region's points are brought back onto the zero set and to an even spacing, with normals that
//! agree with the field (see "Normals" below). Only points inside the region box are touched, and every index is built over them
//! alone: the cost scales with the region, not the object.
//!
//! Three passes, at a commit ([`Scene::end_stroke`]) and in [`Scene::resample_region`]:
//! Candidates at a commit are the points the stroke moved, the stranded ones and those in the
//! box of displaced nodes; after an operation, every point of the region.
//! 1. **Off the surface** (before the refit, against the sculpted field `F = f_base + Δ`): a
//!    candidate with `|F| > tolerance` (stranded by a carve, left behind by a push) is
//!    Newton-projected onto `F = 0`; if that fails, or lands more than [`MAX_PROJECTION`]
//!    spacings away, the point is removed. Its local field stays (refitted to `F`, as an
//!    orphan: [`GlobalField::swap_remove_point`]).
//! 2. **Settled and crowded** (after the refit, against the committed field): candidates
//!    still farther than `tolerance` from its zero set (the refit smooths sharp rims) are
//!    projected onto it, or removed; of two candidates closer than `min_distance` whose normals agree, the later
//!    is removed (compression by a push or an emboss).
//! 3. **Holes**: around each candidate whose neighbourhood lies inside the box, the largest
//!    empty circle of its tangent-plane Voronoi cell ([`largest_empty_circle`]); wider than
//!    `max_gap`, a point is inserted there, projected onto the zero set, normal as below,
//!    colour from its parent; repeated `passes` times around the new points.
//!
//! Normals: a point keeps its own normal (the sampled one, turned by the strokes that moved it:
//! [`crate::follow`]) while it is within [`KEEP_NORMAL_ANGLE_COS`] of the field's gradient, and
//! takes the gradient's direction beyond; an inserted point takes the gradient's direction
//! turned as its nearest neighbours' normals are turned from the gradient's direction at them,
//! under the same rule. The gradient everywhere would be simpler, but at a dense
//! sampling it departs from the sampled normals by several degrees in patches (on a dense
//! sampling of a coarse mesh it leans towards the mesh's facets), and the sculpted region
//! then shades in facets beside the untouched surface.
//!
//! Removals are swap-removes (the object's last point moves into the hole), so only the holes
//! and the tail change index; the renderer sees them through [`Scene::take_changed_points`].

use std::collections::HashSet;

use glam::DVec3;
use rayon::prelude::*;

use super::{Region, Scene, SceneError, SceneObject};
use crate::dynamics::DynamicGrid;
use crate::field::GlobalField;
use crate::follow::{Follower, sculpted_value};
use crate::knn::PointIndex;
use crate::resample::{MERGE_MAX_ANGLE_COS, largest_empty_circle};

/// A point's own normal is kept while its cosine with the field's gradient is at least this
/// (30°): wider than the gradient's own roughness at dense samplings (p90 3°, max 11–15°
/// measured on a 300,000-point sampling of the bunny mesh), narrower than what a torn or
/// flipped point shows.
pub const KEEP_NORMAL_ANGLE_COS: f64 = 0.866;

/// Neighbours whose normals turn an inserted point's (see the module doc).
const INSERT_NORMAL_NEIGHBOURS: usize = 6;

/// `own` where it agrees with the field's unit gradient `field` (see [`KEEP_NORMAL_ANGLE_COS`]),
/// else `field`.
fn own_or_field(own: DVec3, field: DVec3) -> DVec3 {
    if own.dot(field) >= KEEP_NORMAL_ANGLE_COS {
        own
    } else {
        field
    }
}

/// Largest distance (in spacings) a point may be projected back onto the surface; farther,
/// it is removed (the surface it belonged to is gone).
pub const MAX_PROJECTION: f64 = 3.0;

/// Settings of region resampling; lengths relative to `spacing`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResampleOptions {
    /// The spacing to keep (m): the object's median nearest-neighbour distance.
    pub spacing: f64,
    /// Insert where the largest empty tangent circle's radius exceeds this (× spacing).
    pub max_gap: f64,
    /// Remove one of two points closer than this (× spacing).
    pub min_distance: f64,
    /// Points with `|f|` above this (× spacing) are projected back or removed.
    pub tolerance: f64,
    /// Insertion passes (each around the previous pass's insertions).
    pub passes: u32,
    /// Neighbours per empty-circle test.
    pub k: usize,
}

impl ResampleOptions {
    /// Defaults for an object of median spacing `spacing`.
    pub fn new(spacing: f64) -> Self {
        Self {
            spacing,
            max_gap: 1.5,
            min_distance: 0.25,
            tolerance: 0.05,
            passes: 8,
            k: 16,
        }
    }
}

/// What a resampling did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct ResampleReport {
    /// Points considered.
    pub candidates: usize,
    /// Points projected back onto the surface.
    pub projected: usize,
    /// Points removed (off the surface with no projection, or crowded).
    pub removed: usize,
    /// Points inserted into holes.
    pub inserted: usize,
}

impl Scene {
    /// Resample the points of the open region (all of them; see the module doc) against the
    /// object's current field, e.g. after an operation replaced the object. Returns what it did.
    pub fn resample_region(
        &mut self,
        opts: &ResampleOptions,
    ) -> Result<ResampleReport, SceneError> {
        let region = self.region.as_mut().ok_or(SceneError::NoRegion)?;
        let obj = &mut self.objects[region.object];
        let which: Vec<u32> = region.inside.clone();
        let base = region.base.take();
        let mut report = ResampleReport::default();
        let removed = off_surface(obj, &mut region.follower, &which, opts, None, &mut report);
        report.removed += apply_removals(obj, region, removed, &mut HashSet::new());
        let mut cands: HashSet<u32> = which.iter().copied().collect();
        cands.retain(|&i| (i as usize) < obj.positions.len());
        even_out(obj, region, cands, opts, &mut report);
        region.base = base.map(|_| obj.field.clone());
        Ok(report)
    }
}

/// Pass 1 over `which`: project points off the zero set (of `F` when `sculpted` gives the
/// stroke's base field and model, else of the object's field) or list them for removal.
/// Projected points are recorded as changed.
pub(super) fn off_surface(
    obj: &mut SceneObject,
    follower: &mut Follower,
    which: &[u32],
    opts: &ResampleOptions,
    sculpted: Option<(&GlobalField, &DynamicGrid)>,
    report: &mut ResampleReport,
) -> Vec<u32> {
    let h = opts.spacing;
    let tol = opts.tolerance * h;
    let field = &obj.field;
    let eval = |x: DVec3| match sculpted {
        Some((base, model)) => sculpted_value(base, model, x),
        None => field.value_and_gradient(x),
    };
    // Each point's projection reads only the field: in parallel, applied in order below.
    let outcome: Vec<Settled> = which
        .par_iter()
        .with_min_len(64)
        .map(|&i| {
            let p = obj.positions[i as usize];
            let (f, _) = eval(p);
            if f.abs() <= tol && !follower.is_stranded(i as usize) {
                return Settled::On(None);
            }
            settle(&eval, p, tol, h)
        })
        .collect();
    let mut removed = Vec::new();
    let mut moves = Vec::new();
    for (&i, o) in which.iter().zip(outcome) {
        match o {
            Settled::On(_) => {}
            Settled::Projected(q, n) => moves.push((i, q, n)),
            Settled::Off => removed.push(i),
        }
    }
    report.candidates += which.len();
    report.projected += moves.len();
    for (i, q, n) in moves {
        obj.positions[i as usize] = q;
        obj.normals[i as usize] = own_or_field(obj.normals[i as usize], n);
        follower.mark_changed(i);
    }
    removed
}

/// Newton-project `x` onto the zero set of `eval` (steps clamped to `h`); the point and unit
/// normal, or `None` when it does not reach `|f| ≤ tol` in 12 steps.
fn project(
    eval: &dyn Fn(DVec3) -> (f64, DVec3),
    x: DVec3,
    tol: f64,
    h: f64,
) -> Option<(DVec3, DVec3)> {
    let mut p = x;
    for _ in 0..12 {
        let (f, g) = eval(p);
        let g2 = g.length_squared();
        if !(g2 > 1e-24 && g2.is_finite() && f.is_finite()) {
            return None;
        }
        if f.abs() <= tol {
            return Some((p, g.normalize()));
        }
        let step = g * (f / g2);
        let len = step.length();
        p -= if len > h { step * (h / len) } else { step };
    }
    None
}

/// Swap-remove `removed` (any order, no duplicates) from the object, its field's point map,
/// the follower and the region's point list; `cands` (point indices) follows the moves.
pub(super) fn apply_removals(
    obj: &mut SceneObject,
    region: &mut Region,
    mut removed: Vec<u32>,
    cands: &mut HashSet<u32>,
) -> usize {
    removed.sort_unstable_by(|a, b| b.cmp(a));
    removed.dedup();
    let mut inside: HashSet<u32> = region.inside.iter().copied().collect();
    for &i in &removed {
        let n = obj.positions.len();
        let last = (n - 1) as u32;
        obj.positions.swap_remove(i as usize);
        obj.normals.swap_remove(i as usize);
        obj.colors.swap_remove(i as usize);
        obj.field.swap_remove_point(i as usize, n);
        region.follower.swap_remove(i as usize);
        for set in [&mut inside, &mut *cands] {
            set.remove(&i);
            if i != last && set.remove(&last) {
                set.insert(i);
            }
        }
    }
    region.inside = inside.into_iter().collect();
    region.inside.sort_unstable();
    removed.len()
}

/// Passes 2 and 3 around `cands` against the object's (refitted) field: settle onto its zero
/// set, merge crowded pairs, fill holes; normals of the candidates are set from its gradient.
pub(super) fn even_out(
    obj: &mut SceneObject,
    region: &mut Region,
    mut cands: HashSet<u32>,
    opts: &ResampleOptions,
    report: &mut ResampleReport,
) {
    let h = opts.spacing;
    if cands.is_empty() || region.inside.len() < 4 || h.is_nan() || h <= 0.0 {
        return;
    }
    let spec = *region.model.spec();
    let (lo, hi) = (spec.origin, spec.max_corner());
    // Onto the (refitted) zero set: the field the picture and the next stroke start from.
    // Projections read only the field: in parallel, applied in order. No handle on the field
    // is held across a removal, which edits the field's point map: a second handle would make
    // that edit copy the whole field (O(scene), 1.3 s at 10⁶ points).
    let tol = opts.tolerance * h;
    let mut sorted: Vec<u32> = cands.iter().copied().collect();
    sorted.sort_unstable();
    let settled: Vec<Settled> = {
        let field = &obj.field;
        let positions = &obj.positions;
        let eval = |x: DVec3| field.value_and_gradient(x);
        sorted
            .par_iter()
            .with_min_len(64)
            .map(|&i| {
                let p = positions[i as usize];
                let (f, g) = field.value_and_gradient(p);
                if f.abs() <= tol {
                    return Settled::On(g.try_normalize());
                }
                settle(&eval, p, tol, h)
            })
            .collect()
    };
    // Every candidate's normal now agrees with the field (`own_or_field`), and stays so: the
    // field no longer changes.
    let mut off = Vec::new();
    for (&i, o) in sorted.iter().zip(settled) {
        let own = obj.normals[i as usize];
        match o {
            Settled::On(n) => {
                if let Some(n) = n {
                    obj.normals[i as usize] = own_or_field(own, n);
                }
            }
            Settled::Projected(q, n) => {
                obj.positions[i as usize] = q;
                obj.normals[i as usize] = own_or_field(own, n);
                report.projected += 1;
            }
            Settled::Off => off.push(i),
        }
    }
    report.removed += apply_removals(obj, region, off, &mut cands);
    // Work in the candidates' box grown by 4 spacings (within the region): the indices below
    // are built over its points only, so a commit costs O(changed area), not O(region).
    let (mut clo, mut chi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for &i in &cands {
        let p = obj.positions[i as usize];
        (clo, chi) = (clo.min(p), chi.max(p));
    }
    let (lo, hi) = (lo.max(clo - 4.0 * h), hi.min(chi + 4.0 * h));
    let in_box = |p: DVec3| p.cmpge(lo).all() && p.cmple(hi).all();
    let near_of = |region: &Region, obj: &SceneObject| -> Vec<u32> {
        region
            .inside
            .iter()
            .copied()
            .filter(|&i| in_box(obj.positions[i as usize]))
            .collect()
    };
    // Candidates whose neighbourhood (about 3 spacings) is inside the box: elsewhere the
    // box's points do not see all their neighbours.
    let interior = |p: DVec3| (p - lo).min_element() > 3.0 * h && (hi - p).min_element() > 3.0 * h;
    // Crowded pairs.
    let near = near_of(region, obj);
    if near.len() < 4 {
        return;
    }
    let local: Vec<DVec3> = near.iter().map(|&i| obj.positions[i as usize]).collect();
    let index = PointIndex::new(&local);
    let mut sorted: Vec<u32> = cands.iter().copied().collect();
    sorted.sort_unstable();
    let mut gone: HashSet<u32> = HashSet::new();
    for &i in &sorted {
        if gone.contains(&i) {
            continue;
        }
        let (p, n) = (obj.positions[i as usize], obj.normals[i as usize]);
        for (k, _) in index.within(p, opts.min_distance * h) {
            let j = near[k];
            if j > i
                && cands.contains(&j)
                && !gone.contains(&j)
                && obj.normals[j as usize].dot(n) >= MERGE_MAX_ANGLE_COS
            {
                gone.insert(j);
            }
        }
    }
    report.removed += apply_removals(obj, region, gone.into_iter().collect(), &mut cands);
    // Holes, a few passes. Insertions add points without local fields: the field is not edited
    // from here on.
    let field = obj.field.clone();
    let mut around: Vec<u32> = cands.iter().copied().collect();
    around.sort_unstable();
    for _ in 0..opts.passes {
        let near = near_of(region, obj);
        let local: Vec<DVec3> = near.iter().map(|&i| obj.positions[i as usize]).collect();
        if local.len() < 4 {
            break;
        }
        let index = PointIndex::new(&local);
        // Each candidate's proposal (the projected centre of its largest empty circle, if
        // wider than the gap) reads only the index and the field: in parallel. Accepted in
        // order, a proposal closer than half a gap to an accepted one is dropped.
        let proposals: Vec<Option<(DVec3, DVec3)>> = around
            .par_iter()
            .with_min_len(32)
            .map_init(
                || Vec::with_capacity(opts.k + 1),
                |hood, &i| {
                    let (p, n) = (obj.positions[i as usize], obj.normals[i as usize]);
                    if !interior(p) {
                        return None;
                    }
                    let nearest = index.nearest_k(p, opts.k + 1);
                    hood.clear();
                    hood.extend(nearest.iter().map(|&(k, _)| local[k]).filter(|&q| q != p));
                    let (c, r) = largest_empty_circle(p, n, hood)?;
                    if r <= opts.max_gap * h {
                        return None;
                    }
                    let (q, qn) =
                        project(&|x| field.value_and_gradient(x), c, opts.tolerance * h, h)?;
                    if !(q.distance(c) <= r && interior(q)) {
                        return None;
                    }
                    // The field's direction, turned as the nearest neighbours' normals are
                    // turned from the field's direction at them (weighted by closeness).
                    let (mut turn, mut weight) = (DVec3::ZERO, 0.0);
                    for &(k, _) in nearest.iter().take(INSERT_NORMAL_NEIGHBOURS) {
                        let Some(g) = field.value_and_gradient(local[k]).1.try_normalize() else {
                            continue;
                        };
                        let m = obj.normals[near[k] as usize];
                        let w = 1.0 / (local[k].distance(q) + 0.1 * h);
                        turn += w * (if m.dot(g) < 0.0 { -m } else { m } - g);
                        weight += w;
                    }
                    let own = if weight > 0.0 { qn + turn / weight } else { qn };
                    Some((q, own_or_field(own.try_normalize().unwrap_or(qn), qn)))
                },
            )
            .collect();
        let mut added: Vec<(DVec3, DVec3, u32)> = Vec::new();
        let mut taken = NearGrid::new(0.5 * opts.max_gap * h);
        for (&i, proposal) in around.iter().zip(proposals) {
            let Some((q, qn)) = proposal else {
                continue;
            };
            if taken.any_within(q, &added) {
                continue;
            }
            taken.insert(q, added.len() as u32);
            added.push((q, qn, i));
        }
        if added.is_empty() {
            break;
        }
        around.clear();
        for (q, qn, parent) in added {
            let i = obj.positions.len() as u32;
            obj.positions.push(q);
            obj.normals.push(qn);
            obj.colors.push(obj.colors[parent as usize]);
            region.inside.push(i);
            region.follower.grow(obj.positions.len());
            region.follower.mark_changed(i);
            cands.insert(i);
            around.push(i);
            around.push(parent);
            report.inserted += 1;
        }
        around.sort_unstable();
        around.dedup();
    }
    // Their normals were settled against the field or blended as they were inserted.
    let mut sorted: Vec<u32> = cands.into_iter().collect();
    sorted.sort_unstable();
    for i in sorted {
        region.follower.mark_changed(i);
    }
}

/// A settling candidate: on the zero set (with the gradient's direction, if any), projected
/// onto it (position and normal), or off it for good (removed).
enum Settled {
    On(Option<DVec3>),
    Projected(DVec3, DVec3),
    Off,
}

/// A point off the zero set of `eval`: projected onto it, or off for good when the projection
/// fails or lands more than [`MAX_PROJECTION`] spacings away.
fn settle(eval: &dyn Fn(DVec3) -> (f64, DVec3), p: DVec3, tol: f64, h: f64) -> Settled {
    match project(eval, p, tol, h) {
        Some((q, n)) if q.distance(p) <= MAX_PROJECTION * h => Settled::Projected(q, n),
        _ => Settled::Off,
    }
}

/// Accepted insertions hashed by cells of the exclusion distance `d`, so a proposal is tested
/// against the accepted ones within `d` only (was every accepted one: quadratic in a pass's
/// insertions, tens of thousands at 10⁶ points).
struct NearGrid {
    d: f64,
    cells: std::collections::HashMap<[i64; 3], Vec<u32>>,
}

impl NearGrid {
    fn new(d: f64) -> Self {
        Self {
            d,
            cells: std::collections::HashMap::new(),
        }
    }

    fn cell(&self, x: DVec3) -> [i64; 3] {
        let c = (x / self.d).floor();
        [c.x as i64, c.y as i64, c.z as i64]
    }

    /// Whether an accepted point (its index into `added` stored here) is closer than `d`.
    fn any_within(&self, q: DVec3, added: &[(DVec3, DVec3, u32)]) -> bool {
        let [cx, cy, cz] = self.cell(q);
        (-1..=1).any(|dx| {
            (-1..=1).any(|dy| {
                (-1..=1).any(|dz| {
                    self.cells
                        .get(&[cx + dx, cy + dy, cz + dz])
                        .is_some_and(|v| {
                            v.iter().any(|&k| added[k as usize].0.distance(q) < self.d)
                        })
                })
            })
        })
    }

    fn insert(&mut self, q: DVec3, k: u32) {
        let c = self.cell(q);
        self.cells.entry(c).or_default().push(k);
    }
}
