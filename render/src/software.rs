//! [`SoftwareRenderer`]: the same three splatting passes and the same overlays as the GPU
//! [`Renderer`](crate::Renderer), on the CPU with rayon. The reference GPU images are tested
//! against, and the path where no Vulkan driver exists.

use glam::{Vec3, Vec4};
use rayon::prelude::*;

use crate::{
    Camera, Image, Overlay, RenderError, Splat, Style,
    ewa::{self, FrameParams, MIN_WEIGHT, SplatSetup},
    geometry::{Mesh, OverlayInstances, unit_cone, unit_sphere},
    raster::{self, Tri},
    scene::{SrgbEncoder, srgb_to_linear},
};

/// Rows per band: the unit of parallel work (a band's buffers stay in cache).
const BAND: u32 = 8;
/// Largest image side (as the GPU's usual limit).
const MAX_SIDE: u32 = 16384;

/// Per-pixel accumulation of the attribute pass: Σw·albedo, Σw, Σw·normal.
#[derive(Clone, Copy, Debug, Default)]
struct Accum {
    color: Vec3,
    weight: f32,
    normal: Vec3,
}

/// Draws splats and overlays on the CPU into an [`Image`] (see the crate doc for the passes).
///
/// Allocation: its buffers grow with the target size and the largest splat count seen and are
/// reused; a frame allocates nothing of its own once sized (rayon's scheduler aside).
pub struct SoftwareRenderer {
    style: Style,
    width: u32,
    height: u32,
    depth: Vec<f32>,
    accum: Vec<Accum>,
    color: Vec<Vec4>,
    setups: Vec<Option<SplatSetup>>,
    band_start: Vec<u32>,
    band_fill: Vec<u32>,
    refs: Vec<u32>,
    overlay: OverlayInstances,
    tris: Vec<Tri>,
    sphere: Mesh,
    cone: Mesh,
}

impl std::fmt::Debug for SoftwareRenderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SoftwareRenderer")
            .field("size", &(self.width, self.height))
            .field("threads", &rayon::current_num_threads())
            .finish_non_exhaustive()
    }
}

impl SoftwareRenderer {
    /// A renderer of `width × height` images.
    pub fn new(width: u32, height: u32) -> Result<Self, RenderError> {
        let mut r = Self {
            style: Style::default(),
            width: 0,
            height: 0,
            depth: Vec::new(),
            accum: Vec::new(),
            color: Vec::new(),
            setups: Vec::new(),
            band_start: Vec::new(),
            band_fill: Vec::new(),
            refs: Vec::new(),
            overlay: OverlayInstances::default(),
            tris: Vec::new(),
            sphere: unit_sphere(24, 48),
            cone: unit_cone(32),
        };
        r.resize(width, height)?;
        Ok(r)
    }

    /// The current style.
    pub fn style(&self) -> &Style {
        &self.style
    }

    /// Replaces the style used from the next frame on.
    pub fn set_style(&mut self, style: Style) {
        self.style = style;
    }

    /// The image size.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Changes the image size (allocates when it grows).
    pub fn resize(&mut self, width: u32, height: u32) -> Result<(), RenderError> {
        if width == 0 || height == 0 || width > MAX_SIDE || height > MAX_SIDE {
            return Err(RenderError::InvalidSize {
                width,
                height,
                max: MAX_SIDE,
            });
        }
        let n = (width * height) as usize;
        self.depth.resize(n, 1.0);
        self.accum.resize(n, Accum::default());
        self.color.resize(n, Vec4::ZERO);
        self.band_start
            .resize(height.div_ceil(BAND) as usize + 1, 0);
        self.band_fill.resize(height.div_ceil(BAND) as usize, 0);
        (self.width, self.height) = (width, height);
        Ok(())
    }

    /// Renders one frame into a new image; see [`SoftwareRenderer::render_into`].
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

    /// Renders one frame into `image` (its buffer is reused). Validates every input first; on
    /// error `image` is unchanged.
    pub fn render_into(
        &mut self,
        splats: &[Splat],
        overlay: &Overlay,
        camera: &Camera,
        image: &mut Image,
    ) -> Result<(), RenderError> {
        camera.validate()?;
        if let Some(index) = splats.iter().position(|s| !s.is_valid()) {
            return Err(RenderError::NonFinite {
                what: "splat",
                index,
            });
        }
        let (width, height) = (self.width, self.height);
        self.overlay.build(overlay, camera, height, &self.style)?;
        let f = FrameParams::new(camera, (width, height), &self.style);
        raster::build(&mut self.tris, &self.overlay, &self.sphere, &self.cone, &f);

        // Set-up, then binning of the splats into bands of rows (a counting sort).
        if self.setups.len() < splats.len() {
            self.setups.resize(splats.len(), None);
        }
        let setups = &mut self.setups[..splats.len()];
        setups
            .par_iter_mut()
            .zip(splats.par_iter())
            .with_min_len(4096)
            .for_each(|(dst, s)| *dst = ewa::setup(s, &f));
        let bands = height.div_ceil(BAND) as usize;
        let rows_of = |s: &SplatSetup| {
            let y0 = ((s.bbox.y - 0.5).ceil().max(0.0) as u32).min(height);
            let y1 = ((s.bbox.w - 0.5).ceil().max(0.0) as u32).min(height);
            let visible = y0 < y1 && s.bbox.z > 0.0 && s.bbox.x < width as f32;
            visible.then(|| (y0 / BAND, (y1 - 1) / BAND))
        };
        self.band_fill[..bands].fill(0);
        for s in setups.iter().flatten() {
            if let Some((b0, b1)) = rows_of(s) {
                for b in b0..=b1 {
                    self.band_fill[b as usize] += 1;
                }
            }
        }
        let mut total = 0;
        for b in 0..bands {
            self.band_start[b] = total;
            total += self.band_fill[b];
            self.band_fill[b] = self.band_start[b];
        }
        self.band_start[bands] = total;
        if self.refs.len() < total as usize {
            self.refs.resize(total as usize, 0);
        }
        for (i, s) in setups.iter().enumerate() {
            if let Some((b0, b1)) = s.as_ref().and_then(rows_of) {
                for b in b0..=b1 {
                    let slot = &mut self.band_fill[b as usize];
                    self.refs[*slot as usize] = i as u32;
                    *slot += 1;
                }
            }
        }

        // The passes, band by band in parallel.
        let n = (width * height) as usize;
        image.width = width;
        image.height = height;
        image.rgba.resize(n * 4, 0);
        let band_px = (BAND * width) as usize;
        let (setups, refs, starts) = (&self.setups[..], &self.refs[..], &self.band_start[..]);
        let (tris, style) = (&self.tris[..], &self.style);
        // Visibility and attributes per band, then (the outline test reads the rows around)
        // normalisation, overlays and encoding per band.
        self.depth[..n]
            .par_chunks_mut(band_px)
            .zip(self.accum[..n].par_chunks_mut(band_px))
            .enumerate()
            .for_each(|(b, (depth, accum))| {
                let ids = &refs[starts[b] as usize..starts[b + 1] as usize];
                let band = Band {
                    f: &f,
                    width,
                    y0: b as u32 * BAND,
                    rows: depth.len() as u32 / width,
                };
                band.splats(ids, setups, depth, accum);
            });
        let accum = &self.accum[..n];
        self.depth[..n]
            .par_chunks_mut(band_px)
            .zip(self.color[..n].par_chunks_mut(band_px))
            .zip(image.rgba.par_chunks_mut(band_px * 4))
            .enumerate()
            .for_each(|(b, ((depth, color), rgba))| {
                let y0 = b as u32 * BAND;
                let band = Band {
                    f: &f,
                    width,
                    y0,
                    rows: depth.len() as u32 / width,
                };
                band.normalise(accum, color, style);
                raster::draw_band(
                    tris,
                    color,
                    depth,
                    width,
                    y0,
                    band.rows,
                    &f,
                    &style.lighting,
                );
                encode(color, rgba);
            });
        Ok(())
    }
}

/// One band of rows of the frame.
struct Band<'a> {
    f: &'a FrameParams,
    width: u32,
    y0: u32,
    rows: u32,
}

impl Band<'_> {
    /// Calls `visit(pixel index, sample)` for every pixel of splat `s` in this band.
    #[inline]
    fn each(&self, s: &SplatSetup, mut visit: impl FnMut(usize, ewa::Sample)) {
        let ys = ((s.bbox.y - 0.5).ceil().max(0.0) as u32).max(self.y0);
        let ye = ((s.bbox.w - 0.5).ceil().max(0.0) as u32).min(self.y0 + self.rows);
        let xs = (s.bbox.x - 0.5).ceil().max(0.0) as u32;
        let xe = ((s.bbox.z - 0.5).ceil().max(0.0) as u32).min(self.width);
        for y in ys..ye {
            let row = ((y - self.y0) * self.width) as usize;
            let py = y as f32 + 0.5;
            for x in xs..xe {
                if let Some(sample) = ewa::eval(s, self.f, x as f32 + 0.5, py) {
                    visit(row + x as usize, sample);
                }
            }
        }
    }

    /// Pass 1 (visibility: nearest pushed-back depth) and pass 2 (attributes within it).
    fn splats(
        &self,
        ids: &[u32],
        setups: &[Option<SplatSetup>],
        depth: &mut [f32],
        accum: &mut [Accum],
    ) {
        depth.fill(1.0);
        accum.fill(Accum::default());
        let each = |id: &u32| setups[*id as usize].as_ref().expect("binned splats exist");
        for s in ids.iter().map(each) {
            self.each(s, |i, sm| depth[i] = depth[i].min(sm.depth_pushed));
        }
        for s in ids.iter().map(each) {
            self.each(s, |i, sm| {
                if sm.depth <= depth[i] {
                    let a = &mut accum[i];
                    a.color += sm.weight * s.albedo;
                    a.weight += sm.weight;
                    a.normal += sm.weight
                        * if sm.graze {
                            let x = (i as u32 % self.width) as f32 + 0.5;
                            let y = (self.y0 + i as u32 / self.width) as f32 + 0.5;
                            ewa::graze_normal(s.normal, self.f.eye_dir(x, y))
                        } else {
                            ewa::hit_normal(s, sm.uv)
                        };
                }
            });
        }
    }

    /// Pass 3: normalisation and deferred headlight shading; the background (linear) where
    /// nothing weighs. `accum` is the whole frame's (the outline test reads the pixels around);
    /// `color` this band's.
    fn normalise(&self, accum: &[Accum], color: &mut [Vec4], style: &Style) {
        let light = &style.lighting;
        let [r, g, b, a] = style.background;
        let bg = Vec4::new(
            srgb_to_linear(r),
            srgb_to_linear(g),
            srgb_to_linear(b),
            a as f32 / 255.0,
        );
        let (w, h) = (self.width as usize, accum.len() / self.width as usize);
        let first = self.y0 as usize * w;
        let empty = |x: usize, y: usize| accum[y * w + x].weight < MIN_WEIGHT;
        for (k, c) in color.iter_mut().enumerate() {
            let i = first + k;
            let a = &accum[i];
            if a.weight < MIN_WEIGHT {
                *c = bg;
                continue;
            }
            let (px, py) = (i % w, i / w);
            let l = self.f.eye_dir(px as f32 + 0.5, py as f32 + 0.5);
            let mut n = a.normal.try_normalize().unwrap_or(l);
            let outline = (px > 0 && empty(px - 1, py))
                || (px + 1 < w && empty(px + 1, py))
                || (py > 0 && empty(px, py - 1))
                || (py + 1 < h && empty(px, py + 1));
            if outline && n.dot(l).abs() < ewa::CONTOUR_BELOW {
                n = ewa::graze_normal(n, l);
            }
            let albedo = a.color / a.weight;
            let d = n.dot(l).abs().min(1.0);
            *c = Vec3::from(light.shade(albedo.to_array(), d)).extend(1.0);
        }
    }
}

/// Linear RGBA to sRGB bytes (alpha linear), as an sRGB render target stores them.
fn encode(color: &[Vec4], rgba: &mut [u8]) {
    let srgb = SrgbEncoder::get();
    for (c, out) in color.iter().zip(rgba.chunks_exact_mut(4)) {
        out[0] = srgb.encode(c.x);
        out[1] = srgb.encode(c.y);
        out[2] = srgb.encode(c.z);
        out[3] = (c.w.clamp(0.0, 1.0) * 255.0).round() as u8;
    }
}
