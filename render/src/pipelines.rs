//! The render pipelines and the one bind group layout they share.

use crate::{
    Renderer, Splat,
    geometry::{LineInstance, MeshInstance, MeshVertex},
};

/// One pipeline per kind of primitive.
#[derive(Debug)]
pub(crate) struct Pipelines {
    /// Surfel splats, pulled from the storage buffer (no vertex buffers).
    pub splat: wgpu::RenderPipeline,
    /// Cursor and arrow head: lit, depth-written.
    pub mesh_opaque: wgpu::RenderPipeline,
    /// The probe: lit, alpha-blended, depth-tested without depth writes, back faces culled.
    pub mesh_translucent: wgpu::RenderPipeline,
    /// Wide line segments, unlit.
    pub line: wgpu::RenderPipeline,
}

/// Group 0: binding 0 the frame uniform (`frame_size` bytes), binding 1 the splats (read-only
/// storage, vertex stage).
pub(crate) fn bind_group_layout(device: &wgpu::Device, frame_size: u64) -> wgpu::BindGroupLayout {
    let buffer = |ty, visibility, min| wgpu::BindGroupLayoutEntry {
        binding: 0,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: wgpu::BufferSize::new(min),
        },
        count: None,
    };
    let storage = wgpu::BufferBindingType::Storage { read_only: true };
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("frame + splats"),
        entries: &[
            buffer(
                wgpu::BufferBindingType::Uniform,
                wgpu::ShaderStages::VERTEX_FRAGMENT,
                frame_size,
            ),
            wgpu::BindGroupLayoutEntry {
                binding: 1,
                ..buffer(
                    storage,
                    wgpu::ShaderStages::VERTEX,
                    std::mem::size_of::<Splat>() as u64,
                )
            },
        ],
    })
}

/// Builds every pipeline for colour targets of `color_format`.
pub(crate) fn make_pipelines(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    color_format: wgpu::TextureFormat,
) -> Pipelines {
    let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("render shaders"),
        source: wgpu::ShaderSource::Wgsl(include_str!("shaders.wgsl").into()),
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("render"),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    let mesh_attrs = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3];
    let mesh_instance_attrs = wgpu::vertex_attr_array![
        2 => Float32x4, 3 => Float32x4, 4 => Float32x4, 5 => Float32x4,
        6 => Float32x4, 7 => Float32x4, 8 => Float32x4, 9 => Float32x4
    ];
    let line_attrs = wgpu::vertex_attr_array![0 => Float32x4, 1 => Float32x4, 2 => Float32x4];
    let layout_of = |stride: usize, step_mode, attributes| {
        Some(wgpu::VertexBufferLayout {
            array_stride: stride as u64,
            step_mode,
            attributes,
        })
    };
    let instance = wgpu::VertexStepMode::Instance;
    let vertex = wgpu::VertexStepMode::Vertex;
    let mesh_buffers = [
        layout_of(std::mem::size_of::<MeshVertex>(), vertex, &mesh_attrs[..]),
        layout_of(
            std::mem::size_of::<MeshInstance>(),
            instance,
            &mesh_instance_attrs[..],
        ),
    ];
    let line_buffers = [layout_of(
        std::mem::size_of::<LineInstance>(),
        instance,
        &line_attrs[..],
    )];

    struct Spec<'a> {
        label: &'a str,
        vs: &'a str,
        fs: &'a str,
        buffers: &'a [Option<wgpu::VertexBufferLayout<'a>>],
        topology: wgpu::PrimitiveTopology,
        cull: Option<wgpu::Face>,
        depth_write: bool,
        blend: Option<wgpu::BlendState>,
    }
    let make = |s: Spec<'_>| {
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(s.label),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &shader,
                entry_point: Some(s.vs),
                compilation_options: Default::default(),
                buffers: s.buffers,
            },
            primitive: wgpu::PrimitiveState {
                topology: s.topology,
                cull_mode: s.cull,
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: Renderer::DEPTH_FORMAT,
                depth_write_enabled: Some(s.depth_write),
                depth_compare: Some(wgpu::CompareFunction::LessEqual),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &shader,
                entry_point: Some(s.fs),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: color_format,
                    blend: s.blend,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        })
    };
    use wgpu::PrimitiveTopology::{TriangleList, TriangleStrip};
    let back = Some(wgpu::Face::Back);
    Pipelines {
        splat: make(Spec {
            label: "splats",
            vs: "vs_splat",
            fs: "fs_splat",
            buffers: &[],
            topology: TriangleList,
            cull: None,
            depth_write: true,
            blend: None,
        }),
        mesh_opaque: make(Spec {
            label: "opaque meshes",
            vs: "vs_mesh",
            fs: "fs_mesh_opaque",
            buffers: &mesh_buffers,
            topology: TriangleList,
            cull: back,
            depth_write: true,
            blend: None,
        }),
        mesh_translucent: make(Spec {
            label: "translucent meshes",
            vs: "vs_mesh",
            fs: "fs_mesh_translucent",
            buffers: &mesh_buffers,
            topology: TriangleList,
            cull: back,
            depth_write: false,
            blend: Some(wgpu::BlendState::ALPHA_BLENDING),
        }),
        line: make(Spec {
            label: "lines",
            vs: "vs_line",
            fs: "fs_line",
            buffers: &line_buffers,
            topology: TriangleStrip,
            cull: None,
            depth_write: true,
            blend: None,
        }),
    }
}
