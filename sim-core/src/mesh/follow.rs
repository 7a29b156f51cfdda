//! Following the trusted zero set from the points (continuation, as in Bloomenthal's implicit
//! surface polygonizer): instead of evaluating every grid node that might be near the surface,
//! start at the cells holding the points and walk from cell to cell across faces the surface
//! crosses, evaluating only the corners of the cells visited. Nodes evaluated are about those of
//! the crossed cells (2–3 per vertex on a smooth surface), where pruning a narrow band by a
//! slope bound evaluated 10–15 per vertex.
//!
//! The walk stops at cells whose vertex is not trusted (its first guess, or where that guess
//! projects onto the zero set: `cell_facing`), or where the zero set faces
//! against the points vouching for it ([`GlobalField::trusted_facing_near`]: the back of a
//! bump one noisy point's fit makes), so it meshes the trusted zero set connected to the points:
//! a piece of zero set that no point's cell leads to (a fragment the points do not support) is
//! never visited. A point whose cell the surface does not cross is projected onto the zero set
//! once and the projection's cell tried instead.
//!
//! Contract: the visited set, and so the node values, depend only on the field and the grid
//! (each round's frontier is processed as a set; values are evaluated in parallel with the
//! blend's own bits, [`GlobalField::value_near`]).

use std::collections::{HashMap, HashSet};
use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use super::{Fast, Verdict};
use crate::field::{GlobalField, SupportList};
use crate::grid::GridSpec;
use crate::sparse::{
    BLOCK, BlockKey, block_box, block_dims, block_index, block_nodes, gather_block,
};

/// What [`follow`] found.
pub(super) struct Followed {
    /// Node values of every block a visited cell's corner lies in (x fastest; NaN where not
    /// evaluated), ready for the per-block cell scan.
    pub values: HashMap<BlockKey, Vec<f64>>,
    /// The cells the walk found crossed where the surface is trusted and faces its points,
    /// per block: local cell index (`(k · BLOCK + j) · BLOCK + i`, ascending) and its trust
    /// verdict ([`Verdict`]: the vouching points' facing there,
    /// [`GlobalField::trusted_facing_near`], and whether its first guess was trusted). Meshing
    /// places vertices only there, their trust already tested.
    pub crossed: HashMap<BlockKey, Vec<(u32, Verdict)>>,
    /// Field evaluations made (one per node).
    pub evaluations: usize,
    /// Processor time of those evaluations, ns.
    pub eval_ns: u64,
    /// Processor time of the trust tests of the visited cells' first guesses, ns.
    pub trust_ns: u64,
    /// Cells visited.
    pub cells: usize,
}

type Node = [usize; 3];

/// A crossed cell the walk keeps: its corner values and its trust verdict.
type Kept = ([f64; 8], Verdict);

/// Nodes or cells per timed chunk of a parallel step (the phase timers read the clock once
/// per chunk, not once per item).
const TIMED_CHUNK: usize = 256;

/// Walk the trusted zero set of `field` on `spec` from the points' cells.
pub(super) fn follow(field: &GlobalField, spec: &GridSpec) -> Followed {
    let dims = spec.dims;
    let bdims = block_dims(spec);
    let h = spec.spacing;
    let cell_of = |p: DVec3| -> Option<Node> {
        let g = (p - spec.origin) / h;
        let c = [g.x, g.y, g.z].map(|v| v.floor());
        (0..3)
            .all(|a| c[a] >= 0.0 && (c[a] as usize) + 1 < dims[a])
            .then(|| c.map(|v| v as usize))
    };
    let home = |n: Node| -> BlockKey { std::array::from_fn(|a| (n[a] / BLOCK).min(bdims[a] - 1)) };
    let corners = |c: Node| -> [Node; 8] {
        std::array::from_fn(|k| [c[0] + (k & 1), c[1] + ((k >> 1) & 1), c[2] + (k >> 2)])
    };

    let key = |n: Node| ((n[2] * dims[1] + n[1]) * dims[0] + n[0]) as u64;
    // Blocks are keyed by their index in the grid of blocks, hashed by the cheap hasher: the
    // walk looks a block up per node and per cell.
    let block_id = |b: BlockKey| block_index(bdims, b) as u64;
    // Node values, stored in every block whose nodes include the node (face nodes are
    // shared), NaN where not evaluated: read from the node's home block, and handed to
    // meshing as they are.
    let mut blocks: HashMap<u64, (BlockKey, Vec<f64>), Fast> = HashMap::default();
    let value_of = |blocks: &HashMap<u64, (BlockKey, Vec<f64>), Fast>, n: Node| -> f64 {
        let b = home(n);
        blocks.get(&block_id(b)).map_or(f64::NAN, |(_, v)| {
            let (first, count) = block_nodes(spec, b);
            v[((n[2] - first[2]) * count[1] + n[1] - first[1]) * count[0] + n[0] - first[0]]
        })
    };
    let mut lists: HashMap<u64, SupportList, Fast> = HashMap::default();
    let mut visited: HashSet<u64, Fast> = HashSet::default();
    let (mut eval_ns, mut trust_ns, mut evaluations) = (0u64, 0u64, 0usize);
    let mut crossed_cells: Vec<(Node, Verdict)> = Vec::new();

    // Round 0: the cells holding the points, each with the points in it (for the retry).
    let mut seeds: HashMap<u64, DVec3, Fast> = HashMap::default();
    let mut frontier: Vec<Node> = Vec::new();
    for p in field.centres() {
        if let Some(c) = cell_of(p)
            && let std::collections::hash_map::Entry::Vacant(seed) = seeds.entry(key(c))
        {
            seed.insert(p);
            frontier.push(c);
        }
    }
    frontier.sort_unstable();
    visited.extend(frontier.iter().map(|&c| key(c)));
    let mut retry_seeds = true;

    while !frontier.is_empty() {
        // 1. Evaluate the corners not yet known, in parallel, each with its home block's
        //    supports (gathered once per block).
        let mut need: Vec<Node> = frontier
            .par_iter()
            .flat_map_iter(|&c| corners(c))
            .filter(|&n| value_of(&blocks, n).is_nan())
            .collect();
        need.par_sort_unstable();
        need.dedup();
        let mut new_blocks: Vec<BlockKey> = need
            .iter()
            .map(|&n| home(n))
            .filter(|&b| !lists.contains_key(&block_id(b)))
            .collect();
        new_blocks.sort_unstable();
        new_blocks.dedup();
        let gathered: Vec<(u64, SupportList)> = new_blocks
            .par_iter()
            .map(|&b| {
                let mut l = SupportList::new();
                gather_block(field, spec, b, &mut l);
                (block_id(b), l)
            })
            .collect();
        lists.extend(gathered);
        // Timed per chunk: a clock read per node cost a few percent of the walk.
        let evaluated: Vec<(Vec<f64>, u64)> = need
            .par_chunks(TIMED_CHUNK)
            .map(|chunk| {
                let t = Instant::now();
                let f = chunk
                    .iter()
                    .map(|&n| {
                        let x = spec.node_position(n[0], n[1], n[2]);
                        field.value_near(x, &lists[&block_id(home(n))])
                    })
                    .collect();
                (f, t.elapsed().as_nanos() as u64)
            })
            .collect();
        eval_ns += evaluated.iter().map(|e| e.1).sum::<u64>();
        evaluations += need.len();
        for (&n, &f) in need.iter().zip(evaluated.iter().flat_map(|(f, _)| f)) {
            // Every block whose nodes include n: its home and, where n lies on a block face,
            // the blocks below that face.
            let lo: [usize; 3] = std::array::from_fn(|a| n[a].saturating_sub(1) / BLOCK);
            let hi: [usize; 3] = std::array::from_fn(|a| (n[a] / BLOCK).min(bdims[a] - 1));
            for bk in lo[2]..=hi[2] {
                for bj in lo[1]..=hi[1] {
                    for bi in lo[0]..=hi[0] {
                        let b = [bi, bj, bk];
                        let (first, count) = block_nodes(spec, b);
                        let l: [usize; 3] = std::array::from_fn(|a| n[a].wrapping_sub(first[a]));
                        if (0..3).any(|a| l[a] >= count[a]) {
                            continue;
                        }
                        let (_, v) = blocks
                            .entry(block_id(b))
                            .or_insert_with(|| (b, vec![f64::NAN; count[0] * count[1] * count[2]]));
                        v[(l[2] * count[1] + l[1]) * count[0] + l[0]] = f;
                    }
                }
            }
        }

        // 2. Which frontier cells the surface crosses where it is trusted (in parallel: the
        //    trust test is the costly part).
        // Per frontier cell: its corner values and the points' facing if kept; per chunk, the
        // processor time (its trust tests, the rest of a cell's work a small part).
        let crossed: Vec<(Vec<Option<Kept>>, u64)> = frontier
            .par_chunks(TIMED_CHUNK)
            .map(|chunk| {
                let t = Instant::now();
                let kept = chunk
                    .iter()
                    .map(|&c| {
                        let f = corners(c).map(|n| value_of(&blocks, n));
                        let guess = first_guess(&f)?;
                        let cell_lo = spec.node_position(c[0], c[1], c[2]);
                        let p = cell_lo + guess * h;
                        // The guess lies in the cell, inside the box its first corner's block
                        // list was gathered for (the index answers if rounding put it a hair
                        // outside).
                        let b = home(c);
                        let facing = super::cell_facing(
                            field,
                            p,
                            (cell_lo, h),
                            &lists[&block_id(b)],
                            block_box(spec, b),
                        );
                        let kept = facing
                            .filter(|v| field.faces_its_points(corner_gradient(&f), v.facing));
                        kept.map(|v| (f, v))
                    })
                    .collect();
                (kept, t.elapsed().as_nanos() as u64)
            })
            .collect();
        trust_ns += crossed.iter().map(|c| c.1).sum::<u64>();
        let crossed: Vec<Option<Kept>> = crossed.into_iter().flat_map(|c| c.0).collect();

        // 3. Step across every face with a sign change among its corners (in parallel; the
        //    cells not yet visited, each once, form the next frontier).
        let mut steps: Vec<Node> = frontier
            .par_iter()
            .zip(&crossed)
            .flat_map_iter(|(&c, kept)| {
                let f = kept.as_ref().map(|k| k.0);
                (0..6).filter_map(move |face| {
                    let f = f?;
                    let (axis, side) = (face / 2, face % 2);
                    let (mut neg, mut pos) = (false, false);
                    for k in (0..8).filter(|k| (k >> axis) & 1 == side) {
                        (neg, pos) = (neg || f[k] < 0.0, pos || f[k] >= 0.0);
                    }
                    if !(neg && pos) {
                        return None;
                    }
                    let mut n = c;
                    if side == 0 {
                        n[axis] = n[axis].checked_sub(1)?;
                    } else {
                        n[axis] += 1;
                        if n[axis] + 1 >= dims[axis] {
                            return None;
                        }
                    }
                    Some(n)
                })
            })
            .collect();
        if retry_seeds {
            // A point whose cell the surface misses: try where it projects.
            steps.par_extend(frontier.par_iter().zip(&crossed).filter_map(|(&c, kept)| {
                let &p = seeds.get(&key(c)).filter(|_| kept.is_none())?;
                let pr = field.project_to_zero_set(p);
                pr.converged.then(|| cell_of(pr.point)).flatten()
            }));
        }
        crossed_cells.extend(
            frontier
                .iter()
                .zip(&crossed)
                .filter_map(|(&c, kept)| kept.as_ref().map(|k| (c, k.1))),
        );
        steps.par_sort_unstable();
        steps.dedup();
        let next: Vec<Node> = steps
            .into_par_iter()
            .filter(|&n| !visited.contains(&key(n)))
            .collect();
        visited.extend(next.iter().map(|&n| key(n)));
        retry_seeds = false;
        frontier = next;
    }

    let mut crossed: HashMap<BlockKey, Vec<(u32, Verdict)>> = HashMap::new();
    for (c, verdict) in crossed_cells {
        let b = c.map(|v| v / BLOCK);
        let l = c.map(|v| v % BLOCK);
        let local = ((l[2] * BLOCK + l[1]) * BLOCK + l[0]) as u32;
        crossed.entry(b).or_default().push((local, verdict));
    }
    for cells in crossed.values_mut() {
        cells.sort_unstable_by_key(|c| c.0);
    }
    Followed {
        values: blocks.into_values().collect(),
        crossed,
        evaluations,
        eval_ns,
        trust_ns,
        cells: visited.len(),
    }
}

/// The direction in which the corner values of a cell grow (their finite differences along
/// each axis, summed over the cell's four edges on that axis).
pub(super) fn corner_gradient(corner: &[f64; 8]) -> DVec3 {
    let mut g = DVec3::ZERO;
    for (a, b) in super::CUBE_EDGES {
        g += (super::corner_offset(b) - super::corner_offset(a)) * (corner[b] - corner[a]);
    }
    g
}

/// The surface-nets first guess in a cell from its corner values (cell units, relative to
/// its first corner), or `None` without a sign change.
pub(super) fn first_guess(corner: &[f64; 8]) -> Option<DVec3> {
    let (mut sum, mut n) = (DVec3::ZERO, 0.0);
    for (a, b) in super::CUBE_EDGES {
        let (fa, fb) = (corner[a], corner[b]);
        if (fa < 0.0) != (fb < 0.0) {
            let t = fa / (fa - fb);
            let pa = super::corner_offset(a);
            sum += pa + (super::corner_offset(b) - pa) * t;
            n += 1.0;
        }
    }
    (n > 0.0).then(|| sum / n)
}
