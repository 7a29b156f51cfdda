//! The [`Renderer`]: device, pipelines, buffers; headless target and readback.

use std::sync::{
    Arc,
    atomic::{AtomicU8, Ordering},
};

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use wgpu::util::DeviceExt;

use crate::{
    Camera, Image, Overlay, RenderError, Splat, Style,
    ewa::{self, FrameParams},
    geometry::{
        LineInstance, MAX_LINES, MESH_SLOTS, Mesh, MeshInstance, OverlayInstances, SLOT_ARROW_HEAD,
        SLOT_CONTACT, SLOT_CURSOR, SLOT_PROBE, unit_cone, unit_sphere,
    },
    pipelines::{ACCUM_FORMAT, Pipelines, accum_layout, bind_group_layout, make_pipelines},
    scene::srgb_to_linear,
};

/// The per-frame uniform block (`Frame` in `shaders.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct FrameUniform {
    view_proj: [[f32; 4]; 4],
    eye: [f32; 4],
    right: [f32; 4],
    up: [f32; 4],
    viewport: [f32; 4],
    light: [f32; 4],
    options: [f32; 4],
    row_x: [f32; 4],
    row_y: [f32; 4],
    row_w: [f32; 4],
    forward: [f32; 4],
    right_t: [f32; 4],
    up_t: [f32; 4],
    ewa: [f32; 4],
    ewa_k: [f32; 4],
}

/// The attribute pass's two sums at one size, and the bind group the normalisation reads them by.
#[derive(Debug)]
struct Accum {
    size: (u32, u32),
    color: wgpu::TextureView,
    normal: wgpu::TextureView,
    bind_group: wgpu::BindGroup,
}

/// A mesh uploaded to the GPU.
#[derive(Debug)]
struct GpuMesh {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    index_count: u32,
}

impl GpuMesh {
    fn new(device: &wgpu::Device, mesh: &Mesh, label: &str) -> Self {
        let init = |contents: &[u8], usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
        };
        Self {
            vertices: init(
                bytemuck::cast_slice(&mesh.vertices),
                wgpu::BufferUsages::VERTEX,
            ),
            indices: init(
                bytemuck::cast_slice(&mesh.indices),
                wgpu::BufferUsages::INDEX,
            ),
            index_count: mesh.indices.len() as u32,
        }
    }
}

/// The offscreen colour and depth targets of [`Renderer::render`] and their readback buffer.
#[derive(Debug)]
struct Offscreen {
    width: u32,
    height: u32,
    color: wgpu::Texture,
    color_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
    readback: wgpu::Buffer,
    padded_row: u32,
}

/// Readback state shared with the `map_async` callback.
const MAP_PENDING: u8 = 0;
const MAP_OK: u8 = 1;
const MAP_FAILED: u8 = 2;

/// Draws splats and overlays; owns its device, queue, pipelines and buffers (see the crate doc).
pub struct Renderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    adapter: wgpu::AdapterInfo,
    color_format: wgpu::TextureFormat,
    style: Style,
    pipelines: Pipelines,
    frame: wgpu::Buffer,
    layout: wgpu::BindGroupLayout,
    accum_layout: wgpu::BindGroupLayout,
    accum: Option<Accum>,
    bind_group: wgpu::BindGroup,
    sphere: GpuMesh,
    cone: GpuMesh,
    splats: wgpu::Buffer,
    splat_capacity: usize,
    mesh_instances: wgpu::Buffer,
    lines: wgpu::Buffer,
    overlay: OverlayInstances,
    target: Option<Offscreen>,
    map_state: Arc<AtomicU8>,
}

impl std::fmt::Debug for Renderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Renderer")
            .field("adapter", &self.adapter_info())
            .field("color_format", &self.color_format)
            .field("splat_capacity", &self.splat_capacity)
            .field("target", &self.target.as_ref().map(|t| (t.width, t.height)))
            .finish_non_exhaustive()
    }
}

impl Renderer {
    /// Format of the depth buffer `draw` expects (see [`Renderer::create_depth_view`]).
    pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
    /// Colour format of the headless target: sRGB-encoded RGBA8.
    pub const HEADLESS_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
    /// Splat capacity of a new renderer; the buffer doubles past it.
    const INITIAL_SPLATS: usize = 4096;

    /// A renderer on the first suitable Vulkan adapter (a GPU if there is one, else lavapipe)
    /// with a `width × height` offscreen target. `WGPU_BACKEND` and the other wgpu environment
    /// variables apply.
    pub fn headless(width: u32, height: u32) -> Result<Self, RenderError> {
        let desc = wgpu::InstanceDescriptor {
            backends: wgpu::Backends::VULKAN,
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        };
        let instance = wgpu::Instance::new(desc.with_env());
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
            apply_limit_buckets: false,
        }))
        .map_err(|e| RenderError::NoAdapter(e.to_string()))?;
        let info = adapter.get_info();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("render"),
            required_limits: wgpu::Limits {
                max_storage_buffer_binding_size: adapter.limits().max_storage_buffer_binding_size,
                max_buffer_size: adapter.limits().max_buffer_size,
                ..wgpu::Limits::default().using_resolution(adapter.limits())
            },
            ..Default::default()
        }))
        .map_err(|source| RenderError::RequestDevice {
            adapter: describe(&info),
            source,
        })?;
        let mut renderer = Self::with_device(device, queue, info, Self::HEADLESS_FORMAT);
        renderer.resize(width, height)?;
        Ok(renderer)
    }

    /// A renderer on a device the caller made (e.g. for a window's surface), drawing into
    /// targets of `color_format` (use an sRGB format: shading is linear). It has no offscreen
    /// target until [`Renderer::resize`].
    pub fn with_device(
        device: wgpu::Device,
        queue: wgpu::Queue,
        adapter: wgpu::AdapterInfo,
        color_format: wgpu::TextureFormat,
    ) -> Self {
        let frame = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame uniform"),
            size: std::mem::size_of::<FrameUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let layout = bind_group_layout(&device, std::mem::size_of::<FrameUniform>() as u64);
        let accum_layout = accum_layout(&device);
        let pipelines = make_pipelines(&device, &layout, &accum_layout, color_format);
        let splats = splat_buffer(&device, Self::INITIAL_SPLATS);
        let bind_group = make_bind_group(&device, &layout, &frame, &splats);
        let instance_buffer = |label, bytes: usize| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes as u64,
                usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let mesh_instances = instance_buffer(
            "mesh instances",
            MESH_SLOTS * std::mem::size_of::<MeshInstance>(),
        );
        let lines = instance_buffer("lines", MAX_LINES * std::mem::size_of::<LineInstance>());
        Self {
            sphere: GpuMesh::new(&device, &unit_sphere(24, 48), "sphere"),
            cone: GpuMesh::new(&device, &unit_cone(32), "cone"),
            device,
            queue,
            adapter,
            color_format,
            style: Style::default(),
            pipelines,
            frame,
            layout,
            accum_layout,
            accum: None,
            bind_group,
            splats,
            splat_capacity: Self::INITIAL_SPLATS,
            mesh_instances,
            lines,
            overlay: OverlayInstances::default(),
            target: None,
            map_state: Arc::new(AtomicU8::new(MAP_PENDING)),
        }
    }

    /// The adapter's name and backend, e.g. `"llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, Cpu)"`.
    pub fn adapter_info(&self) -> String {
        describe(&self.adapter)
    }

    /// Whether the adapter is a CPU implementation of Vulkan (Mesa's lavapipe/llvmpipe): there
    /// the [`SoftwareRenderer`](crate::SoftwareRenderer) draws the same frames faster
    /// (docs/BENCHMARKS.md, "Headless renderer"), so [`HeadlessRenderer`](crate::HeadlessRenderer)
    /// prefers it.
    pub fn is_cpu_adapter(&self) -> bool {
        self.adapter.device_type == wgpu::DeviceType::Cpu
    }

    /// The device, for a caller that creates its own targets (a window's surface).
    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    /// The queue `render` submits to; a window submits `draw`'s encoder to it.
    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    /// The current style.
    pub fn style(&self) -> &Style {
        &self.style
    }

    /// Replaces the style (colours, sizes, lighting) used from the next frame on.
    pub fn set_style(&mut self, style: Style) {
        self.style = style;
    }

    /// (Re)creates the offscreen target of [`Renderer::render`] at `width × height`
    /// (allocates; a no-op if the size is unchanged).
    pub fn resize(&mut self, width: u32, height: u32) -> Result<(), RenderError> {
        let max = self.device.limits().max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(RenderError::InvalidSize { width, height, max });
        }
        if self
            .target
            .as_ref()
            .is_some_and(|t| (t.width, t.height) == (width, height))
        {
            return Ok(());
        }
        let color = self.texture_2d(
            "offscreen colour",
            width,
            height,
            self.color_format,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        );
        let padded_row = (4 * width).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let readback = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: padded_row as u64 * height as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        self.target = Some(Offscreen {
            width,
            height,
            color_view: color.create_view(&Default::default()),
            color,
            depth_view: self.create_depth_view(width, height),
            readback,
            padded_row,
        });
        Ok(())
    }

    /// A depth buffer view of [`Renderer::DEPTH_FORMAT`] for `draw` into a `width × height`
    /// target (allocates).
    pub fn create_depth_view(&self, width: u32, height: u32) -> wgpu::TextureView {
        let depth = self.texture_2d(
            "depth",
            width,
            height,
            Self::DEPTH_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        depth.create_view(&Default::default())
    }

    /// A single-sampled 2-D texture without mips.
    fn texture_2d(
        &self,
        label: &str,
        width: u32,
        height: u32,
        format: wgpu::TextureFormat,
        usage: wgpu::TextureUsages,
    ) -> wgpu::Texture {
        self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        })
    }

    /// Draws one frame into the offscreen target and reads it back (blocks until the GPU is
    /// done). Allocates the returned image; see [`Renderer::render_into`].
    pub fn render(
        &mut self,
        splats: &[Splat],
        overlay: &Overlay,
        camera: &Camera,
    ) -> Result<Image, RenderError> {
        let mut image = Image::default();
        self.render_into(splats, overlay, camera, &mut image)?;
        Ok(image)
    }

    /// As [`Renderer::render`], into `image` (its buffer is reused when large enough).
    pub fn render_into(
        &mut self,
        splats: &[Splat],
        overlay: &Overlay,
        camera: &Camera,
        image: &mut Image,
    ) -> Result<(), RenderError> {
        let target = self.target.take().ok_or(RenderError::NoTarget)?;
        let result = self.render_target(&target, splats, overlay, camera, image);
        self.target = Some(target);
        result
    }

    fn render_target(
        &mut self,
        t: &Offscreen,
        splats: &[Splat],
        overlay: &Overlay,
        camera: &Camera,
        image: &mut Image,
    ) -> Result<(), RenderError> {
        let mut encoder = self.device.create_command_encoder(&Default::default());
        self.draw(
            &mut encoder,
            &t.color_view,
            &t.depth_view,
            (t.width, t.height),
            splats,
            overlay,
            camera,
        )?;
        encoder.copy_texture_to_buffer(
            t.color.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &t.readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(t.padded_row),
                    rows_per_image: Some(t.height),
                },
            },
            wgpu::Extent3d {
                width: t.width,
                height: t.height,
                depth_or_array_layers: 1,
            },
        );
        self.queue.submit([encoder.finish()]);

        self.map_state.store(MAP_PENDING, Ordering::Release);
        let state = Arc::clone(&self.map_state);
        t.readback.map_async(wgpu::MapMode::Read, .., move |r| {
            state.store(
                if r.is_ok() { MAP_OK } else { MAP_FAILED },
                Ordering::Release,
            );
        });
        self.device.poll(wgpu::PollType::wait_indefinitely())?;
        if self.map_state.load(Ordering::Acquire) != MAP_OK {
            return Err(RenderError::Readback(wgpu::BufferAsyncError));
        }
        // Copy out, then unmap on every path: a buffer left mapped fails the next frame.
        let copied = t.readback.get_mapped_range(..).map(|mapped| {
            let row = 4 * t.width as usize;
            image.width = t.width;
            image.height = t.height;
            image.rgba.clear();
            image.rgba.reserve(row * t.height as usize);
            for y in 0..t.height as usize {
                let start = y * t.padded_row as usize;
                image.rgba.extend_from_slice(&mapped[start..start + row]);
            }
        });
        t.readback.unmap();
        copied.map_err(|_| RenderError::Readback(wgpu::BufferAsyncError))
    }

    /// Records one frame into `encoder`: the three splatting passes into `depth` (of
    /// [`Renderer::DEPTH_FORMAT`], cleared to 1 and left holding the splats' pushed-back depth)
    /// and the renderer's accumulation targets, then `color` (of the renderer's colour format)
    /// cleared to the background, the normalised and shaded splats and the overlay seen by
    /// `camera`, all `size` pixels. Uploads happen through the queue, so submit the encoder
    /// before the next `draw`. Validates every input first; on error nothing is recorded.
    /// Grows the splat buffer if this frame has more splats than any before, and (re)creates
    /// the accumulation targets when `size` changes.
    #[allow(clippy::too_many_arguments)] // the target (encoder, two views, size) and the scene
    pub fn draw(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        color: &wgpu::TextureView,
        depth: &wgpu::TextureView,
        size: (u32, u32),
        splats: &[Splat],
        overlay: &Overlay,
        camera: &Camera,
    ) -> Result<(), RenderError> {
        let (width, height) = size;
        let max = self.device.limits().max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(RenderError::InvalidSize { width, height, max });
        }
        camera.validate()?;
        if let Some(index) = splats.iter().position(|s| !s.is_valid()) {
            return Err(RenderError::NonFinite {
                what: "splat",
                index,
            });
        }
        let max_splats = self.device.limits().max_storage_buffer_binding_size as usize
            / std::mem::size_of::<Splat>();
        if splats.len() > max_splats {
            return Err(RenderError::TooManySplats {
                count: splats.len(),
                max: max_splats,
            });
        }
        self.overlay.build(overlay, camera, height, &self.style)?;

        self.queue.write_buffer(
            &self.frame,
            0,
            bytemuck::bytes_of(&self.frame_uniform(camera, size)),
        );
        if splats.len() > self.splat_capacity {
            self.splat_capacity = splats.len().next_power_of_two().min(max_splats);
            self.splats = splat_buffer(&self.device, self.splat_capacity);
            self.bind_group =
                make_bind_group(&self.device, &self.layout, &self.frame, &self.splats);
        }
        if !splats.is_empty() {
            self.queue
                .write_buffer(&self.splats, 0, bytemuck::cast_slice(splats));
        }
        self.queue.write_buffer(
            &self.mesh_instances,
            0,
            bytemuck::cast_slice(&self.overlay.meshes),
        );
        self.queue
            .write_buffer(&self.lines, 0, bytemuck::cast_slice(&self.overlay.lines));
        if self.accum.as_ref().is_none_or(|a| a.size != size) {
            self.accum = Some(self.make_accum(size));
        }
        let accum = self.accum.as_ref().expect("made above");
        // Splat vertices: six per splat (two triangles), pulled from the storage buffer.
        let vertices = 0..6 * splats.len() as u32;

        // Pass 1, visibility: depth only.
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("splat visibility"),
                color_attachments: &[],
                depth_stencil_attachment: Some(depth_attachment(depth, wgpu::LoadOp::Clear(1.0))),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            if !splats.is_empty() {
                pass.set_bind_group(0, &self.bind_group, &[]);
                pass.set_pipeline(&self.pipelines.ewa_visibility);
                pass.draw(vertices.clone(), 0..1);
            }
        }
        // Pass 2, attributes: additive sums within ε of the front.
        {
            let zero = wgpu::Operations {
                load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                store: wgpu::StoreOp::Store,
            };
            let sum = |view| {
                Some(wgpu::RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: zero,
                })
            };
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("splat attributes"),
                color_attachments: &[sum(&accum.color), sum(&accum.normal)],
                depth_stencil_attachment: Some(depth_attachment(depth, wgpu::LoadOp::Load)),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            if !splats.is_empty() {
                pass.set_bind_group(0, &self.bind_group, &[]);
                pass.set_pipeline(&self.pipelines.ewa_attribute);
                pass.draw(vertices, 0..1);
            }
        }

        // Pass 3, normalisation and shading, then the overlays over it.
        let [r, g, b, a] = self.style.background;
        let clear = wgpu::Color {
            r: srgb_to_linear(r) as f64,
            g: srgb_to_linear(g) as f64,
            b: srgb_to_linear(b) as f64,
            a: a as f64 / 255.0,
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("scene"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: color,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(clear),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(depth_attachment(depth, wgpu::LoadOp::Load)),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_bind_group(0, &self.bind_group, &[]);
        if !splats.is_empty() {
            pass.set_bind_group(1, &accum.bind_group, &[]);
            pass.set_pipeline(&self.pipelines.ewa_normalise);
            pass.draw(0..3, 0..1);
        }
        let used = self.overlay.used;
        let mesh = |pass: &mut wgpu::RenderPass<'_>, m: &GpuMesh, slot: u32| {
            if used[slot as usize] {
                pass.set_vertex_buffer(0, m.vertices.slice(..));
                pass.set_vertex_buffer(1, self.mesh_instances.slice(..));
                pass.set_index_buffer(m.indices.slice(..), wgpu::IndexFormat::Uint16);
                pass.draw_indexed(0..m.index_count, 0, slot..slot + 1);
            }
        };
        pass.set_pipeline(&self.pipelines.mesh_opaque);
        mesh(&mut pass, &self.sphere, SLOT_CURSOR);
        mesh(&mut pass, &self.sphere, SLOT_CONTACT);
        mesh(&mut pass, &self.cone, SLOT_ARROW_HEAD);
        if self.overlay.line_count > 0 {
            pass.set_pipeline(&self.pipelines.line);
            pass.set_vertex_buffer(0, self.lines.slice(..));
            pass.draw(0..4, 0..self.overlay.line_count);
        }
        pass.set_pipeline(&self.pipelines.mesh_translucent);
        mesh(&mut pass, &self.sphere, SLOT_PROBE);
        Ok(())
    }

    /// The accumulation targets for frames of `size` (allocates).
    fn make_accum(&self, (width, height): (u32, u32)) -> Accum {
        let usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
        let view = |label| {
            self.texture_2d(label, width, height, ACCUM_FORMAT, usage)
                .create_view(&Default::default())
        };
        let (color, normal) = (view("Σw·albedo, Σw"), view("Σw·normal"));
        let bind_group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("accumulation"),
            layout: &self.accum_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&color),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&normal),
                },
            ],
        });
        Accum {
            size: (width, height),
            color,
            normal,
            bind_group,
        }
    }

    fn frame_uniform(&self, camera: &Camera, (width, height): (u32, u32)) -> FrameUniform {
        let f = FrameParams::new(camera, (width, height), &self.style);
        let l = &self.style.lighting;
        let (w, h) = (width as f32, height as f32);
        let v4 = |v: Vec3| v.extend(0.0).to_array();
        FrameUniform {
            view_proj: f.view_proj.to_cols_array_2d(),
            eye: f.eye.extend(1.0).into(),
            right: v4(f.right),
            up: v4(f.up),
            viewport: [w, h, 1.0 / w, 1.0 / h],
            light: [l.ambient, l.diffuse, l.specular, l.shininess],
            options: [if f.cull { 1.0 } else { 0.0 }, 0.0, 0.0, 0.0],
            row_x: f.row_x.to_array(),
            row_y: f.row_y.to_array(),
            row_w: f.row_w.to_array(),
            forward: v4(f.forward),
            right_t: v4(f.right_t),
            up_t: v4(f.up_t),
            ewa: [f.depth_a, f.depth_b, f.near, ewa::EPS_PX * f.px_per_depth],
            ewa_k: [
                ewa::GAUSS_K,
                ewa::EPS_FRACTION,
                ewa::PREFILTER_PX,
                ewa::MIN_WEIGHT,
            ],
        }
    }
}

/// The depth attachment of every pass: `load`, then stored.
fn depth_attachment(
    view: &wgpu::TextureView,
    load: wgpu::LoadOp<f32>,
) -> wgpu::RenderPassDepthStencilAttachment<'_> {
    wgpu::RenderPassDepthStencilAttachment {
        view,
        depth_ops: Some(wgpu::Operations {
            load,
            store: wgpu::StoreOp::Store,
        }),
        stencil_ops: None,
    }
}

fn describe(info: &wgpu::AdapterInfo) -> String {
    format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type)
}

fn splat_buffer(device: &wgpu::Device, capacity: usize) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("splats"),
        size: (capacity * std::mem::size_of::<Splat>()) as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

fn make_bind_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    frame: &wgpu::Buffer,
    splats: &wgpu::Buffer,
) -> wgpu::BindGroup {
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("frame + splats"),
        layout,
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: frame.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: splats.as_entire_binding(),
            },
        ],
    })
}
