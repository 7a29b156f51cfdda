//! The render pipelines and the one bind group layout they share.

use crate::{
    Renderer, Splat,
    geometry::{LineInstance, MeshInstance, MeshVertex},
};

/// Format of the attribute pass's two sums (blendable without an extra feature).
pub(crate) const ACCUM_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;

/// One pipeline per pass and kind of primitive.
#[derive(Debug)]
pub(crate) struct Pipelines {
    /// Splatting pass 1: pushed-back depth only.
    pub ewa_visibility: wgpu::RenderPipeline,
    /// Splatting pass 2: additive Σw·albedo, Σw, Σw·normal, depth-tested, no depth write.
    pub ewa_attribute: wgpu::RenderPipeline,
    /// Splatting pass 3: full-screen normalisation and shading into the colour target.
    pub ewa_normalise: wgpu::RenderPipeline,
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

/// Group 1 of the normalisation pass: the two accumulation textures.
pub(crate) fn accum_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    let texture = |binding| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: false },
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    };
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("accumulation"),
        entries: &[texture(0), texture(1)],
    })
}

/// Builds every pipeline for colour targets of `color_format`.
pub(crate) fn make_pipelines(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    accum: &wgpu::BindGroupLayout,
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
    let normalise_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("normalise"),
        bind_group_layouts: &[Some(layout), Some(accum)],
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
        depth_compare: wgpu::CompareFunction,
        targets: &'a [Option<wgpu::ColorTargetState>],
        layout: &'a wgpu::PipelineLayout,
    }
    let make = |s: Spec<'_>| {
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(s.label),
            layout: Some(s.layout),
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
                depth_compare: Some(s.depth_compare),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &shader,
                entry_point: Some(s.fs),
                compilation_options: Default::default(),
                targets: s.targets,
            }),
            multiview_mask: None,
            cache: None,
        })
    };
    use wgpu::CompareFunction::{Always, LessEqual};
    use wgpu::PrimitiveTopology::{TriangleList, TriangleStrip};
    let target = |blend| {
        [Some(wgpu::ColorTargetState {
            format: color_format,
            blend,
            write_mask: wgpu::ColorWrites::ALL,
        })]
    };
    let (opaque, blended) = (target(None), target(Some(wgpu::BlendState::ALPHA_BLENDING)));
    let add = wgpu::BlendComponent {
        src_factor: wgpu::BlendFactor::One,
        dst_factor: wgpu::BlendFactor::One,
        operation: wgpu::BlendOperation::Add,
    };
    let sum = Some(wgpu::ColorTargetState {
        format: ACCUM_FORMAT,
        blend: Some(wgpu::BlendState {
            color: add,
            alpha: add,
        }),
        write_mask: wgpu::ColorWrites::ALL,
    });
    let sums = [sum.clone(), sum];
    let back = Some(wgpu::Face::Back);
    let scene = &pipeline_layout;
    Pipelines {
        ewa_visibility: make(Spec {
            label: "splat visibility",
            vs: "vs_ewa",
            fs: "fs_ewa_visibility",
            buffers: &[],
            topology: TriangleList,
            cull: None,
            depth_write: true,
            depth_compare: LessEqual,
            targets: &[],
            layout: scene,
        }),
        ewa_attribute: make(Spec {
            label: "splat attributes",
            vs: "vs_ewa",
            fs: "fs_ewa_attribute",
            buffers: &[],
            topology: TriangleList,
            cull: None,
            depth_write: false,
            depth_compare: LessEqual,
            targets: &sums,
            layout: scene,
        }),
        ewa_normalise: make(Spec {
            label: "splat normalisation",
            vs: "vs_fullscreen",
            fs: "fs_ewa_normalise",
            buffers: &[],
            topology: TriangleList,
            cull: None,
            depth_write: false,
            depth_compare: Always,
            targets: &opaque,
            layout: &normalise_layout,
        }),
        mesh_opaque: make(Spec {
            label: "opaque meshes",
            vs: "vs_mesh",
            fs: "fs_mesh_opaque",
            buffers: &mesh_buffers,
            topology: TriangleList,
            cull: back,
            depth_write: true,
            depth_compare: LessEqual,
            targets: &opaque,
            layout: scene,
        }),
        mesh_translucent: make(Spec {
            label: "translucent meshes",
            vs: "vs_mesh",
            fs: "fs_mesh_translucent",
            buffers: &mesh_buffers,
            topology: TriangleList,
            cull: back,
            depth_write: false,
            depth_compare: LessEqual,
            targets: &blended,
            layout: scene,
        }),
        line: make(Spec {
            label: "lines",
            vs: "vs_line",
            fs: "fs_line",
            buffers: &line_buffers,
            topology: TriangleStrip,
            cull: None,
            depth_write: true,
            depth_compare: LessEqual,
            targets: &opaque,
            layout: scene,
        }),
    }
}
