//! Field sampling that scales with the surface, not the box: the grid is cut into blocks of
//! [`BLOCK`]³ cells and only the blocks near the points are evaluated, on all cores, each with
//! one support query for the whole block ([`GlobalField::gather_supports`]) instead of one per
//! node.
//!
//! Two consumers:
//! - [`crate::mesh`] gathers a block's supports once ([`gather_block`]) for the nodes and
//!   vertices of the cells its walk along the zero set visits there, and samples every block
//!   ([`sample_block`]) when meshing densely, the reference.
//! - [`sample_trusted`] fills a whole grid (the sculpting region) with
//!   [`GlobalField::trusted_value`]: blocks reached by a support get the blend, the rest the
//!   nearest point's signed distance, which is exactly what the blend falls back to there.
//!
//! Contract: the result equals evaluating every node ([`sample_trusted_dense`], and the dense
//! mesher) bit for bit: gathered lists keep the index's order, so every blend sums the same
//! terms in the same order; a test checks both.
//! Deterministic: blocks are processed in parallel but assembled in key order.

use glam::DVec3;
use rayon::prelude::*;

use crate::field::{GlobalField, SupportList};
use crate::grid::{GridSpec, ScalarGrid};

/// Cells per block edge.
pub const BLOCK: usize = 8;

/// A block's coordinates (in blocks) on a grid.
pub type BlockKey = [usize; 3];

/// Number of blocks along each axis of `spec` (cells / [`BLOCK`], rounded up).
pub fn block_dims(spec: &GridSpec) -> [usize; 3] {
    spec.dims
        .map(|n| (n.saturating_sub(1)).div_ceil(BLOCK).max(1))
}

/// Block `b`'s index in the grid of blocks `bdims` ([`block_dims`]), x fastest: one integer
/// to key maps of blocks by.
pub fn block_index(bdims: [usize; 3], b: BlockKey) -> usize {
    (b[2] * bdims[1] + b[1]) * bdims[0] + b[0]
}

/// Every block of the grid, in key order (z slowest).
pub fn all_blocks(spec: &GridSpec) -> Vec<BlockKey> {
    let [bx, by, bz] = block_dims(spec);
    let mut out = Vec::with_capacity(bx * by * bz);
    for k in 0..bz {
        for j in 0..by {
            for i in 0..bx {
                out.push([i, j, k]);
            }
        }
    }
    out
}

/// The blocks holding a node or cell of `spec` within one of `balls` (centre, radius), sorted in
/// key order and deduplicated. A ball's bounding box is tested, so the set is conservative.
/// `cells = true` selects by the cells the balls touch (a block owns its cells), `false` by
/// the nodes (a block's nodes include its far faces).
pub fn blocks_near(
    spec: &GridSpec,
    balls: impl Iterator<Item = (DVec3, f64)>,
    cells: bool,
) -> Vec<BlockKey> {
    let [bx, by, bz] = block_dims(spec);
    let limit = spec
        .dims
        .map(|n| n.saturating_sub(if cells { 2 } else { 1 }) as f64);
    let mut keys: Vec<u64> = Vec::new();
    for (c, r) in balls {
        let lo = (c - DVec3::splat(r) - spec.origin) / spec.spacing;
        let hi = (c + DVec3::splat(r) - spec.origin) / spec.spacing;
        if !(lo.is_finite() && hi.is_finite()) {
            continue;
        }
        let range = |a: usize| -> Option<(usize, usize)> {
            let (first, last) = if cells {
                (lo[a].floor(), hi[a].floor())
            } else {
                (lo[a].ceil(), hi[a].floor())
            };
            if last < 0.0 || first > limit[a] || first > last {
                return None;
            }
            let to_block = |v: f64| v.clamp(0.0, limit[a]) as usize / BLOCK;
            Some((to_block(first), to_block(last)))
        };
        let (Some(x), Some(y), Some(z)) = (range(0), range(1), range(2)) else {
            continue;
        };
        for k in z.0..=z.1.min(bz - 1) {
            for j in y.0..=y.1.min(by - 1) {
                for i in x.0..=x.1.min(bx - 1) {
                    keys.push(((k * by + j) * bx + i) as u64);
                }
            }
        }
    }
    keys.par_sort_unstable();
    keys.dedup();
    keys.into_iter()
        .map(|key| {
            let key = key as usize;
            [key % bx, (key / bx) % by, key / (bx * by)]
        })
        .collect()
}

/// The node range of block `b`: first node and node counts per axis (up to `BLOCK + 1`, clipped
/// to the grid).
pub fn block_nodes(spec: &GridSpec, b: BlockKey) -> ([usize; 3], [usize; 3]) {
    let first = b.map(|v| v * BLOCK);
    let count = std::array::from_fn(|a| (spec.dims[a] - first[a]).min(BLOCK + 1));
    (first, count)
}

/// The box block `b`'s nodes span: what [`gather_block`] gathers for, so a list it filled
/// answers for every point inside.
pub fn block_box(spec: &GridSpec, b: BlockKey) -> (DVec3, DVec3) {
    let (first, count) = block_nodes(spec, b);
    let lo = spec.node_position(first[0], first[1], first[2]);
    let hi = spec.node_position(
        first[0] + count[0] - 1,
        first[1] + count[1] - 1,
        first[2] + count[2] - 1,
    );
    (lo, hi)
}

/// Gather into `supports` every support reaching block `b`'s nodes.
pub fn gather_block(field: &GlobalField, spec: &GridSpec, b: BlockKey, supports: &mut SupportList) {
    let (lo, hi) = block_box(spec, b);
    field.gather_supports(lo, hi, supports);
}

/// The field's values at block `b`'s nodes (x fastest), `value(x, f)` mapping the blend `f(x)`
/// to what is stored; `supports` must hold the block's supports ([`gather_block`]).
pub fn sample_block(
    field: &GlobalField,
    spec: &GridSpec,
    b: BlockKey,
    supports: &SupportList,
    value: impl Fn(DVec3, f64) -> f64,
    out: &mut Vec<f64>,
) {
    let (first, count) = block_nodes(spec, b);
    out.clear();
    for k in 0..count[2] {
        for j in 0..count[1] {
            for i in 0..count[0] {
                let x = spec.node_position(first[0] + i, first[1] + j, first[2] + k);
                out.push(value(x, field.value_near(x, supports)));
            }
        }
    }
}

/// The grid `spec` filled with [`GlobalField::trusted_value`], evaluating the blend only in the
/// blocks some support reaches; elsewhere the value is the nearest point's signed distance.
pub fn sample_trusted(field: &GlobalField, spec: GridSpec) -> ScalarGrid {
    let blocks = blocks_near(&spec, field.support_balls(), false);
    sample_blocks_trusted(field, spec, &blocks)
}

/// [`sample_trusted`] evaluating the blend at every node (for comparison and tests).
pub fn sample_trusted_dense(field: &GlobalField, spec: GridSpec) -> ScalarGrid {
    sample_blocks_trusted(field, spec, &all_blocks(&spec))
}

fn sample_blocks_trusted(field: &GlobalField, spec: GridSpec, blocks: &[BlockKey]) -> ScalarGrid {
    let sampled: Vec<(BlockKey, Vec<f64>)> = blocks
        .par_iter()
        .map_init(SupportList::new, |supports, &b| {
            let mut v = Vec::new();
            gather_block(field, &spec, b, supports);
            sample_block(
                field,
                &spec,
                b,
                supports,
                |x, f| field.trusted_value_from(x, f),
                &mut v,
            );
            (b, v)
        })
        .collect();
    let mut values = vec![f64::NAN; spec.node_count()];
    for (b, v) in &sampled {
        let (first, count) = block_nodes(&spec, *b);
        let mut it = v.iter();
        for k in 0..count[2] {
            for j in 0..count[1] {
                for i in 0..count[0] {
                    let idx = spec.index(first[0] + i, first[1] + j, first[2] + k);
                    values[idx] = *it.next().unwrap_or(&f64::NAN);
                }
            }
        }
    }
    values.par_iter_mut().enumerate().for_each(|(idx, v)| {
        if v.is_nan() {
            let [i, j, k] = spec.coords(idx);
            *v = field.nearest_signed_distance(spec.node_position(i, j, k)).0;
        }
    });
    // Finite by the field's contract; fall back to the dense path's guarantee otherwise.
    ScalarGrid::from_values(spec, values)
        .unwrap_or_else(|_| ScalarGrid::from_fn(spec, |x| field.trusted_value(x)))
}
