//! The rendering thread: the newest [`RenderSnapshot`] and the newest cursor, force and contact
//! → one PNG frame every interval, with the `render` crate's EWA surface splatting
//! ([`HeadlessRenderer`]: a GPU through wgpu, or the same passes on the CPU where the only
//! Vulkan driver is a software one, or none is installed). The window draws with the same
//! splats and overlays.
//!
//! Points become elliptical surface splats in the plane of their normals, sized and stretched by
//! their 12 nearest neighbours on their own side of a thin part (`render::splat_shape`;
//! recomputed only for the points that moved, turned, appeared or disappeared and their
//! neighbours: [`SplatCache`]), in their colours;
//! overlays: the probe (when the probe is the tool), the haptic cursor, the sculpting region
//! box and the contact force arrow.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use glam::DVec3;
use render::{BackendChoice, Camera, Ellipsoid, HeadlessRenderer, Image, Overlay, Splat};

use super::neighbours::{Edits, NeighbourCache, NeighbourShape, shapes_and_reach};
use super::points::ChunkedPoints;
use super::scene_file::{RenderSpec, ToolKind};
use super::shared::{RenderSnapshot, Shared};

/// Length of the drawn force arrow per newton (m/N).
pub const ARROW_M_PER_N: f64 = 0.05;

/// Splat shapes of `positions` with `normals` from scratch (every point's [`NeighbourShape`],
/// k-d tree, no index kept): what [`SplatUpdate::Full`] recomputes whenever anything moved.
pub fn splat_shapes(positions: &[DVec3], normals: &[DVec3]) -> Vec<NeighbourShape> {
    shapes_and_reach(positions, normals).0
}

/// How a [`SplatCache`] keeps the radii up to date.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum SplatUpdate {
    /// Recompute only moved, added and removed points and the points whose neighbourhood
    /// they entered or left ([`NeighbourCache`]).
    #[default]
    Incremental,
    /// The old way, kept to measure against: when any point changed, recompute every shape
    /// ([`splat_shapes`]) and rewrite every splat.
    Full,
}

/// What one [`SplatCache::update`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SplatWork {
    /// Points whose position changed (moved, added; removed ones are not counted).
    pub moved: usize,
    /// Radii recomputed.
    pub recomputed: usize,
    /// Splats rewritten.
    pub rewritten: usize,
}

/// Splats of a snapshot, kept from frame to frame and rewritten only where points changed
/// (shared by the PNG frames and the window). Changed points are found by chunk: a chunk the
/// cache saw before (same id, same place) is skipped, the others are compared point by point
/// with the cache's copy; radii come from a [`NeighbourCache`], the one place neighbour-derived
/// data lives. Cost per snapshot: O(chunks + points of changed chunks + recomputed points · k);
/// the k-d tree is only built on a full rebuild (first snapshot, or a quarter of the points
/// changed).
#[derive(Debug, Default)]
pub struct SplatCache {
    mode: SplatUpdate,
    /// `(first point, chunk id)` of the chunks of the last snapshot.
    seen: Vec<(usize, u64)>,
    neighbours: NeighbourCache,
    /// [`SplatUpdate::Full`]: the shapes of the last full recompute.
    full_shapes: Vec<NeighbourShape>,
    splats: Vec<Splat>,
    edits: Edits,
    recolored: Vec<u32>,
    starts: Vec<usize>,
    last: SplatWork,
}

impl SplatCache {
    /// An empty cache updating by `mode`.
    pub fn new(mode: SplatUpdate) -> Self {
        Self {
            mode,
            ..Self::default()
        }
    }

    /// The splats of `snap` (the buffer is reused from frame to frame).
    pub fn splats(&mut self, snap: &RenderSnapshot) -> &[Splat] {
        self.update(&snap.points);
        &self.splats
    }

    /// No update yet, or no points.
    pub fn is_empty(&self) -> bool {
        self.splats.is_empty()
    }

    /// The splats of the last update.
    pub fn current(&self) -> &[Splat] {
        &self.splats
    }

    /// What the last update did.
    pub fn last_work(&self) -> SplatWork {
        self.last
    }

    /// The neighbour cache (radii and the positions they are for).
    pub fn neighbours(&self) -> &NeighbourCache {
        &self.neighbours
    }

    /// Bring the splats up to date with `points`.
    pub fn update(&mut self, points: &ChunkedPoints) -> SplatWork {
        self.starts.clear();
        let mut start = 0;
        for c in points.chunks() {
            self.starts.push(start);
            start += c.len();
        }
        if self.mode == SplatUpdate::Full {
            return self.update_full(points);
        }
        let old = self.neighbours.positions().len();
        let first = self.neighbours.rebuilds() == 0;
        self.edits.set.clear();
        self.edits.len = points.len();
        self.recolored.clear();
        for (j, c) in points.chunks().iter().enumerate() {
            let s = self.starts[j];
            if !first && self.seen.get(j) == Some(&(s, c.id)) {
                continue;
            }
            let (pos, normals) = (self.neighbours.positions(), self.neighbours.normals());
            for (k, p) in c.positions.iter().enumerate() {
                let i = s + k;
                if i >= old || pos[i] != *p || normals[i] != c.normals[k] {
                    self.edits.set.push((i as u32, *p, c.normals[k]));
                } else {
                    let want = splat(*p, c.normals[k], c.colors[k], &self.neighbours.shapes()[i]);
                    if want != self.splats[i] {
                        self.recolored.push(i as u32);
                    }
                }
            }
        }
        self.seen.clear();
        self.seen.extend(
            points
                .chunks()
                .iter()
                .zip(&self.starts)
                .map(|(c, &s)| (s, c.id)),
        );
        if !first && self.edits.set.is_empty() && self.recolored.is_empty() && old == points.len() {
            self.last = SplatWork::default();
            return self.last;
        }
        self.neighbours.update(&self.edits);
        self.splats.resize(points.len(), Splat::default());
        let (affected, shapes) = (self.neighbours.affected(), self.neighbours.shapes());
        let mut rewritten = 0;
        for &i in affected.iter().chain(&self.recolored) {
            let i = i as usize;
            let j = self.starts.partition_point(|&s| s <= i) - 1;
            let (c, k) = (&points.chunks()[j], i - self.starts[j]);
            self.splats[i] = splat(c.positions[k], c.normals[k], c.colors[k], &shapes[i]);
            rewritten += 1;
        }
        self.last = SplatWork {
            moved: self.edits.set.len(),
            recomputed: affected.len(),
            rewritten,
        };
        self.last
    }

    /// A thinned stand-in for `points` without updating the cache ([`render::thin_splats`]'s
    /// stride and growth): every k-th point where it is now, with the splat shape the cache
    /// last computed for its index (the last one for points past the cache's end). O(budget):
    /// for frames drawn while a stroke moves tens of thousands of points, whose shapes the
    /// next [`SplatCache::update`] brings up to date once the surface holds still. Returns k.
    pub fn preview(&self, points: &ChunkedPoints, budget: usize, out: &mut Vec<Splat>) -> usize {
        out.clear();
        let shapes = self.neighbours.shapes();
        let Some(last) = shapes.last() else {
            return 1;
        };
        let k = points.len().div_ceil(budget.max(1)).max(1);
        let grow = (k as f32).sqrt() * render::THIN_MARGIN;
        let grow = if k == 1 { 1.0 } else { grow };
        let mut i = 0;
        for c in points.chunks() {
            // The first point of this chunk on the stride.
            let mut at = (k - i % k) % k;
            while at < c.len() {
                let shape = shapes.get(i + at).unwrap_or(last);
                let s = splat(c.positions[at], c.normals[at], c.colors[at], shape);
                out.push(Splat {
                    radius: s.radius * grow,
                    minor_radius: s.minor_radius * grow,
                    ..s
                });
                at += k;
            }
            i += c.len();
        }
        k
    }

    fn update_full(&mut self, points: &ChunkedPoints) -> SplatWork {
        let key = points.key();
        let changed = self.seen.first() != Some(&key);
        let mut work = SplatWork::default();
        if changed {
            let pos: Vec<DVec3> = points.positions().copied().collect();
            let normals: Vec<DVec3> = points.normals().copied().collect();
            self.full_shapes = splat_shapes(&pos, &normals);
            self.seen = vec![key];
            work = SplatWork {
                moved: pos.len(),
                recomputed: pos.len(),
                rewritten: pos.len(),
            };
        } else {
            // The old cache rewrote every splat every frame.
            work.rewritten = self.full_shapes.len();
        }
        self.splats.clear();
        self.splats.extend(
            points
                .chunks()
                .iter()
                .flat_map(|c| (0..c.len()).map(move |k| (c, k)))
                .zip(&self.full_shapes)
                .map(|((c, k), shape)| splat(c.positions[k], c.normals[k], c.colors[k], shape)),
        );
        self.last = work;
        work
    }
}

/// A point's normal further than this (cosine) from the plane its neighbours span is not the
/// surface's there: its splat takes the plane's normal (turned to agree with the point's).
pub const NORMAL_AGREES: f64 = 0.8;

/// The splat of point `p` with normal `n`. A normal that disagrees with the point's neighbours
/// (a sculpted rim's field gradient can be tens of degrees off) would stand the splat out of the
/// surface as a stray disk; there the neighbours' plane orients it ([`NORMAL_AGREES`]).
fn splat(p: DVec3, n: DVec3, c: [u8; 3], shape: &NeighbourShape) -> Splat {
    let plane = DVec3::from(shape.plane_normal.map(f64::from));
    let cos = n.dot(plane);
    let n = if plane.length_squared() > 0.5 && cos.abs() < NORMAL_AGREES * n.length() {
        if cos < 0.0 { -plane } else { plane }
    } else {
        n
    };
    Splat {
        curvature: shape.curvature_along(n),
        cell_growth: shape.cell_growth,
        ..Splat::ellipse(
            p.as_vec3().to_array(),
            n.as_vec3().to_array(),
            shape.axis,
            shape.radius,
            shape.minor_radius,
            [c[0], c[1], c[2], 255],
        )
    }
}

/// The box a view of `snap` should frame: its points and the region (a 0.2 m cube at the
/// origin when it has neither).
pub fn scene_bounds(snap: &RenderSnapshot) -> (DVec3, DVec3) {
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for p in snap.points.positions() {
        (lo, hi) = (lo.min(*p), hi.max(*p));
    }
    if let Some((a, b)) = snap.region {
        (lo, hi) = (lo.min(a), hi.max(b));
    }
    if !lo.is_finite() {
        (lo, hi) = (DVec3::splat(-0.1), DVec3::splat(0.1));
    }
    (lo, hi)
}

/// The overlays of a frame: the probe (when it is the tool), the haptic cursor, the region box
/// and the force arrow, from `snap` and the force thread's last tick.
pub fn overlay(snap: &RenderSnapshot, shared: &Shared) -> Overlay {
    let cursor = shared.haptic.cursor();
    let force = shared.haptic.force();
    let f32x3 = |v: DVec3| v.as_vec3().to_array();
    Overlay {
        probe: match (snap.tool, snap.probe_semi_axes) {
            (Some(ToolKind::ProbePush | ToolKind::ProbePull), Some(a)) if cursor.is_finite() => {
                Some(Ellipsoid {
                    center: f32x3(cursor),
                    rotation: [0.0, 0.0, 0.0, 1.0],
                    semi_axes: f32x3(a),
                })
            }
            _ => None,
        },
        cursor: cursor.is_finite().then(|| f32x3(cursor)),
        contact: shared.haptic.contact().map(f32x3),
        region: snap.region.map(|(a, b)| (f32x3(a), f32x3(b))),
        force: (force.length() > 1e-3 && cursor.is_finite())
            .then(|| (f32x3(cursor), f32x3(force * ARROW_M_PER_N))),
    }
}

/// Turns snapshots into frames; keeps the camera fixed on the first snapshot's framing.
#[derive(Debug)]
pub struct FrameMaker {
    renderer: HeadlessRenderer,
    spec: RenderSpec,
    camera: Option<Camera>,
    splats: SplatCache,
    image: Image,
    /// Time the last frame spent preparing splats and drawing them.
    timings: (Duration, Duration),
    /// Draw at most about this many splats ([`render::thin_splats`]).
    thin_budget: Option<usize>,
    /// The thinned set of the last frame (reused).
    thinned: Vec<Splat>,
}

impl FrameMaker {
    /// A headless renderer of the scene's size on the backend `HAPTIC_RENDER` names
    /// (`auto`, the default: a GPU; the CPU splatter on a software Vulkan driver or without
    /// any, said once with how to get the fast path).
    pub fn new(spec: &RenderSpec) -> anyhow::Result<Self> {
        Self::build(spec, BackendChoice::Auto, SplatUpdate::Incremental)
    }

    /// As [`FrameMaker::new`] on the backend `choice`.
    pub fn with_backend(spec: &RenderSpec, choice: BackendChoice) -> anyhow::Result<Self> {
        Self::build(spec, choice, SplatUpdate::Incremental)
    }

    /// [`FrameMaker::new`], keeping splat radii up to date by `mode`.
    pub fn with_splats(spec: &RenderSpec, mode: SplatUpdate) -> anyhow::Result<Self> {
        Self::build(spec, BackendChoice::Auto, mode)
    }

    fn build(spec: &RenderSpec, choice: BackendChoice, mode: SplatUpdate) -> anyhow::Result<Self> {
        let renderer = HeadlessRenderer::new(spec.width, spec.height, choice)?;
        match renderer.fallback_reason() {
            Some(why) => tracing::warn!("frames are drawn on the CPU: {why}"),
            None => tracing::info!("frames are drawn by {}", renderer.describe()),
        }
        Ok(Self {
            renderer,
            spec: *spec,
            camera: None,
            splats: SplatCache::new(mode),
            image: Image {
                width: 0,
                height: 0,
                rgba: Vec::new(),
            },
            timings: (Duration::ZERO, Duration::ZERO),
            thin_budget: None,
            thinned: Vec::new(),
        })
    }

    /// Draw at most about `budget` splats from now on, a thinned stand-in as the window's CPU
    /// path draws while the picture changes (`None`: every splat, the default).
    pub fn thin_to(&mut self, budget: Option<usize>) {
        self.thin_budget = budget;
    }

    /// Time the last [`FrameMaker::render`] spent bringing the splats up to date, and drawing.
    pub fn timings(&self) -> (Duration, Duration) {
        self.timings
    }

    /// The splat cache.
    pub fn splat_cache(&self) -> &SplatCache {
        &self.splats
    }

    /// Render `snap` with the haptic overlays from `shared`.
    pub fn render(&mut self, snap: &RenderSnapshot, shared: &Shared) -> anyhow::Result<&Image> {
        let camera = *self.camera.get_or_insert_with(|| {
            let (lo, hi) = scene_bounds(snap);
            let d = DVec3::from(self.spec.view_dir).normalize();
            Camera::framing(
                lo.as_vec3().to_array(),
                hi.as_vec3().to_array(),
                d.as_vec3().to_array(),
            )
        });
        let overlay = overlay(snap, shared);
        let t0 = Instant::now();
        let mut splats = self.splats.splats(snap);
        if let Some(budget) = self.thin_budget {
            render::thin_splats(splats, budget, &mut self.thinned);
            splats = &self.thinned;
        }
        let t1 = Instant::now();
        self.renderer
            .render_into(splats, &overlay, &camera, &mut self.image)?;
        self.timings = (t1 - t0, t1.elapsed());
        Ok(&self.image)
    }
}

/// Changes when the points change (count, positions, normals or colours): the snapshot's
/// chunk ids, O(chunks).
pub fn points_key(snap: &RenderSnapshot) -> (usize, u64) {
    snap.points.key()
}

/// Frames written so far, shared with the session.
#[derive(Debug, Default)]
pub struct FrameCount(pub AtomicU64);

/// The thread body: a frame every `spec.interval_s` into `dir/frame_NNNN.png` until stop.
pub fn run(
    mut maker: FrameMaker,
    dir: PathBuf,
    interval: Duration,
    count: Arc<FrameCount>,
    shared: Arc<Shared>,
) {
    let mut next = Instant::now();
    let mut last_steps = None;
    while !shared.stopping() {
        let now = Instant::now();
        if now < next {
            std::thread::sleep((next - now).min(Duration::from_millis(50)));
            continue;
        }
        next = now + interval;
        let Some(snap) = shared.render.load_full() else {
            continue;
        };
        // Nothing moved and nobody touched: no new frame.
        let key = (
            points_key(&snap),
            shared.haptic.cursor().to_array().map(f64::to_bits),
        );
        if last_steps == Some(key) {
            continue;
        }
        last_steps = Some(key);
        match write_frame(&mut maker, &snap, &shared, &dir, &count) {
            Ok(path) => tracing::debug!("frame {}", path.display()),
            Err(e) => {
                tracing::error!("rendering stopped: {e:#}");
                return;
            }
        }
    }
}

/// Render one frame now and save it as the next numbered PNG.
pub fn write_frame(
    maker: &mut FrameMaker,
    snap: &RenderSnapshot,
    shared: &Shared,
    dir: &Path,
    count: &FrameCount,
) -> anyhow::Result<PathBuf> {
    let n = count.0.fetch_add(1, Ordering::Relaxed);
    let path = dir.join(format!("frame_{n:04}.png"));
    maker.render(snap, shared)?.save_png(&path)?;
    Ok(path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::live::points::{ObjectPoints, PointPublisher};

    fn ring(n: usize) -> Vec<DVec3> {
        // A wavy band: irregular spacing, no exact ties.
        (0..n)
            .map(|i| {
                let a = i as f64 * 0.618_033_988_75 * std::f64::consts::TAU;
                let h = (i as f64 * 0.754_877_666).fract() * 0.02;
                DVec3::new(a.cos() * 0.05, a.sin() * 0.05, h + 0.001 * (3.0 * a).sin())
            })
            .collect()
    }

    /// The window's stand-in while a stroke moves points: every k-th point where it is now,
    /// with the shape last computed for it; unchanged points preview exactly as the cache's
    /// own splats thin.
    #[test]
    fn a_preview_thins_the_points_where_they_are_with_the_cached_shapes() {
        let mut p = ring(20_000);
        let n = vec![DVec3::Z; p.len()];
        let c = vec![[10u8, 20, 30]; p.len()];
        let mut publisher = PointPublisher::new();
        let mut publish = |p: &[DVec3]| {
            publisher.mark_all();
            publisher.publish(&[ObjectPoints {
                positions: p,
                normals: &n,
                colors: &c,
            }])
        };
        let mut cache = SplatCache::default();
        let snap = publish(&p);
        cache.update(&snap);
        let (mut preview, mut thinned) = (Vec::new(), Vec::new());
        let k = cache.preview(&snap, 3_000, &mut preview);
        assert_eq!(k, render::thin_splats(cache.current(), 3_000, &mut thinned));
        assert_eq!(preview, thinned);
        // Move every point up: the preview follows them, the cache does not.
        for x in &mut p {
            *x += DVec3::Z * 0.001;
        }
        let moved = publish(&p);
        cache.preview(&moved, 3_000, &mut preview);
        for (a, b) in preview.iter().zip(&thinned) {
            assert!((a.position[2] - b.position[2] - 0.001).abs() < 1e-6);
            assert_eq!((a.radius, a.axis), (b.radius, b.axis));
        }
        assert_eq!(cache.current()[0].position, thinned[0].position);
    }

    #[test]
    fn incremental_splats_equal_a_full_recompute_after_moves_turns_insertions_and_deletions() {
        let mut p = ring(20_000);
        let mut n = vec![DVec3::Z; p.len()];
        let mut c = vec![[10u8, 20, 30]; p.len()];
        let mut publisher = PointPublisher::new();
        let mut inc = SplatCache::new(SplatUpdate::Incremental);
        let publish = |pb: &mut PointPublisher, p: &[DVec3], n: &[DVec3], c: &[[u8; 3]]| {
            pb.publish(&[ObjectPoints {
                positions: p,
                normals: n,
                colors: c,
            }])
        };
        let snap = publish(&mut publisher, &p, &n, &c);
        inc.update(&snap);
        for round in 0..8 {
            match round % 4 {
                // Moves: a bump around one place (and a recolour elsewhere).
                0 => {
                    let centre = p[round * 100];
                    for (i, x) in p.iter_mut().enumerate() {
                        if x.distance(centre) < 0.008 {
                            *x += DVec3::Z * 0.002;
                            publisher.mark(0, i);
                        }
                    }
                    c[777] = [1, 2, 3];
                    publisher.mark(0, 777);
                }
                // Insertions at the end.
                1 => {
                    for k in 0..30 {
                        let x = p[k * 13] + DVec3::new(1e-4, 2e-4, 0.0);
                        p.push(x);
                        n.push(DVec3::X);
                        c.push([0, 0, 0]);
                        publisher.mark(0, p.len() - 1);
                    }
                }
                // Turns in place: a few normals flipped (the other side of a sheet) or tilted.
                2 => {
                    for k in 0..40 {
                        let j = 17 + k * 389;
                        n[j] = if k % 2 == 0 {
                            -n[j]
                        } else {
                            (n[j] + DVec3::X).normalize()
                        };
                        publisher.mark(0, j);
                    }
                }
                // Deletions by swap-remove.
                _ => {
                    for k in 0..25 {
                        let hole = 3 + k * 411;
                        p.swap_remove(hole);
                        n.swap_remove(hole);
                        c.swap_remove(hole);
                        publisher.mark(0, hole);
                    }
                }
            }
            let snap = publish(&mut publisher, &p, &n, &c);
            let work = inc.update(&snap);
            assert!(work.recomputed < p.len() / 10, "round {round}: {work:?}");
            let mut full = SplatCache::new(SplatUpdate::Full);
            full.update(&snap);
            assert_eq!(inc.current(), full.current(), "round {round}");
            let shapes = splat_shapes(&p, &n);
            assert!(
                inc.current()
                    .iter()
                    .zip(&shapes)
                    .all(|(s, r)| s.radius == r.radius
                        && s.minor_radius == r.minor_radius
                        && s.axis == r.axis)
            );
        }
        // Nothing changed: nothing recomputed or rewritten.
        let snap = publish(&mut publisher, &p, &n, &c);
        assert_eq!(inc.update(&snap), SplatWork::default());
    }
}
