//! The scene's texture: the `render` crate's renderer on eframe's wgpu device drawing into a
//! texture that egui shows as an image, so one renderer serves the window, the PNG frames and
//! `render`; and the window's pixels saved as a PNG (screenshots).
//!
//! On a CPU implementation of Vulkan (Mesa's lavapipe, a machine without a GPU) the same
//! splatting runs on the CPU ([`render::SoftwareRenderer`], faster there than lavapipe) and
//! the frame is uploaded into the texture instead. There a frame costs ~0.3 µs per splat, so
//! the CPU path draws only what changed the picture: a frame whose points, camera, overlay,
//! style and size are those of the frame on screen is not drawn again. Above
//! [`CPU_SPLAT_BUDGET`] splats a frame drawn while something changes is a thinned stand-in
//! built from the snapshot's points and the splat shapes last computed
//! ([`SplatCache::preview`], O(budget)): the shapes of the points a stroke moves (tens of
//! thousands at 10⁶ points, ~0.1 s) are brought up to date once, on the first frame after the
//! picture holds still, which draws every splat.
//!
//! Tried and dropped (measured in docs/BENCHMARKS.md, "The window"): drawing on a thread of
//! its own. The window's thread then never waited for the scene (11 frames/s while a rope moved
//! 10⁶ points, against 5–6), but on two cores the window's own frames (egui through lavapipe)
//! and the scene's ran side by side instead of in turn, and the surface under the mouse moved
//! at 2.5 frames/s instead of 5–6.

use std::path::Path;
use std::sync::Arc;

use anyhow::Context as _;

use eframe::egui;
use eframe::egui_wgpu;

use crate::live::frames::SplatCache;
use crate::live::shared::RenderSnapshot;

/// Above this many splats the CPU path draws a thinned set while the picture changes (a
/// frame of ~50 ms on two cores; 10⁶ splats take ~0.35 s).
pub(super) const CPU_SPLAT_BUDGET: usize = 150_000;

/// What a CPU frame showed: drawn again only when one of these changes, or to refine.
#[derive(Clone, Copy, PartialEq)]
struct Shown {
    size: (u32, u32),
    camera: render::Camera,
    overlay: render::Overlay,
    style: render::Style,
    /// The snapshot's points ([`crate::live::points::ChunkedPoints::key`]).
    points: (usize, u64),
    /// Drawn from every splat (not a thinned stand-in).
    full: bool,
}

/// The CPU splatter of the window (on a CPU Vulkan adapter) and what it last drew.
struct Cpu {
    renderer: render::SoftwareRenderer,
    image: render::Image,
    thinned: Vec<render::Splat>,
    shown: Option<Shown>,
}

/// The scene's texture on eframe's device, and the renderer that draws into it.
pub(super) struct Gpu {
    renderer: render::Renderer,
    /// On a CPU Vulkan adapter: the CPU splatter; its frames are uploaded into `texture`.
    software: Option<Cpu>,
    egui: Arc<egui::mutex::RwLock<egui_wgpu::Renderer>>,
    color: Option<(
        wgpu::Texture,
        wgpu::TextureView,
        wgpu::TextureView,
        (u32, u32),
    )>,
    texture: Option<egui::TextureId>,
}

impl Gpu {
    pub(super) fn new(state: &egui_wgpu::RenderState) -> Self {
        let renderer = render::Renderer::with_device(
            state.device.clone(),
            state.queue.clone(),
            state.adapter.get_info(),
            render::Renderer::HEADLESS_FORMAT,
        );
        let software = renderer
            .is_cpu_adapter()
            .then(|| render::SoftwareRenderer::new(1, 1).ok())
            .flatten()
            .map(|renderer| Cpu {
                renderer,
                image: render::Image::default(),
                thinned: Vec::new(),
                shown: None,
            });
        tracing::info!(
            "the window draws with {}",
            if software.is_some() {
                "the CPU splatter (the Vulkan adapter is a CPU one)".to_owned()
            } else {
                renderer.adapter_info()
            }
        );
        Self {
            renderer,
            software,
            egui: Arc::clone(&state.renderer),
            color: None,
            texture: None,
        }
    }

    /// The texture for a view of `size` pixels (recreated when the size changes).
    fn target(&mut self, size: (u32, u32)) -> egui::TextureId {
        if self.color.as_ref().is_none_or(|c| c.3 != size) {
            let device = self.renderer.device();
            let texture = device.create_texture(&wgpu::TextureDescriptor {
                label: Some("window scene"),
                size: wgpu::Extent3d {
                    width: size.0,
                    height: size.1,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: render::Renderer::HEADLESS_FORMAT,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::TEXTURE_BINDING
                    | wgpu::TextureUsages::COPY_DST,
                view_formats: &[wgpu::TextureFormat::Rgba8Unorm],
            });
            // The renderer writes sRGB-encoded bytes through the sRGB view; egui blends in
            // gamma space, so it samples the same bytes through a plain view (no decoding).
            let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
            let shown = texture.create_view(&wgpu::TextureViewDescriptor {
                format: Some(wgpu::TextureFormat::Rgba8Unorm),
                ..Default::default()
            });
            let depth = self.renderer.create_depth_view(size.0, size.1);
            let mut egui = self.egui.write();
            match self.texture {
                Some(id) => egui.update_egui_texture_from_wgpu_texture(
                    device,
                    &shown,
                    wgpu::FilterMode::Linear,
                    id,
                ),
                None => {
                    self.texture = Some(egui.register_native_texture(
                        device,
                        &shown,
                        wgpu::FilterMode::Linear,
                    ));
                }
            }
            self.color = Some((texture, view, depth, size));
        }
        self.texture.expect("registered above")
    }

    /// Draw the points of `snap` (their splats in `splats`, brought up to date here) with
    /// `overlay` from `camera` into the scene texture.
    pub(super) fn draw(
        &mut self,
        size: (u32, u32),
        splats: &mut SplatCache,
        snap: &RenderSnapshot,
        overlay: &render::Overlay,
        camera: &render::Camera,
    ) -> anyhow::Result<egui::TextureId> {
        let id = self.target(size);
        let (texture, color, depth, _) = self.color.as_ref().expect("made by target");
        if let Some(cpu) = &mut self.software {
            let style = *self.renderer.style();
            let still = |full| Shown {
                size,
                camera: *camera,
                overlay: *overlay,
                style,
                points: snap.points.key(),
                full,
            };
            // Nothing changed: the texture already shows this frame (the full one, or the
            // thinned one refined below).
            if cpu.shown == Some(still(true)) {
                return Ok(id);
            }
            let moving = cpu.shown.is_none_or(|s| s != still(s.full));
            let thin = moving && snap.points.len() > CPU_SPLAT_BUDGET && !splats.is_empty();
            let drawn: &[render::Splat] = if thin {
                splats.preview(&snap.points, CPU_SPLAT_BUDGET, &mut cpu.thinned);
                &cpu.thinned
            } else {
                splats.update(&snap.points);
                splats.current()
            };
            cpu.renderer.resize(size.0, size.1)?;
            cpu.renderer.set_style(style);
            cpu.renderer
                .render_into(drawn, overlay, camera, &mut cpu.image)?;
            cpu.shown = Some(still(!thin));
            self.renderer.queue().write_texture(
                texture.as_image_copy(),
                &cpu.image.rgba,
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(4 * size.0),
                    rows_per_image: Some(size.1),
                },
                wgpu::Extent3d {
                    width: size.0,
                    height: size.1,
                    depth_or_array_layers: 1,
                },
            );
            return Ok(id);
        }
        splats.update(&snap.points);
        let splats = splats.current();
        let mut encoder =
            self.renderer
                .device()
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("window scene"),
                });
        self.renderer
            .draw(&mut encoder, color, depth, size, splats, overlay, camera)?;
        self.renderer.queue().submit(Some(encoder.finish()));
        Ok(id)
    }
}

/// Save an egui screenshot as an opaque PNG (directories made as needed).
pub(super) fn save_color_image(image: &egui::ColorImage, path: &Path) -> anyhow::Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let [w, h] = image.size;
    let rgba = image
        .pixels
        .iter()
        .flat_map(|c| {
            let [r, g, b, _] = c.to_array();
            [r, g, b, 255]
        })
        .collect();
    render::Image {
        width: w as u32,
        height: h as u32,
        rgba,
    }
    .save_png(path)?;
    Ok(())
}
