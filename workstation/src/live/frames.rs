//! The rendering thread: the newest [`RenderSnapshot`] and the newest cursor, force and contact
//! → one PNG frame every interval, with the `render` crate's EWA surface splatting
//! ([`HeadlessRenderer`]: a GPU through wgpu, or the same passes on the CPU where the only
//! Vulkan driver is a software one, or none is installed). The window draws with the same
//! splats and overlays.
//!
//! Points become lit surfel splats oriented by their normals, each of a radius from its local
//! spacing (the distance to its 6th nearest neighbour, recomputed only when the point set
//! changed size or moved), in its colour; overlays: the probe (when the probe is the tool), the
//! haptic cursor, the sculpting region box and the contact force arrow.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use glam::DVec3;
use render::{BackendChoice, Camera, Ellipsoid, HeadlessRenderer, Image, Overlay, Splat};
use sim_core::knn::PointIndex;

use super::scene_file::{RenderSpec, ToolKind};
use super::shared::{RenderSnapshot, Shared};

/// Length of the drawn force arrow per newton (m/N).
pub const ARROW_M_PER_N: f64 = 0.05;

/// Splat radii from local spacing: the distance to the 6th nearest neighbour, so that the
/// disks of an irregular (randomly sampled) surface overlap without holes.
pub fn splat_radii(positions: &[glam::DVec3]) -> Vec<f32> {
    const K: usize = 6;
    if positions.len() <= K {
        return vec![1e-3; positions.len()];
    }
    let index = PointIndex::new(positions);
    positions
        .iter()
        .map(|&p| {
            let n = index.nearest_k(p, K + 1);
            n.last().map_or(1e-3, |x| x.1.max(1e-6)) as f32
        })
        .collect()
}

/// Splats of a snapshot, with the radii kept until the points change (the neighbour search
/// is the expensive part); shared by the PNG frames and the window.
#[derive(Debug, Default)]
pub struct SplatCache {
    radii: Vec<f32>,
    radii_for: Option<(usize, u64)>,
    splats: Vec<Splat>,
}

impl SplatCache {
    /// The splats of `snap` (the buffer is reused from frame to frame).
    pub fn splats(&mut self, snap: &RenderSnapshot) -> &[Splat] {
        let key = points_key(snap);
        if self.radii_for != Some(key) {
            self.radii = splat_radii(&snap.positions);
            self.radii_for = Some(key);
        }
        self.splats.clear();
        self.splats.extend(
            snap.positions
                .iter()
                .zip(&snap.normals)
                .zip(&snap.colors)
                .zip(&self.radii)
                .map(|(((p, n), c), r)| {
                    Splat::disk(
                        p.as_vec3().to_array(),
                        n.as_vec3().to_array(),
                        *r,
                        [c[0], c[1], c[2], 255],
                    )
                }),
        );
        &self.splats
    }
}

/// The box a view of `snap` should frame: its points and the region (a 0.2 m cube at the
/// origin when it has neither).
pub fn scene_bounds(snap: &RenderSnapshot) -> (DVec3, DVec3) {
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for p in &snap.positions {
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
}

impl FrameMaker {
    /// A headless renderer of the scene's size on the backend `HAPTIC_RENDER` names
    /// (`auto`, the default: a GPU; the CPU splatter on a software Vulkan driver or without
    /// any, said once with how to get the fast path).
    pub fn new(spec: &RenderSpec) -> anyhow::Result<Self> {
        Self::with_backend(spec, BackendChoice::Auto)
    }

    /// As [`FrameMaker::new`] on the backend `choice`.
    pub fn with_backend(spec: &RenderSpec, choice: BackendChoice) -> anyhow::Result<Self> {
        let renderer = HeadlessRenderer::new(spec.width, spec.height, choice)?;
        match renderer.fallback_reason() {
            Some(why) => tracing::warn!("frames are drawn on the CPU: {why}"),
            None => tracing::info!("frames are drawn by {}", renderer.describe()),
        }
        Ok(Self {
            renderer,
            spec: *spec,
            camera: None,
            splats: SplatCache::default(),
            image: Image {
                width: 0,
                height: 0,
                rgba: Vec::new(),
            },
        })
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
        let splats = self.splats.splats(snap);
        self.renderer
            .render_into(splats, &overlay, &camera, &mut self.image)?;
        Ok(&self.image)
    }
}

/// Changes when the points change (count, positions or colours): a sum over them, O(points),
/// far cheaper than the neighbour search it saves.
pub fn points_key(snap: &RenderSnapshot) -> (usize, u64) {
    let mut h = 0u64;
    for (p, c) in snap.positions.iter().zip(&snap.colors) {
        for v in p.to_array() {
            h = h.wrapping_mul(31).wrapping_add(v.to_bits());
        }
        h = h
            .wrapping_mul(31)
            .wrapping_add(u64::from(u32::from_le_bytes([c[0], c[1], c[2], 0])));
    }
    (snap.positions.len(), h)
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
