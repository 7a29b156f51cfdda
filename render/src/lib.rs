//! `render`: the sculpting scene as high-quality surface splats (DESIGN §6b; Zwicker et al.
//! 2001, Botsch, Hornung, Zwicker & Kobbelt 2005) with its overlays, on the GPU (wgpu,
//! [`Renderer`]) or on the CPU ([`SoftwareRenderer`], the reference and the fallback), headless
//! into RGBA/PNG ([`HeadlessRenderer`] picks the backend) and into a window's surface with the
//! same [`Renderer`].
//!
//! A splat ([`Splat`]) is an ellipse in the tangent plane of its normal: semi-axes `radius`
//! along its tangent `axis` and `minor_radius` across (a disk when `axis` is zero), sized by
//! the caller from the local spacing ([`splat_shape`] does it from a point's neighbours), and
//! carrying the surface's curvature there ([`Splat::curvature`], zero for a flat splat). What
//! a frame draws, in this order:
//! 1. **visibility**: every splat writes, per pixel, the depth where the pixel's ray meets its
//!    plane (exact ray casting through the ellipse's homography), pushed back in view depth by
//!    ε = [`EPS_FRACTION`]·radius + [`EPS_PX`] pixel footprints, nearest wins; near a silhouette
//!    the part of the plane the ray reaches beyond the curved surface's outline is cut off
//!    (the ray must meet the osculating paraboloid);
//! 2. **attributes**: every splat fragment within ε of that front (depth test, no write) adds
//!    w·albedo (linear), w and w·normal (the curved surface's normal at the hit, `n + K·x`,
//!    Phong splatting; turned to face the eye) into float sums (GPU:
//!    two `Rgba16Float` targets, additive blending), with w the Gaussian of the fragment's
//!    elliptical distance d: `(exp(-K d²) − e^-K) / (1 − e^-K)`, K = [`GAUSS_K`] (σ = radius/2,
//!    truncated and zero at the ellipse's edge);
//! 3. **normalisation**: per pixel, albedo = Σw·albedo / Σw and the normal of Σw·normal are
//!    shaded with the headlight ([`Lighting`]: Lambert with ambient and a white specular,
//!    two-sided, in linear colour); pixels with Σw < [`MIN_WEIGHT`] keep the background;
//! 4. the **overlays** ([`Overlay`]), depth-tested against the splats' (pushed-back) depth: the
//!    cursor and contact point (spheres of constant screen size), the force arrow's head, the
//!    region box's 12 edges and the arrow's shaft as lines of a width in pixels, and the
//!    translucent probe ellipsoid (alpha-blended, front faces).
//!
//! Screen-space pre-filter: a pixel within [`PREFILTER_PX`] of a splat's projected centre takes
//! the smaller of its object-space and screen-space elliptical distances (Botsch et al.'s
//! approximation of the EWA filter): a splat never covers less than that disk, so far or tiny
//! splats neither vanish between pixel centres nor alias. Targets are sRGB; the hardware (or
//! [`linear_to_srgb`]) encodes. The GPU and the software renderer share this math (`ewa.rs` is
//! mirrored line by line in `shaders.wgsl`) and agree to ~60 dB PSNR.
//!
//! Contract:
//! - No global state. A [`Renderer`] owns its wgpu device, queue, pipelines and buffers; a
//!   [`SoftwareRenderer`] its buffers; several can coexist.
//! - Allocation: the GPU's splat buffer grows (to the next power of two) when a frame has more
//!   splats than any before and never shrinks; its accumulation targets are made when the frame
//!   size changes; overlay buffers have a fixed size. The software renderer's per-pixel,
//!   per-splat and binning buffers grow likewise and are reused. Once sized, a frame allocates
//!   nothing of ours (wgpu allocates a little per command encoder, rayon per job). The most
//!   splats per GPU frame is the storage binding size / 64 bytes
//!   ([`RenderError::TooManySplats`]). `render` allocates the [`Image`] it returns
//!   (`render_into` reuses one).
//! - [`Renderer::draw`] records into a caller's encoder and colour/depth views, so a window can
//!   reuse the renderer unchanged: make the device with the surface's adapter, call
//!   [`Renderer::with_device`] with the surface's (sRGB) format, create a depth view with
//!   [`Renderer::create_depth_view`], and `draw` into each frame's surface texture view.
//! - Inputs are validated at the boundary: a non-finite splat or overlay value, a negative
//!   radius, or an invalid camera, is an error that names it, and nothing is drawn.
//!
//! Backends: wgpu 30 with Vulkan only (features `std`, `vulkan`, `wgsl`). Without a GPU it runs
//! on Mesa's software Vulkan driver, lavapipe (Debian `mesa-vulkan-drivers` + `libvulkan1`,
//! which CI installs). Without any Vulkan driver, [`HeadlessRenderer`] in
//! [`BackendChoice::Auto`] falls back to [`SoftwareRenderer`] and says why. In a session
//! without a display, Mesa may print `XDG_RUNTIME_DIR is invalid or not set` on stderr when the
//! instance is made: harmless. Frame times: docs/BENCHMARKS.md, "Headless renderer".

mod camera;
mod ewa;
mod geometry;
mod headless;
mod image;
mod lod;
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
pub use lod::{THIN_MARGIN, thin_splats};
pub use renderer::Renderer;
pub use scene::{Ellipsoid, Lighting, Overlay, Splat, Style, linear_to_srgb, srgb_to_linear};
pub use shape::{
    CORNER_MARGIN, MAX_CELL_GROWTH, MAX_SHAPE_NEIGHBOURS, MIN_SPLAT_ASPECT, SPLAT_OVERLAP,
    SplatShape, splat_shape,
};
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
        /// Most splats one frame can draw (storage binding size / 64 bytes).
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
