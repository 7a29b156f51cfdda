//! `render`: a wgpu renderer of the sculpting scene (DESIGN §6, the rendering thread), headless
//! to RGBA/PNG today and into a window's surface later with the same [`Renderer`].
//!
//! What it draws, in this order, in one render pass with a depth buffer:
//! 1. the points as lit, oriented surfel splats ([`Splat`]): a disk per point centred at its
//!    position, in the tangent plane of its unit normal, of the radius the caller gives (from
//!    local spacing), in its sRGB colour; one triangle per splat enclosing its disk, expanded
//!    in the vertex shader in the tangent plane from the splat array (bound as a storage
//!    buffer: no instancing, which Mesa's software rasteriser runs one instance at a time),
//!    fragments outside the unit disk discarded, depth-tested and written (no EWA blending: the
//!    nearest disk wins); optionally back-facing splats culled ([`Style::cull_back_facing`]);
//! 2. the opaque overlays ([`Overlay`]): the haptic cursor and the contact point (small spheres
//!    of constant screen size) and the head of the force arrow;
//! 3. lines of a given width in pixels, depth-tested: the sculpting region's 12 box edges and the
//!    force arrow's shaft;
//! 4. the probe ellipsoid, translucent (alpha-blended over everything above, depth-tested, no
//!    depth write), front faces only.
//!
//! Lighting ([`Lighting`]) is a headlight (a point light at the eye): Lambert with ambient and a
//! little white specular, two-sided (`|n·l|`), computed in linear colour; targets are sRGB.
//!
//! Contract:
//! - No global state. A [`Renderer`] owns its wgpu device, queue, pipelines and buffers; several
//!   can coexist (each test makes its own).
//! - Allocation: the splat buffer grows (to the next power of two) when a frame has more splats
//!   than any frame before, and never shrinks; overlay buffers have a fixed size. Once sized, a
//!   frame creates no buffer or texture; the most splats per frame is the device's storage
//!   binding size / 32 bytes ([`RenderError::TooManySplats`]; 4 M at wgpu's default limits).
//!   [`Renderer::render`] allocates the [`Image`] it returns ([`Renderer::render_into`] reuses
//!   one); wgpu itself allocates a little per command encoder.
//! - [`Renderer::draw`] records into a caller's encoder and colour/depth views, so a window can
//!   reuse the renderer unchanged: make the device with the surface's adapter, call
//!   [`Renderer::with_device`] with the surface's (sRGB) format, create a depth view with
//!   [`Renderer::create_depth_view`], and `draw` into each frame's surface texture view.
//! - Inputs are validated at the boundary: a non-finite splat or overlay value, or an invalid
//!   camera, is an error that names it, and nothing is drawn.
//!
//! Backend: wgpu 30 with Vulkan only (features `std`, `vulkan`, `wgsl`). Without a GPU it runs
//! on Mesa's software Vulkan driver, lavapipe (Debian `mesa-vulkan-drivers` + `libvulkan1`,
//! which CI installs); GL was not needed and is not built. In a session without a display,
//! Mesa may print `XDG_RUNTIME_DIR is invalid or not set` on stderr when the instance is made:
//! harmless. On lavapipe a 1280×720 frame with readback takes ~22 ms at 10k splats and
//! ~80–100 ms at 100k (docs/BENCHMARKS.md, "Headless renderer").

mod camera;
mod ewa;
mod geometry;
mod headless;
mod image;
mod pipelines;
mod raster;
mod renderer;
mod scene;
mod shape;
mod software;

pub use camera::Camera;
pub use ewa::{EPS_FRACTION, EPS_PX, GAUSS_K, MIN_WEIGHT, PREFILTER_PX};
pub use headless::{BACKEND_ENV, Backend, BackendChoice, HeadlessRenderer};
pub use image::Image;
pub use renderer::Renderer;
pub use scene::{Ellipsoid, Lighting, Overlay, Splat, Style, linear_to_srgb, srgb_to_linear};
pub use shape::{MAX_SHAPE_NEIGHBOURS, MIN_SPLAT_ASPECT, SPLAT_OVERLAP, SplatShape, splat_shape};
pub use software::SoftwareRenderer;

/// Errors of the renderer; each variant names what failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RenderError {
    /// No Vulkan adapter (GPU or software) could be found.
    #[error(
        "no Vulkan adapter found ({0}); without a GPU install Mesa's software Vulkan driver: \
         `apt-get install mesa-vulkan-drivers libvulkan1` (Debian/Ubuntu)"
    )]
    NoAdapter(String),
    /// The adapter refused to create a device.
    #[error("could not create a device on adapter {adapter}: {source}")]
    RequestDevice {
        /// The adapter's description.
        adapter: String,
        /// wgpu's error.
        source: wgpu::RequestDeviceError,
    },
    /// A target size is zero or larger than the device allows.
    #[error("target size {width}x{height} is invalid (each side 1..={max})")]
    InvalidSize {
        /// Requested width in pixels.
        width: u32,
        /// Requested height in pixels.
        height: u32,
        /// The device's largest texture side.
        max: u32,
    },
    /// `render` was called on a renderer that has no offscreen target (see [`Renderer::resize`]).
    #[error("this renderer has no offscreen target; call `resize` first")]
    NoTarget,
    /// More splats than one storage buffer binding of this device holds.
    #[error("{count} splats exceed this device's limit of {max} per frame")]
    TooManySplats {
        /// Splats passed.
        count: usize,
        /// Most splats one frame can draw (storage binding size / 48 bytes).
        max: usize,
    },
    /// The camera cannot produce a projection.
    #[error("invalid camera: {0}")]
    InvalidCamera(&'static str),
    /// A splat or overlay value is NaN or infinite, or a radius is negative.
    #[error("{what} {index} is not finite (or has a negative radius)")]
    NonFinite {
        /// Which input: "splat", "probe", "cursor", "contact", "region", "force".
        what: &'static str,
        /// Index of the offending splat (0 for overlays).
        index: usize,
    },
    /// Waiting for the GPU failed.
    #[error("waiting for the GPU failed: {0}")]
    Poll(#[from] wgpu::PollError),
    /// Mapping the readback buffer failed.
    #[error("reading the image back failed: {0}")]
    Readback(#[from] wgpu::BufferAsyncError),
    /// A backend name other than `auto`, `gpu` or `software`.
    #[error("unknown renderer backend {0:?} (expected auto, gpu or software)")]
    UnknownBackend(String),
    /// Writing a PNG file failed.
    #[error("writing PNG {path}: {source}")]
    Png {
        /// The file being written.
        path: String,
        /// The encoder's or the file system's error.
        source: png::EncodingError,
    },
}
