//! [`HeadlessRenderer`]: frames into [`Image`]s on the GPU when there is a Vulkan driver, else
//! on the CPU, behind one type.

use crate::{Camera, Image, Overlay, RenderError, Renderer, SoftwareRenderer, Splat, Style};

/// Which renderer draws the frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    /// wgpu on a Vulkan adapter (a GPU, or Mesa's lavapipe).
    Gpu,
    /// [`SoftwareRenderer`] on the CPU.
    Software,
}

/// What the caller asks for (e.g. a `--renderer auto|gpu|software` flag).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BackendChoice {
    /// The GPU if a Vulkan adapter is found, else the software renderer; the environment
    /// variable `HAPTIC_RENDER=gpu|software|auto` overrides it.
    #[default]
    Auto,
    /// The GPU or an error.
    Gpu,
    /// The software renderer.
    Software,
}

/// Name of the environment variable [`BackendChoice::Auto`] honours.
pub const BACKEND_ENV: &str = "HAPTIC_RENDER";

impl std::str::FromStr for BackendChoice {
    type Err = RenderError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "auto" => Ok(Self::Auto),
            "gpu" => Ok(Self::Gpu),
            "software" | "cpu" => Ok(Self::Software),
            _ => Err(RenderError::UnknownBackend(s.to_string())),
        }
    }
}

enum Inner {
    Gpu(Box<Renderer>),
    Software(Box<SoftwareRenderer>),
}

/// Headless frames on the backend chosen at construction (see [`BackendChoice`]).
pub struct HeadlessRenderer {
    inner: Inner,
    fallback: Option<String>,
}

impl std::fmt::Debug for HeadlessRenderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HeadlessRenderer")
            .field("backend", &self.describe())
            .field("fallback", &self.fallback)
            .finish()
    }
}

impl HeadlessRenderer {
    /// A renderer of `width × height` frames. `Auto` (after [`BACKEND_ENV`]) takes a GPU; on a
    /// CPU implementation of Vulkan (lavapipe) it takes the software renderer, which draws
    /// the same splats faster there; and it falls back to software when no Vulkan adapter or
    /// device is available ([`HeadlessRenderer::fallback_reason`] says why, with how to get
    /// the fast path). `Gpu` returns that error instead.
    pub fn new(width: u32, height: u32, choice: BackendChoice) -> Result<Self, RenderError> {
        let choice = match choice {
            BackendChoice::Auto => match std::env::var(BACKEND_ENV) {
                Ok(v) => v.parse()?,
                Err(_) => BackendChoice::Auto,
            },
            c => c,
        };
        let software = |fallback| -> Result<Self, RenderError> {
            Ok(Self {
                inner: Inner::Software(Box::new(SoftwareRenderer::new(width, height)?)),
                fallback,
            })
        };
        match choice {
            BackendChoice::Software => software(None),
            BackendChoice::Gpu => Ok(Self {
                inner: Inner::Gpu(Box::new(Renderer::headless(width, height)?)),
                fallback: None,
            }),
            BackendChoice::Auto => match Renderer::headless(width, height) {
                Ok(r) if r.is_cpu_adapter() => software(None),
                Ok(r) => Ok(Self {
                    inner: Inner::Gpu(Box::new(r)),
                    fallback: None,
                }),
                Err(e @ (RenderError::NoAdapter(_) | RenderError::RequestDevice { .. })) => {
                    software(Some(e.to_string()))
                }
                Err(e) => Err(e),
            },
        }
    }

    /// The backend drawing the frames.
    pub fn backend(&self) -> Backend {
        match self.inner {
            Inner::Gpu(_) => Backend::Gpu,
            Inner::Software(_) => Backend::Software,
        }
    }

    /// Why `Auto` chose the software renderer (the GPU error, with how to install the driver),
    /// or `None`.
    pub fn fallback_reason(&self) -> Option<&str> {
        self.fallback.as_deref()
    }

    /// The adapter (`"llvmpipe (…) (Vulkan, Cpu)"`) or `"software (N threads)"`.
    pub fn describe(&self) -> String {
        match &self.inner {
            Inner::Gpu(r) => r.adapter_info(),
            Inner::Software(_) => format!("software ({} threads)", rayon::current_num_threads()),
        }
    }

    /// The current style.
    pub fn style(&self) -> &Style {
        match &self.inner {
            Inner::Gpu(r) => r.style(),
            Inner::Software(r) => r.style(),
        }
    }

    /// Replaces the style used from the next frame on.
    pub fn set_style(&mut self, style: Style) {
        match &mut self.inner {
            Inner::Gpu(r) => r.set_style(style),
            Inner::Software(r) => r.set_style(style),
        }
    }

    /// Changes the frame size (allocates; a no-op on the GPU if unchanged).
    pub fn resize(&mut self, width: u32, height: u32) -> Result<(), RenderError> {
        match &mut self.inner {
            Inner::Gpu(r) => r.resize(width, height),
            Inner::Software(r) => r.resize(width, height),
        }
    }

    /// One frame into `image` (its buffer is reused).
    pub fn render_into(
        &mut self,
        splats: &[Splat],
        overlay: &Overlay,
        camera: &Camera,
        image: &mut Image,
    ) -> Result<(), RenderError> {
        match &mut self.inner {
            Inner::Gpu(r) => r.render_into(splats, overlay, camera, image),
            Inner::Software(r) => r.render_into(splats, overlay, camera, image),
        }
    }

    /// One frame into a new image.
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
}
