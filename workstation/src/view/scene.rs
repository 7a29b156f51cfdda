//! The scene's texture: the `render` crate's renderer on eframe's wgpu device drawing into a
//! texture that egui shows as an image, so one renderer serves the window, the PNG frames and
//! `render`.

use std::sync::Arc;

use eframe::egui;
use eframe::egui_wgpu;

/// The scene's texture on eframe's device, and the renderer that draws into it.
pub(super) struct Gpu {
    renderer: render::Renderer,
    egui: Arc<egui::mutex::RwLock<egui_wgpu::Renderer>>,
    color: Option<(wgpu::TextureView, wgpu::TextureView, (u32, u32))>,
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
        Self {
            renderer,
            egui: Arc::clone(&state.renderer),
            color: None,
            texture: None,
        }
    }

    /// The texture for a view of `size` pixels (recreated when the size changes).
    fn target(&mut self, size: (u32, u32)) -> egui::TextureId {
        if self.color.as_ref().is_none_or(|c| c.2 != size) {
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
                    | wgpu::TextureUsages::TEXTURE_BINDING,
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
            self.color = Some((view, depth, size));
        }
        self.texture.expect("registered above")
    }

    pub(super) fn draw(
        &mut self,
        size: (u32, u32),
        splats: &[render::Splat],
        overlay: &render::Overlay,
        camera: &render::Camera,
    ) -> anyhow::Result<egui::TextureId> {
        let id = self.target(size);
        let (color, depth, _) = self.color.as_ref().expect("made by target");
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
