//! [`Follower`]: which points to update each step, in parallel, and the per-stroke bookkeeping.
//!
//! Finding the points worth updating without touching all of them: the region's points are
//! bucketed into blocks of `BLOCK³` grid cells. Each call marks a node *hot* when its velocity
//! would move the field by more than `ε` this step or its displacement drifted more than `ε`
//! from the value it had when it was last hot (then that value is renewed). Only points in the
//! blocks around hot nodes (the block and its 26 neighbours, so points may drift up to a block
//! from where they were bucketed) go through the per-point test of [`super::follow_point`].
//! A point skipped this way has `|Δ(x) − Δ_seen| ≤ 2ε`. Buckets are rebuilt when a point has
//! moved half a block since bucketing, and at the end of each stroke.

use glam::DVec3;
use rayon::prelude::*;

use super::{FollowOptions, FollowReport, PointCache, PointUpdate, follow_point};
use crate::dynamics::DynamicGrid;
use crate::field::GlobalField;

/// Grid cells per block edge.
const BLOCK: usize = 4;

/// Moves points with the field; owns the per-stroke moved list and per-step scratch.
#[derive(Debug, Clone, Default)]
pub struct Follower {
    /// Settings.
    pub options: FollowOptions,
    moved: Vec<u32>,
    is_moved: Vec<bool>,
    /// Points changed since the last [`Follower::take_changed`] (each once).
    changed: Vec<u32>,
    is_changed: Vec<bool>,
    is_stranded: Vec<bool>,
    stranded: usize,
    /// Per point (object index).
    cache: Vec<PointCache>,
    /// Bucketing: block of each candidate, CSR block → candidates, bucketed positions.
    bucketed: Vec<DVec3>,
    block_start: Vec<u32>,
    block_items: Vec<u32>,
    block_dims: [usize; 3],
    rebuild: bool,
    /// Per active slot: displacement when last hot.
    u_ref: Vec<f64>,
    touched: Vec<bool>,
    work: Vec<u32>,
    results: Vec<Option<PointUpdate>>,
}

impl Follower {
    /// A follower for an object of `points` points.
    pub fn new(points: usize, options: FollowOptions) -> Self {
        Self {
            options,
            is_moved: vec![false; points],
            is_changed: vec![false; points],
            is_stranded: vec![false; points],
            cache: vec![PointCache::default(); points],
            rebuild: true,
            ..Self::default()
        }
    }

    /// Points moved since the last [`Follower::clear_moved`] (each once).
    pub fn moved(&self) -> &[u32] {
        &self.moved
    }

    /// Make room for points appended to the object (they start unmoved); rebucket.
    pub fn grow(&mut self, points: usize) {
        if points > self.is_moved.len() {
            self.is_moved.resize(points, false);
            self.is_changed.resize(points, false);
            self.is_stranded.resize(points, false);
            self.cache.resize(points, PointCache::default());
        }
        self.rebuild = true;
    }

    /// Start a new stroke: clear the moved list, forget the Taylor models (the base field
    /// changed) and the node references (the model was committed), rebucket.
    pub fn clear_moved(&mut self) {
        self.cache.fill(PointCache::default());
        self.u_ref.fill(0.0);
        for &i in &self.moved {
            self.is_moved[i as usize] = false;
        }
        self.moved.clear();
        self.rebuild = true;
    }

    /// Record that point `i` changed (moved, appended, or refilled by a removal) for the next
    /// [`Follower::take_changed`].
    pub fn mark_changed(&mut self, i: u32) {
        let iu = i as usize;
        if iu >= self.is_changed.len() {
            self.is_changed.resize(iu + 1, false);
        }
        if !self.is_changed[iu] {
            self.is_changed[iu] = true;
            self.changed.push(i);
        }
    }

    /// Append the points changed since the last call to `out` (each once, in the order they
    /// first changed) and forget them. O(changed).
    pub fn take_changed(&mut self, out: &mut Vec<u32>) {
        for &i in &self.changed {
            if let Some(c) = self.is_changed.get_mut(i as usize) {
                *c = false;
            }
        }
        out.extend(
            self.changed
                .iter()
                .copied()
                .filter(|&i| (i as usize) < self.is_moved.len()),
        );
        self.changed.clear();
    }

    /// The object's point `i` was swap-removed (its last point moved into `i`): keep the
    /// per-point state in step. O(moved points).
    pub fn swap_remove(&mut self, i: usize) {
        if i >= self.is_moved.len() {
            return;
        }
        let last = self.is_moved.len() - 1;
        if self.is_moved[i] {
            self.moved.retain(|&x| x as usize != i);
        }
        if self.is_moved[last] && last != i {
            for x in &mut self.moved {
                if *x as usize == last {
                    *x = i as u32;
                }
            }
            self.moved.sort_unstable();
        }
        if self.is_stranded[i] {
            self.stranded -= 1;
        }
        self.is_moved.swap_remove(i);
        self.is_stranded.swap_remove(i);
        self.cache.swap_remove(i);
        // The point now at `i` is new there to whoever reads the changes (a listed index past
        // the end is dropped by `take_changed`).
        self.is_changed.resize(self.is_moved.len(), false);
        if let Some(c) = self.is_changed.get_mut(i) {
            *c = false;
        }
        self.mark_changed(i as u32);
        self.rebuild = true;
    }

    /// Heap bytes held (per-point caches and flags, buckets, per-node references, scratch).
    pub fn memory_bytes(&self) -> usize {
        self.cache.capacity() * std::mem::size_of::<PointCache>()
            + self.is_moved.capacity() * 3
            + self.changed.capacity() * 4
            + (self.moved.capacity() + self.block_items.capacity() + self.block_start.capacity())
                * 4
            + self.bucketed.capacity() * 24
            + self.u_ref.capacity() * 8
            + self.touched.capacity()
            + self.work.capacity() * 4
            + self.results.capacity() * std::mem::size_of::<Option<PointUpdate>>()
    }

    /// Whether point `i` is currently stranded.
    pub fn is_stranded(&self, i: usize) -> bool {
        self.is_stranded.get(i).copied().unwrap_or(false)
    }

    /// Move the candidate points near changing nodes by Eq. 9 over `dt`, re-project them onto
    /// `F = 0`, update their normals, and remember them as moved. `candidates` lists the points
    /// inside the region. Points are processed in parallel, each independently, so the result
    /// does not depend on the thread count.
    pub fn follow(
        &mut self,
        base: &GlobalField,
        model: &DynamicGrid,
        candidates: &[u32],
        points: &mut [DVec3],
        normals: &mut [DVec3],
        dt: f64,
    ) -> FollowReport {
        if self.rebuild || self.bucketed.len() != candidates.len() {
            self.bucket(model, candidates, points);
        }
        self.collect_work(model, candidates, dt);
        let opts = self.options;
        self.results.clear();
        self.results.resize(self.work.len(), None);
        {
            let (pts, nrm, cache) = (&*points, &*normals, &self.cache);
            self.results
                .par_iter_mut()
                .zip(self.work.par_iter())
                .with_min_len(32)
                .for_each(|(out, &i)| {
                    let i = i as usize;
                    *out = follow_point(base, model, cache[i], pts[i], nrm[i], dt, &opts);
                });
        }
        let mut report = FollowReport::default();
        let half_block = 0.5 * BLOCK as f64 * model.spec().spacing;
        for (r, &w) in self.results.iter().zip(&self.work) {
            let Some(up) = *r else {
                continue;
            };
            let i = w as usize;
            report.visited += 1;
            report.exact_evaluations += usize::from(up.exact);
            self.cache[i] = up.cache;
            let stranded = up.residual > model.spec().spacing;
            if stranded != self.is_stranded[i] {
                self.is_stranded[i] = stranded;
                if stranded {
                    self.stranded += 1;
                } else {
                    self.stranded -= 1;
                }
            }
            if stranded {
                continue;
            }
            report.max_residual = report.max_residual.max(up.residual);
            report.max_move = report.max_move.max(up.position.distance(points[i]));
            points[i] = up.position;
            normals[i] = up.normal;
            if !self.is_moved[i] {
                self.is_moved[i] = true;
                self.moved.push(w);
            }
            if !self.is_changed[i] {
                self.is_changed[i] = true;
                self.changed.push(w);
            }
        }
        // Rebucket once points have drifted half a block from where they were bucketed.
        self.rebuild |= self
            .work
            .iter()
            .filter_map(|&i| candidates.binary_search(&i).ok().map(|k| (i, k)))
            .any(|(i, k)| points[i as usize].distance(self.bucketed[k]) > half_block);
        report.stranded = self.stranded;
        report
    }

    /// Turn the moved points' normals by the smooth gradient of the displacements (the module
    /// doc of [`crate::follow`]): call at the end of a stroke, before the model commits (the
    /// displacements are what turns them). O(moved points), in parallel; points the follower
    /// left stranded keep theirs.
    pub fn settle_normals(&self, model: &DynamicGrid, points: &[DVec3], normals: &mut [DVec3]) {
        let turned: Vec<(u32, DVec3)> = self
            .moved
            .par_iter()
            .with_min_len(256)
            .filter_map(|&i| {
                let iu = i as usize;
                let c = self.cache.get(iu)?;
                if c.start_normal == DVec3::ZERO || self.is_stranded(iu) {
                    return None;
                }
                let dg = super::displacement_gradient_smooth(model, *points.get(iu)?)?;
                super::turned_normal(c.start_normal, c.g, dg).map(|n| (i, n))
            })
            .collect();
        for (i, n) in turned {
            normals[i as usize] = n;
        }
    }

    fn block_of(&self, model: &DynamicGrid, x: DVec3) -> usize {
        let spec = model.spec();
        let g = ((x - spec.origin) / (spec.spacing * BLOCK as f64)).floor();
        let c = |a: usize| (g[a].max(0.0) as usize).min(self.block_dims[a] - 1);
        c(0) + self.block_dims[0] * (c(1) + self.block_dims[1] * c(2))
    }

    fn bucket(&mut self, model: &DynamicGrid, candidates: &[u32], points: &[DVec3]) {
        let dims = model.spec().dims;
        self.block_dims = dims.map(|n| n.div_ceil(BLOCK).max(1));
        let nb = self.block_dims.iter().product::<usize>();
        self.block_start.clear();
        self.block_start.resize(nb + 1, 0);
        self.bucketed.clear();
        self.bucketed
            .extend(candidates.iter().map(|&i| points[i as usize]));
        let blocks: Vec<usize> = self
            .bucketed
            .iter()
            .map(|&x| self.block_of(model, x))
            .collect();
        for &b in &blocks {
            self.block_start[b + 1] += 1;
        }
        for b in 0..nb {
            self.block_start[b + 1] += self.block_start[b];
        }
        let mut fill = self.block_start.clone();
        self.block_items.clear();
        self.block_items.resize(candidates.len(), 0);
        for (&i, &b) in candidates.iter().zip(&blocks) {
            self.block_items[fill[b] as usize] = i;
            fill[b] += 1;
        }
        self.touched.clear();
        self.touched.resize(nb, false);
        self.u_ref.resize(model.active_len(), 0.0);
        self.rebuild = false;
    }

    /// Mark hot nodes' neighbourhoods and gather their points into `work` (sorted, unique).
    fn collect_work(&mut self, model: &DynamicGrid, candidates: &[u32], dt: f64) {
        let eps = self.options.motion_epsilon;
        let (u, v) = (model.displacement(), model.velocity());
        self.u_ref.resize(u.len(), 0.0);
        self.touched.fill(false);
        let spec = *model.spec();
        let [bx, by, bz] = self.block_dims;
        for (s, &g) in model.active_nodes().iter().enumerate() {
            let hot = (v[s] * dt).abs() > eps || (u[s] - self.u_ref[s]).abs() > eps;
            if !hot {
                continue;
            }
            self.u_ref[s] = u[s];
            let [i, j, k] = spec.coords(g as usize);
            let (ci, cj, ck) = (i / BLOCK, j / BLOCK, k / BLOCK);
            for kk in ck.saturating_sub(1)..=(ck + 1).min(bz - 1) {
                for jj in cj.saturating_sub(1)..=(cj + 1).min(by - 1) {
                    for ii in ci.saturating_sub(1)..=(ci + 1).min(bx - 1) {
                        self.touched[ii + bx * (jj + by * kk)] = true;
                    }
                }
            }
        }
        self.work.clear();
        for (b, _) in self.touched.iter().enumerate().filter(|(_, t)| **t) {
            let (a, e) = (
                self.block_start[b] as usize,
                self.block_start[b + 1] as usize,
            );
            self.work.extend_from_slice(&self.block_items[a..e]);
        }
        // Candidate order (ascending point index) keeps the moved list deterministic.
        self.work.sort_unstable();
        debug_assert!(
            self.work
                .iter()
                .all(|i| candidates.binary_search(i).is_ok())
        );
    }
}
