//! Triangle meshes, and extraction of a field's zero set by surface nets: one vertex per grid
//! cell crossed by the surface (the mean of its edge crossings, then Newton-projected onto the
//! zero set), one quad per crossed grid edge, oriented so triangle normals point outward.
//!
//! Only the trusted zero set is meshed ([`GlobalField::trusted_facing_near`]): a cell emits a
//! vertex only where it is trusted (near the points, covered, near their planes), judged at
//! its first guess or, where that is not, at the guess's projection onto the zero set (a grid
//! coarse for the part puts the crossings' mean off the surface), and the zero set there faces
//! the way those points do, so sheets and blobs where local fits extrapolate, inverted bumps of
//! noisy points, and sign changes of the nearest-point fallback
//! far from the surface, leave no geometry. [`extract_zero_set`] finds the cells by walking the
//! trusted zero set from the points' cells (`follow.rs`): it evaluates about the corners of the
//! crossed cells (cost ∝ surface, not box) and meshes no piece that no point leads to.
//! [`MeshOptions`] can leave vertices at the edge crossings' mean (to measure what projecting
//! them gains) and move vertices near sharp creases onto the faces' wedge (`features.rs`).
//! [`extract_zero_set_dense`] evaluates every node and scans every cell: on a surface the points
//! support everywhere it gives the same triangles, bit for bit (it may also place a lone vertex
//! no triangle uses, in a cell no crossed neighbour leads the walk to).
//! [`TriMesh::cut_unsupported_pieces`] (`pieces.rs`) is the safety net a caller may add: it cuts
//! a piece that holds no point's nearest vertex, and reports it.
//!
//! Contract: vertices are finite; deterministic for a field and grid.

mod features;
mod follow;
mod pieces;

use std::collections::HashMap;
use std::hash::BuildHasherDefault;
use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use crate::field::{GlobalField, SupportList};
use crate::grid::GridSpec;
use crate::projection::{ProjectOptions, project_to_zero_set_near, project_to_zero_set_near_from};
use crate::sparse::{
    BLOCK, BlockKey, all_blocks, block_box, block_dims, block_index, block_nodes, gather_block,
    sample_block,
};
use crate::spatial::MulHasher;

pub use pieces::CutPiece;

/// An indexed triangle mesh; triangles are counter-clockwise seen from outside.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions.
    pub vertices: Vec<DVec3>,
    /// Unit vertex normals (empty, or one per vertex).
    pub normals: Vec<DVec3>,
    /// Vertex index triples.
    pub triangles: Vec<[u32; 3]>,
}

impl TriMesh {
    /// Area-weighted vertex normals from the triangles' winding (zero for a vertex that no
    /// non-degenerate triangle uses). For a consistently wound mesh they face outward.
    pub fn vertex_normals(&self) -> Vec<DVec3> {
        let mut n = vec![DVec3::ZERO; self.vertices.len()];
        for t in &self.triangles {
            let [a, b, c] = t.map(|i| self.vertices[i as usize]);
            let area_normal = (b - a).cross(c - a);
            if area_normal.is_finite() {
                for &i in t {
                    n[i as usize] += area_normal;
                }
            }
        }
        n.into_iter()
            .map(|v| v.try_normalize().unwrap_or(DVec3::ZERO))
            .collect()
    }

    /// Connected components (triangles sharing a vertex are connected): each vertex's
    /// component label (`u32::MAX` for a vertex no triangle uses) and the number of triangles
    /// in each component, largest first in label order.
    pub fn components(&self) -> (Vec<u32>, Vec<usize>) {
        let n = self.vertices.len();
        let mut parent: Vec<u32> = (0..n as u32).collect();
        fn root(parent: &mut [u32], mut v: u32) -> u32 {
            while parent[v as usize] != v {
                let up = parent[parent[v as usize] as usize];
                parent[v as usize] = up;
                v = up;
            }
            v
        }
        for t in &self.triangles {
            for &o in &t[1..] {
                let (a, b) = (root(&mut parent, t[0]), root(&mut parent, o));
                if a != b {
                    parent[a.max(b) as usize] = a.min(b);
                }
            }
        }
        let mut triangles_of_root = vec![0usize; n];
        for t in &self.triangles {
            triangles_of_root[root(&mut parent, t[0]) as usize] += 1;
        }
        let mut roots: Vec<(usize, u32)> = (0..n as u32)
            .filter(|&r| triangles_of_root[r as usize] > 0)
            .map(|r| (triangles_of_root[r as usize], r))
            .collect();
        roots.sort_unstable_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)));
        let mut label = vec![u32::MAX; n];
        for (i, &(_, r)) in roots.iter().enumerate() {
            label[r as usize] = i as u32;
        }
        let labels = (0..n as u32)
            .map(|v| label[root(&mut parent, v) as usize])
            .collect();
        (labels, roots.iter().map(|&(c, _)| c).collect())
    }

    /// Connected pieces as a person sees them: [`TriMesh::components`] after merging vertices
    /// at exactly the same position (files that split vertices by normal or texture
    /// coordinate, as OBJ exporters do, would otherwise count every face apart).
    pub fn pieces(&self) -> usize {
        let remap = self.welded_ids();
        let welded = TriMesh {
            vertices: self.vertices.clone(),
            normals: Vec::new(),
            triangles: self
                .triangles
                .iter()
                .map(|t| t.map(|v| remap[v as usize]))
                .collect(),
        };
        welded.components().1.len()
    }

    /// Edges that one triangle alone uses, after merging vertices at exactly the same position
    /// (as [`TriMesh::pieces`]): the rims of holes and of open surfaces; 0 for a closed
    /// surface. A part thinner than the cells it was meshed on shows here.
    pub fn open_edges(&self) -> usize {
        let id = &self.welded_ids();
        // Every triangle's three edges as sorted (welded) vertex pairs packed into one key,
        // sorted: an open edge is a key that occurs once. (Sorting beats hashing here: a
        // mesh at resolution 200 has ~10⁵ triangles.)
        let mut edges: Vec<u64> = self
            .triangles
            .iter()
            .flat_map(|t| {
                (0..3).map(move |k| {
                    let (a, b) = (id[t[k] as usize], id[t[(k + 1) % 3] as usize]);
                    (u64::from(a.min(b)) << 32) | u64::from(a.max(b))
                })
            })
            .collect();
        edges.sort_unstable();
        edges
            .chunk_by(|a, b| a == b)
            .filter(|run| run.len() == 1)
            .count()
    }

    /// Each vertex's id after merging vertices at exactly the same position: the first of them.
    fn welded_ids(&self) -> Vec<u32> {
        // Vertex indices sorted by position (bit for bit), ties by index: each run of one
        // position starts at its first vertex.
        let bits = |i: u32| self.vertices[i as usize].to_array().map(f64::to_bits);
        let mut order: Vec<u32> = (0..self.vertices.len() as u32).collect();
        order.sort_unstable_by_key(|&i| (bits(i), i));
        let mut id = vec![0u32; self.vertices.len()];
        for run in order.chunk_by(|&a, &b| bits(a) == bits(b)) {
            for &i in run {
                id[i as usize] = run[0];
            }
        }
        id
    }

    /// The vertices some triangle uses, each once (a file's stray vertices left out).
    pub fn used_vertices(&self) -> Vec<DVec3> {
        let mut used = vec![false; self.vertices.len()];
        for &i in self.triangles.iter().flatten() {
            used[i as usize] = true;
        }
        self.vertices
            .iter()
            .zip(used)
            .filter_map(|(&v, u)| u.then_some(v))
            .collect()
    }

    /// Total triangle area.
    pub fn area(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.vertices[i as usize]);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }
}

/// The grid [`extract_zero_set`] meshes on: covering `bounds` with `resolution` cells (clamped
/// to 8..=2048) along the longest side.
pub fn mesh_grid(bounds: (DVec3, DVec3), resolution: usize) -> GridSpec {
    let (lo, hi) = bounds;
    let extent = (hi - lo).max(DVec3::splat(1e-300));
    let h = extent.max_element() / resolution.clamp(8, 2048) as f64;
    let dims = ((extent / h).ceil().as_uvec3() + glam::UVec3::ONE).max(glam::UVec3::splat(2));
    GridSpec {
        origin: lo,
        spacing: h,
        dims: [dims.x as usize, dims.y as usize, dims.z as usize],
    }
}

/// Extract the trusted zero set of `field` inside `bounds` on a grid whose longest side has
/// `resolution` cells (clamped to 8..=2048), following it from the points. Runs on all cores.
pub fn extract_zero_set(field: &GlobalField, bounds: (DVec3, DVec3), resolution: usize) -> TriMesh {
    extract_zero_set_with_stats(field, bounds, resolution).0
}

/// [`extract_zero_set`] evaluating the field at every node of the box and scanning every cell
/// (the reference the walk is tested against; O(resolution³)).
pub fn extract_zero_set_dense(
    field: &GlobalField,
    bounds: (DVec3, DVec3),
    resolution: usize,
) -> TriMesh {
    let spec = mesh_grid(bounds, resolution);
    let options = MeshOptions::default();
    extract_blocks(field, &spec, &all_blocks(&spec), None, None, &options).0
}

/// Block keys in [`all_blocks`]' order (z slowest), so a followed mesh numbers its vertices as
/// the dense one does.
fn in_grid_order(mut keys: Vec<BlockKey>) -> Vec<BlockKey> {
    keys.sort_unstable_by_key(|b| [b[2], b[1], b[0]]);
    keys
}

/// Where a meshing run's time went, s. The parallel phases are summed over the worker
/// threads (processor time), so they add up to about `threads × wall` of their part.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct MeshTimings {
    /// Whole run, wall clock.
    pub wall_s: f64,
    /// Walking the zero set from the points' cells, wall clock (its evaluations are
    /// `sample_s`; 0 for dense meshing).
    pub follow_s: f64,
    /// Gathering each block's supporting points (parallel).
    pub gather_s: f64,
    /// Evaluating the field at grid nodes (parallel).
    pub sample_s: f64,
    /// Scanning cells for sign changes and placing first guesses (parallel).
    pub cells_s: f64,
    /// Trust tests of the first guesses (parallel).
    pub trust_s: f64,
    /// Newton projections of the trusted guesses onto the zero set (parallel).
    pub project_s: f64,
    /// Joining the blocks' vertices into quads (one thread). Vertex normals come from the
    /// gradient the projection ended with, at no extra cost.
    pub stitch_s: f64,
}

/// What a meshing run evaluated.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct MeshStats {
    /// Grid-node field evaluations: the corners of the cells the walk visited, each once (dense
    /// meshing: every node of every block, a node on a shared block face once per block).
    pub evaluations: usize,
    /// Nodes of the whole grid: what dense meshing evaluates.
    pub box_nodes: usize,
    /// Blocks meshed: those the walk reached (every block for dense meshing).
    pub blocks_near: usize,
    /// Of those, blocks that hold part of the mesh.
    pub blocks_meshed: usize,
    /// Cells the walk along the zero set visited (0 for dense meshing).
    pub cells_visited: usize,
    /// Cells with a sign change whose vertex was trusted, projected.
    pub projections: usize,
    /// Newton steps those projections took in all.
    pub newton_steps: usize,
    /// Projected vertices left out because the zero set where they landed faces against the
    /// points vouching for it ([`FitParams::trust_facing`](crate::FitParams::trust_facing)).
    pub inverted: usize,
    /// Vertices moved from the blend's rounded crease onto the wedge of its faces' planes.
    pub sharpened: usize,
    /// Where the time went.
    pub timings: MeshTimings,
}

/// Choices for [`extract_zero_set_with`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MeshOptions {
    /// Move vertices near a sharp crease of two faces onto the faces' planes and the crease
    /// line, where the points there are explained by such a wedge (`features.rs`; for CAD
    /// data: it sharpens a rounding smaller than the sampling spacing too).
    pub creases: bool,
    /// Leave each vertex at the mean of its cell's edge crossings, as plain surface nets does,
    /// instead of projecting it onto the zero set (to measure what the projection gains).
    pub unprojected: bool,
}

/// [`extract_zero_set`], also saying what it evaluated.
pub fn extract_zero_set_with_stats(
    field: &GlobalField,
    bounds: (DVec3, DVec3),
    resolution: usize,
) -> (TriMesh, MeshStats) {
    extract_zero_set_with(field, bounds, resolution, &MeshOptions::default())
}

/// [`extract_zero_set_with_stats`] with `options`.
pub fn extract_zero_set_with(
    field: &GlobalField,
    bounds: (DVec3, DVec3),
    resolution: usize,
    options: &MeshOptions,
) -> (TriMesh, MeshStats) {
    let started = Instant::now();
    let spec = mesh_grid(bounds, resolution);
    let followed = follow::follow(field, &spec);
    let follow_s = started.elapsed().as_secs_f64();
    let blocks = in_grid_order(followed.values.keys().copied().collect());
    let (mesh, mut stats) = extract_blocks(
        field,
        &spec,
        &blocks,
        Some(&followed.values),
        Some(&followed.crossed),
        options,
    );
    stats.evaluations = followed.evaluations;
    stats.cells_visited = followed.cells;
    stats.timings.sample_s = followed.eval_ns as f64 * 1e-9;
    stats.timings.trust_s += followed.trust_ns as f64 * 1e-9;
    stats.timings.follow_s = follow_s;
    stats.timings.wall_s = started.elapsed().as_secs_f64();
    (mesh, stats)
}

/// One evaluated block: node values and the vertex (if any) of each of its cells.
struct MeshBlock {
    key: BlockKey,
    values: Vec<f64>,
    /// Local cell index → vertex position and the field's gradient there.
    vertices: Vec<(u32, DVec3, DVec3)>,
    /// Field evaluations made for it.
    evaluations: usize,
    /// Projections and Newton steps made for it.
    projections: usize,
    newton_steps: usize,
    /// Projected vertices left out as facing against their points.
    inverted: usize,
    /// Vertices moved onto a crease's wedge: local cell, where they were and their gradient.
    sharpened: Vec<(u32, DVec3, DVec3)>,
    /// Processor time of its phases, ns: gather, sample, cells, trust, project.
    ns: [u64; 5],
}

/// Groups per axis of a block: its cells in groups of 2×2×2 share one narrowed support list.
const GROUPS: usize = BLOCK.div_ceil(2);

/// Mesh `blocks`, with their node values `given` (NaN where not evaluated; from the walk) or
/// else evaluated at every node; with `crossed` (the walk's trusted crossed cells) vertices go
/// only there, else in every cell with a sign change whose vertex is trusted ([`cell_facing`]).
fn extract_blocks(
    field: &GlobalField,
    spec: &GridSpec,
    blocks: &[BlockKey],
    given: Option<&HashMap<BlockKey, Vec<f64>>>,
    crossed: Option<&HashMap<BlockKey, Vec<(u32, Verdict)>>>,
    options: &MeshOptions,
) -> (TriMesh, MeshStats) {
    let started = Instant::now();
    let h = spec.spacing;
    let opts = ProjectOptions {
        tolerance: VERTEX_TOLERANCE,
        ..ProjectOptions::default()
    };
    let evaluated: Vec<MeshBlock> = blocks
        .par_iter()
        .map_init(
            || {
                let groups = vec![SupportList::new(); GROUPS * GROUPS * GROUPS];
                (SupportList::new(), groups)
            },
            |(supports, groups), &key| {
                let mut ready = [false; GROUPS * GROUPS * GROUPS];
                let t0 = Instant::now();
                gather_block(field, spec, key, supports);
                let t1 = Instant::now();
                let (values, evaluations) = match given {
                    Some(given) => (given[&key].clone(), 0),
                    None => {
                        let mut values = Vec::new();
                        sample_block(field, spec, key, supports, |_, f| f, &mut values);
                        let n = values.len();
                        (values, n)
                    }
                };
                let t2 = Instant::now();
                let (first, count) = block_nodes(spec, key);
                let block_box = block_box(spec, key);
                let at = |i: usize, j: usize, k: usize| values[(k * count[1] + j) * count[0] + i];
                let mut vertices = Vec::new();
                let (mut trust_ns, mut project_ns, mut projections, mut newton_steps) =
                    (0, 0, 0, 0);
                let mut inverted = 0;
                let mut sharpened = Vec::new();
                let creases = options.creases;
                let mut place = |i: usize, j: usize, k: usize, known: Option<Verdict>| {
                    let mut corner = [0.0; 8];
                    for (c, v) in corner.iter_mut().enumerate() {
                        *v = at(i + (c & 1), j + ((c >> 1) & 1), k + (c >> 2));
                    }
                    if corner.iter().any(|f| f.is_nan()) {
                        return; // pruned: no sign change here
                    }
                    let Some(offset) = follow::first_guess(&corner) else {
                        return;
                    };
                    let cell_lo = spec.node_position(first[0] + i, first[1] + j, first[2] + k);
                    let guess = cell_lo + offset * h;
                    let ta = Instant::now();
                    // The cell's group of 2×2×2 and a cell around it: where the guess and,
                    // nearly always, the projection's iterates lie (outside it they use the
                    // index). Kept inside the block, the box `supports` was gathered for. The
                    // group's cells share its narrowed list (narrowing costs a pass over the
                    // block's).
                    let g = [i / 2, j / 2, k / 2];
                    let group_lo = spec.node_position(
                        first[0] + 2 * g[0],
                        first[1] + 2 * g[1],
                        first[2] + 2 * g[2],
                    );
                    let reach = (
                        (group_lo - DVec3::splat(h)).max(block_box.0),
                        (group_lo + DVec3::splat(3.0 * h)).min(block_box.1),
                    );
                    let slot = (g[2] * GROUPS + g[1]) * GROUPS + g[0];
                    let near_cell = &mut groups[slot];
                    if !ready[slot] {
                        supports.narrow_to(reach.0, reach.1, near_cell);
                        ready[slot] = true;
                    }
                    let near_cell = &*near_cell;
                    let verdict = known
                        .or_else(|| cell_facing(field, guess, (cell_lo, h), near_cell, reach))
                        .filter(|v| {
                            field.faces_its_points(follow::corner_gradient(&corner), v.facing)
                        });
                    let tb = Instant::now();
                    trust_ns += nanos(tb - ta);
                    let Some(Verdict { facing, at_guess }) = verdict else {
                        return;
                    };
                    let local = ((k * BLOCK + j) * BLOCK + i) as u32;
                    let projected = (!options.unprojected).then(|| {
                        let pr = project_to_zero_set_near_from(
                            field, guess, &opts, near_cell, reach, at_guess,
                        );
                        project_ns += nanos(tb.elapsed());
                        projections += 1;
                        newton_steps += pr.iterations as usize;
                        pr
                    });
                    let (mut p, mut gradient) = match projected {
                        Some(pr)
                            if pr.converged
                                && (pr.point - guess).length() < 2.0 * h
                                && pr.trusted =>
                        {
                            (pr.point, pr.gradient)
                        }
                        _ => (guess, field.value_and_gradient(guess).1),
                    };
                    if creases && p.cmpge(reach.0).all() && p.cmple(reach.1).all() {
                        let box_ = (cell_lo, cell_lo + DVec3::splat(h));
                        if let Some((x, n)) = features::sharpen(field, p, gradient, box_, near_cell)
                        {
                            sharpened.push((local, p, gradient));
                            (p, gradient) = (x, n * gradient.length());
                        }
                    }
                    // Where the vertex lies, the zero set must face its points too: the corner
                    // values of a cell a tiny inverted bubble crosses can still grow outward.
                    if field.faces_its_points(gradient, facing) {
                        vertices.push((local, p, gradient));
                    } else {
                        inverted += 1;
                    }
                };
                match crossed {
                    // The walk's cells, in the scan's order, their trust already tested.
                    Some(crossed) => {
                        for &(local, verdict) in crossed.get(&key).map_or(&[][..], Vec::as_slice) {
                            let l = local as usize;
                            let (i, j, k) = (l % BLOCK, (l / BLOCK) % BLOCK, l / (BLOCK * BLOCK));
                            place(i, j, k, Some(verdict));
                        }
                    }
                    None => {
                        for k in 0..count[2] - 1 {
                            for j in 0..count[1] - 1 {
                                for i in 0..count[0] - 1 {
                                    place(i, j, k, None);
                                }
                            }
                        }
                    }
                }
                let cells_ns = nanos(t2.elapsed()).saturating_sub(trust_ns + project_ns);
                MeshBlock {
                    key,
                    values,
                    vertices,
                    evaluations,
                    projections,
                    newton_steps,
                    inverted,
                    sharpened,
                    ns: [
                        nanos(t1 - t0),
                        nanos(t2 - t1),
                        cells_ns,
                        trust_ns,
                        project_ns,
                    ],
                }
            },
        )
        .collect();
    let stitch_started = Instant::now();
    let mut stats = MeshStats {
        evaluations: evaluated.iter().map(|b| b.evaluations).sum(),
        box_nodes: spec.node_count(),
        blocks_near: blocks.len(),
        blocks_meshed: evaluated.iter().filter(|b| !b.vertices.is_empty()).count(),
        cells_visited: 0,
        projections: evaluated.iter().map(|b| b.projections).sum(),
        newton_steps: evaluated.iter().map(|b| b.newton_steps).sum(),
        inverted: evaluated.iter().map(|b| b.inverted).sum(),
        sharpened: 0,
        timings: MeshTimings::default(),
    };
    let phase_s = |i: usize| evaluated.iter().map(|b| b.ns[i]).sum::<u64>() as f64 * 1e-9;
    let t = &mut stats.timings;
    (t.gather_s, t.sample_s, t.cells_s, t.trust_s, t.project_s) =
        (phase_s(0), phase_s(1), phase_s(2), phase_s(3), phase_s(4));

    // Vertex ids run block by block in the blocks' order: each block's first id is the count
    // before it, so the blocks number their vertices and cells in parallel, and then emit the
    // quads of the edges they own in parallel; both are concatenated in block order (the same
    // mesh as one pass would make).
    let mut first_id = Vec::with_capacity(evaluated.len() + 1);
    first_id.push(0u32);
    for b in &evaluated {
        first_id.push(first_id[first_id.len() - 1] + b.vertices.len() as u32);
    }
    let mut mesh = TriMesh {
        vertices: evaluated
            .iter()
            .flat_map(|b| b.vertices.iter().map(|v| v.1))
            .collect(),
        normals: evaluated
            .iter()
            .flat_map(|b| b.vertices.iter())
            .map(|v| v.2.try_normalize().unwrap_or(DVec3::Z))
            .collect(),
        ..TriMesh::default()
    };
    // Vertex ids per block and local cell (u32::MAX: no vertex).
    let ids: Vec<Vec<u32>> = evaluated
        .par_iter()
        .zip(&first_id)
        .map(|(b, &first)| {
            let mut cell_ids = vec![u32::MAX; BLOCK * BLOCK * BLOCK];
            for (id, &(local, _, _)) in (first..).zip(&b.vertices) {
                cell_ids[local as usize] = id;
            }
            cell_ids
        })
        .collect();
    // Sharpened vertices: id, and where they were before with their normal.
    let sharpened: Vec<(u32, DVec3, DVec3)> = evaluated
        .iter()
        .zip(&ids)
        .flat_map(|(b, cell_ids)| {
            b.sharpened.iter().filter_map(|&(local, p, gradient)| {
                let id = cell_ids[local as usize];
                (id != u32::MAX).then(|| (id, p, gradient.try_normalize().unwrap_or(DVec3::Z)))
            })
        })
        .collect();
    let bdims = block_dims(spec);
    let block_key = |b: BlockKey| block_index(bdims, b) as u64;
    let slot: HashMap<u64, usize, Fast> = evaluated
        .iter()
        .enumerate()
        .map(|(s, b)| (block_key(b.key), s))
        .collect();
    let [cx, cy, cz] = spec.dims.map(|n| n - 1);
    let cell = |i: usize, j: usize, k: usize| -> u32 {
        let b = [i / BLOCK, j / BLOCK, k / BLOCK];
        match slot.get(&block_key(b)) {
            Some(&s) => ids[s][((k % BLOCK) * BLOCK + j % BLOCK) * BLOCK + i % BLOCK],
            None => u32::MAX,
        }
    };
    let quads: Vec<Vec<[u32; 3]>> = evaluated
        .par_iter()
        .map(|b| {
            let mut triangles = Vec::new();
            let (first, count) = block_nodes(spec, b.key);
            let at = |i: usize, j: usize, k: usize| b.values[(k * count[1] + j) * count[0] + i];
            // The block owns the edges starting at its nodes 0..BLOCK on each axis.
            for lk in 0..count[2].min(BLOCK) {
                for lj in 0..count[1].min(BLOCK) {
                    for li in 0..count[0].min(BLOCK) {
                        let (i, j, k) = (first[0] + li, first[1] + lj, first[2] + lk);
                        let f0 = at(li, lj, lk);
                        // Edges along +x, +y, +z from this node, with the four cells around
                        // each, listed counter-clockwise about the edge direction.
                        for axis in 0..3 {
                            let (f1, quad) = match axis {
                                0 if li + 1 < count[0] && j > 0 && k > 0 => (
                                    at(li + 1, lj, lk),
                                    [(i, j - 1, k - 1), (i, j, k - 1), (i, j, k), (i, j - 1, k)],
                                ),
                                1 if lj + 1 < count[1] && i > 0 && k > 0 => (
                                    at(li, lj + 1, lk),
                                    [(i - 1, j, k - 1), (i - 1, j, k), (i, j, k), (i, j, k - 1)],
                                ),
                                2 if lk + 1 < count[2] && i > 0 && j > 0 => (
                                    at(li, lj, lk + 1),
                                    [(i - 1, j - 1, k), (i, j - 1, k), (i, j, k), (i - 1, j, k)],
                                ),
                                _ => continue,
                            };
                            if f0.is_nan() || f1.is_nan() || (f0 < 0.0) == (f1 < 0.0) {
                                continue;
                            }
                            if quad.iter().any(|&(a, b, c)| a >= cx || b >= cy || c >= cz) {
                                continue;
                            }
                            let v = quad.map(|(a, b, c)| cell(a, b, c));
                            if v.contains(&u32::MAX) {
                                continue;
                            }
                            // Inside → outside along +axis: the quad's normal (+axis) is outward.
                            let mut tris = if f0 < 0.0 {
                                [[v[0], v[1], v[2]], [v[0], v[2], v[3]]]
                            } else {
                                [[v[0], v[2], v[1]], [v[0], v[3], v[2]]]
                            };
                            let q = if f0 < 0.0 {
                                v
                            } else {
                                [v[0], v[3], v[2], v[1]]
                            };
                            if options.creases && !split_along_02(&mesh, q) {
                                tris = [[q[1], q[2], q[3]], [q[1], q[3], q[0]]];
                            }
                            triangles.extend(tris);
                        }
                    }
                }
            }
            triangles
        })
        .collect();
    mesh.triangles = quads.concat();
    stats.sharpened = sharpened.len() - features::unfold(&mut mesh, &sharpened);
    stats.timings.stitch_s = stitch_started.elapsed().as_secs_f64();
    stats.timings.wall_s = started.elapsed().as_secs_f64();
    (mesh, stats)
}

/// Whether the quad `v` (counter-clockwise from outside) is better split along its diagonal
/// 0–2 than 1–3: the split whose worse triangle agrees more with its corners' normals (the
/// zero set's gradients). Used with [`MeshOptions::creases`]: where vertices sit on a crease
/// line, the other diagonal would cut across it. (Always on, it helps smooth shapes, the torus
/// at resolution 200 RMS 1.05e-5 → 8.6e-6, and costs creased ones their max, the CSG crease
/// 5.3e-3 → 6.2e-3, so the default keeps the fixed split.)
fn split_along_02(mesh: &TriMesh, v: [u32; 4]) -> bool {
    let agreement = |t: [u32; 3]| {
        let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
        let n = t.iter().map(|&i| mesh.normals[i as usize]).sum::<DVec3>();
        (b - a)
            .cross(c - a)
            .normalize_or_zero()
            .dot(n.normalize_or_zero())
    };
    let along_02 = agreement([v[0], v[1], v[2]]).min(agreement([v[0], v[2], v[3]]));
    let along_13 = agreement([v[1], v[2], v[3]]).min(agreement([v[1], v[3], v[0]]));
    along_02 >= along_13
}

/// Hash maps keyed by grid or block coordinates packed into one integer (a multiplicative
/// hash).
type Fast = BuildHasherDefault<MulHasher>;

fn nanos(d: std::time::Duration) -> u64 {
    d.as_nanos() as u64
}

/// A vertex's Newton projection stops where `|f|` is below this many of the field's length
/// scale (its median support radius, some five cells at the usual resolutions): a millionth,
/// a hundred times below the finest mesh error measured (the torus's 1e-5 of its size), where
/// the default's 1e-10 took a second Newton step on most vertices for nothing (the same error
/// to three digits on every bench shape; airplane 2.0 → 1.3 steps per vertex).
const VERTEX_TOLERANCE: f64 = 1e-6;

/// How far outside its cell, in cells, the projection of an untrusted first guess may land
/// and still vouch for the cell ([`cell_facing`]). Within 0.01, 119 open edges were left on
/// the armadillo at resolution 100 and 256 on a tube 1.8 cells across (the test's); at 0.5,
/// none. At two cells the projection reached the real surface from the cells of a small
/// bubble beside it: two pieces of four and six triangles on cheburashka.
const PROJECTED_SLACK: f64 = 0.5;

/// Whether a crossed cell is trusted, judged where its vertex goes, and the facing of the
/// points vouching for it ([`GlobalField::trusted_facing_near`]): at the surface-nets first
/// `guess` (the mean of the cell's edge crossings), or, where that is not trusted, at the
/// guess projected onto the zero set, if the projection lands in or near the cell
/// ([`PROJECTED_SLACK`]), where vertex placement then puts the vertex (it takes a trusted
/// projection within two cells of the guess). On a grid coarse for the part, the crossings'
/// mean lies off the surface: between the sheets of a part about a cell thick, inside the
/// bend of a tube two or three cells across, off every vouching point's plane. Judged there
/// alone, such cells were left out: a tube three cells across had a thousand open edges, one
/// under two cells across no triangle at all, and the armadillo at resolution 100 had 513
/// open edges and six pieces of two to four triangles (test
/// `parts_two_to_three_cells_thick_mesh_whole_on_a_coarse_grid`). The projection's own trust
/// test still keeps a spurious sheet out. `cell_lo` and `h` are the cell's first corner and
/// edge; `supports` is a list gathered for `bounds` (outside it the field's index answers).
fn cell_facing(
    field: &GlobalField,
    guess: DVec3,
    (cell_lo, h): (DVec3, f64),
    supports: &SupportList,
    bounds: (DVec3, DVec3),
) -> Option<Verdict> {
    let inside = |p: DVec3| p.cmpge(bounds.0).all() && p.cmple(bounds.1).all();
    let facing_at = |p: DVec3| {
        if inside(p) {
            field.trusted_facing_near(p, supports)
        } else {
            field.trusted_facing(p)
        }
    };
    if let Some(facing) = facing_at(guess) {
        return Some(Verdict {
            facing,
            at_guess: true,
        });
    }
    {
        let opts = ProjectOptions {
            tolerance: VERTEX_TOLERANCE,
            ..ProjectOptions::default()
        };
        let pr = project_to_zero_set_near(field, guess, &opts, supports, bounds);
        let slack = DVec3::splat(PROJECTED_SLACK * h);
        let near_cell = pr.point.cmpge(cell_lo - slack).all()
            && pr.point.cmple(cell_lo + DVec3::splat(h) + slack).all();
        (pr.converged && pr.trusted && near_cell)
            .then(|| facing_at(pr.point))
            .flatten()
            .map(|facing| Verdict {
                facing,
                at_guess: false,
            })
    }
}

/// A crossed cell's trust verdict ([`cell_facing`]): the facing of the points vouching for it,
/// and whether the field is trusted at the cell's first guess itself (so a vertex that stays
/// there needs no second test).
#[derive(Debug, Clone, Copy)]
pub(super) struct Verdict {
    pub facing: DVec3,
    pub at_guess: bool,
}

const CUBE_EDGES: [(usize, usize); 12] = [
    (0, 1),
    (2, 3),
    (4, 5),
    (6, 7),
    (0, 2),
    (1, 3),
    (4, 6),
    (5, 7),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];

fn corner_offset(c: usize) -> DVec3 {
    DVec3::new((c & 1) as f64, ((c >> 1) & 1) as f64, (c >> 2) as f64)
}

/// The point of triangle `abc` closest to `p` (Ericson, Real-Time Collision Detection §5.1.5).
/// A degenerate triangle (collinear or coincident corners, which other tools' meshes contain)
/// is measured as its three edges.
pub fn closest_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let q = closest_on_proper_triangle(p, a, b, c);
    if q.is_finite() && (b - a).cross(c - a).length_squared() > 0.0 {
        return q;
    }
    [(a, b), (b, c), (c, a)]
        .map(|(u, v)| closest_on_segment(p, u, v))
        .into_iter()
        .min_by(|x, y| {
            (*x - p)
                .length_squared()
                .total_cmp(&(*y - p).length_squared())
        })
        .unwrap_or(a)
}

fn closest_on_segment(p: DVec3, a: DVec3, b: DVec3) -> DVec3 {
    let ab = b - a;
    let len2 = ab.length_squared();
    if len2.is_nan() || len2 <= 0.0 {
        return a;
    }
    a + ab * ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
}

fn closest_on_proper_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = va + vb + vc;
    if denom.abs() < f64::MIN_POSITIVE || !denom.is_finite() {
        return a; // degenerate triangle
    }
    let (v, w) = (vb / denom, vc / denom);
    a + ab * v + ac * w
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn components_count_pieces_largest_first_and_skip_unused_vertices() {
        let v = |x: f64| DVec3::new(x, 0.0, 0.0);
        let mesh = TriMesh {
            // Two triangles sharing vertex 1, a lone triangle, and an unused vertex 7.
            vertices: (0..8).map(|i| v(i as f64)).collect(),
            normals: Vec::new(),
            triangles: vec![[4, 5, 6], [0, 1, 2], [1, 3, 2]],
        };
        let (labels, sizes) = mesh.components();
        assert_eq!(sizes, vec![2, 1]);
        assert_eq!(labels, vec![0, 0, 0, 0, 1, 1, 1, u32::MAX]);
        assert_eq!(mesh.pieces(), 2);
        // The lone triangle's corner 4 duplicated at vertex 0's position: one piece.
        let mut split = mesh.clone();
        split.vertices[4] = split.vertices[0];
        assert_eq!(split.components().1.len(), 2);
        assert_eq!(split.pieces(), 1);
    }

    #[test]
    fn open_edges_count_the_rims_of_holes_after_welding() {
        let tetrahedron = TriMesh {
            vertices: vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z],
            normals: Vec::new(),
            triangles: vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
        };
        assert_eq!(tetrahedron.open_edges(), 0);
        // One face gone: its three edges are a hole's rim.
        let mut open = tetrahedron.clone();
        open.triangles.pop();
        assert_eq!(open.open_edges(), 3);
        // A face with its own copies of its corners (as a file may split them) still closes.
        let mut split = tetrahedron.clone();
        split.vertices.extend([DVec3::ZERO, DVec3::Z, DVec3::Y]);
        split.triangles[3] = [4, 5, 6];
        assert_eq!(split.open_edges(), 0);
        assert_eq!(split.components().1.len(), 2);
    }
}
