//! Test scenes and image measures shared by the quality and backend tests: seeded samplings of
//! analytic shapes with exact normals, splat shapes from a brute-force grid k-NN through
//! [`render::splat_shape`], PSNR and gradient energy.

use glam::Vec3;
use render::{Image, Splat, splat_shape};

/// Neighbours passed to `splat_shape` (the crate doc recommends 10–16).
pub const K: usize = 16;

/// SplitMix64: a seeded generator without a dependency.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// Uniform in [0, 1).
    pub fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// A point sample: position, exact unit normal, sRGB colour.
pub type Sample = (Vec3, Vec3, [u8; 4]);

/// `n` points uniformly random by area on a torus about the y axis (major radius `big`, tube
/// `small`), tilted so neither axis is aligned with the view.
pub fn torus(
    n: usize,
    big: f32,
    small: f32,
    seed: u64,
    color: impl Fn(Vec3) -> [u8; 4],
) -> Vec<Sample> {
    let mut rng = Rng::new(seed);
    let tilt = glam::Quat::from_rotation_x(0.55) * glam::Quat::from_rotation_z(0.2);
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let u = std::f32::consts::TAU * rng.next();
        let v = std::f32::consts::TAU * rng.next();
        // Area element ∝ big + small·cos v: rejection sampling.
        if rng.next() * (big + small) > big + small * v.cos() {
            continue;
        }
        let ring = Vec3::new(u.cos(), 0.0, u.sin());
        let normal = tilt * (ring * v.cos() + Vec3::Y * v.sin());
        let p = tilt * (ring * big) + normal * small;
        out.push((p, normal, color(p)));
    }
    out
}

/// A lat-long grid on an ellipsoid of semi-axes `axes` (`rings × segments` points): strongly
/// anisotropic sampling near the poles, where the segments crowd together.
pub fn ellipsoid_grid(rings: usize, segments: usize, axes: Vec3, color: [u8; 4]) -> Vec<Sample> {
    let mut out = Vec::with_capacity(rings * segments);
    for i in 0..rings {
        let theta = std::f32::consts::PI * (i as f32 + 0.5) / rings as f32;
        for j in 0..segments {
            let phi = std::f32::consts::TAU * (j as f32 + 0.5 * (i % 2) as f32) / segments as f32;
            let s = Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            );
            let p = s * axes;
            let normal = (s / axes).normalize();
            out.push((p, normal, color));
        }
    }
    out
}

/// `n` points uniformly random on an ellipsoid (by rejection on the area element).
pub fn ellipsoid_random(n: usize, axes: Vec3, seed: u64, color: [u8; 4]) -> Vec<Sample> {
    let mut rng = Rng::new(seed);
    let mut out = Vec::with_capacity(n);
    // The map from the unit sphere scales area by a·b·c·|s / axes| ≤ a·b·c / min(axes).
    let bound = axes.x * axes.y * axes.z / axes.min_element();
    while out.len() < n {
        let z = 2.0 * rng.next() - 1.0;
        let phi = std::f32::consts::TAU * rng.next();
        let r = (1.0 - z * z).sqrt();
        let s = Vec3::new(r * phi.cos(), z, r * phi.sin());
        let p = s * axes;
        let normal = (s / axes).normalize();
        let scale = (s / axes).length() * axes.x * axes.y * axes.z;
        if rng.next() * bound > scale {
            continue;
        }
        out.push((p, normal, color));
    }
    out
}

/// The `K` nearest neighbours of every point (brute force over a uniform grid).
pub fn knn(points: &[Vec3]) -> Vec<Vec<Vec3>> {
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for p in points {
        (lo, hi) = (lo.min(*p), hi.max(*p));
    }
    let extent = (hi - lo).max(Vec3::splat(1e-6));
    // About 2 points per cell.
    let cell = (extent.x * extent.y * extent.z * 2.0 / points.len() as f32)
        .cbrt()
        .max(extent.max_element() / 256.0);
    let dims = ((extent / cell).floor() + 1.0).as_uvec3();
    let key = |p: Vec3| ((p - lo) / cell).floor().as_uvec3().min(dims - 1);
    let index = |c: glam::UVec3| ((c.z * dims.y + c.y) * dims.x + c.x) as usize;
    let mut cells = vec![Vec::new(); (dims.x * dims.y * dims.z) as usize];
    for (i, p) in points.iter().enumerate() {
        cells[index(key(*p))].push(i);
    }
    points
        .iter()
        .enumerate()
        .map(|(i, &p)| {
            let c = key(p).as_ivec3();
            let mut found: Vec<(f32, usize)> = Vec::new();
            for reach in 1i32.. {
                found.clear();
                for dz in -reach..=reach {
                    for dy in -reach..=reach {
                        for dx in -reach..=reach {
                            let q = c + glam::IVec3::new(dx, dy, dz);
                            if q.cmplt(glam::IVec3::ZERO).any() || q.cmpge(dims.as_ivec3()).any() {
                                continue;
                            }
                            for &j in &cells[index(q.as_uvec3())] {
                                if j != i {
                                    found.push((points[j].distance_squared(p), j));
                                }
                            }
                        }
                    }
                }
                found.sort_by(|a, b| a.0.total_cmp(&b.0));
                // Exact once the K-th is within the searched cube's inscribed radius.
                let inscribed = reach as f32 * cell;
                if found.len() >= K && found[K - 1].0.sqrt() <= inscribed
                    || reach as u32 > dims.max_element()
                {
                    break;
                }
            }
            found.iter().take(K).map(|&(_, j)| points[j]).collect()
        })
        .collect()
}

/// Splats of `samples` with their shapes from [`render::splat_shape`].
pub fn splats(samples: &[Sample]) -> Vec<Splat> {
    let points: Vec<Vec3> = samples.iter().map(|s| s.0).collect();
    let neighbours = knn(&points);
    samples
        .iter()
        .zip(&neighbours)
        .map(|(&(p, n, c), nb)| {
            let nb: Vec<[f32; 3]> = nb.iter().map(|q| q.to_array()).collect();
            let shape = splat_shape(p.to_array(), n.to_array(), &nb).expect("a shape");
            Splat::with_shape(p.to_array(), n.to_array(), shape, c)
        })
        .collect()
}

/// Luma (Rec. 709 weights on the sRGB bytes) of pixel `i`.
fn luma(img: &Image, i: usize) -> f32 {
    let p = &img.rgba[4 * i..4 * i + 3];
    0.2126 * p[0] as f32 + 0.7152 * p[1] as f32 + 0.0722 * p[2] as f32
}

/// PSNR in dB of the RGB bytes of `a` against `b`, over the pixels where either differs from
/// `background` (the shape, not the empty frame around it).
pub fn psnr(a: &Image, b: &Image, background: [u8; 4]) -> f64 {
    assert_eq!((a.width, a.height), (b.width, b.height));
    let (mut sum, mut count) = (0.0f64, 0usize);
    for (pa, pb) in a.rgba.chunks(4).zip(b.rgba.chunks(4)) {
        if pa == background && pb == background {
            continue;
        }
        count += 1;
        for k in 0..3 {
            let d = pa[k] as f64 - pb[k] as f64;
            sum += d * d;
        }
    }
    let mse = sum / (3 * count.max(1)) as f64;
    10.0 * (255.0f64 * 255.0 / mse.max(1e-12)).log10()
}

/// Σ |∇ luma|² (forward differences in x and y) over the pixels where `mask` holds.
pub fn gradient_energy(img: &Image, mask: &[bool]) -> f64 {
    let (w, h) = (img.width as usize, img.height as usize);
    let mut e = 0.0f64;
    for y in 0..h - 1 {
        for x in 0..w - 1 {
            if !mask[y * w + x] {
                continue;
            }
            let c = luma(img, y * w + x);
            let dx = luma(img, y * w + x + 1) - c;
            let dy = luma(img, (y + 1) * w + x) - c;
            e += (dx * dx + dy * dy) as f64;
        }
    }
    e
}

/// The pixels of the shape's inside in both images: neither image shows the background within
/// `margin` pixels (the silhouettes, where splats protrude by up to r²/2R, are left out).
pub fn interior(a: &Image, b: &Image, background: [u8; 4], margin: i32) -> Vec<bool> {
    let (w, h) = (a.width as i32, a.height as i32);
    let bg = |img: &Image, x: i32, y: i32| {
        x < 0 || y < 0 || x >= w || y >= h || img.pixel(x as u32, y as u32) == background
    };
    let mut near_bg = vec![false; (w * h) as usize];
    for y in 0..h {
        for x in 0..w {
            if bg(a, x, y) || bg(b, x, y) {
                for dy in -margin..=margin {
                    for dx in -margin..=margin {
                        let (u, v) = (x + dx, y + dy);
                        if u >= 0 && v >= 0 && u < w && v < h {
                            near_bg[(v * w + u) as usize] = true;
                        }
                    }
                }
            }
        }
    }
    near_bg.into_iter().map(|n| !n).collect()
}

/// Where test images go, to be looked at: `$RENDER_TEST_PNG_DIR` or the temp dir.
pub fn save(img: &Image, name: &str) {
    let dir = std::env::var_os("RENDER_TEST_PNG_DIR")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::env::temp_dir().join("render-tests"));
    std::fs::create_dir_all(&dir).unwrap();
    img.save_png(dir.join(format!("{name}.png"))).unwrap();
}

/// PSNR of the RGB bytes of `a` against `b` over the pixels where `mask` holds.
pub fn psnr_masked(a: &Image, b: &Image, mask: &[bool]) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for (i, (pa, pb)) in a.rgba.chunks(4).zip(b.rgba.chunks(4)).enumerate() {
        if mask[i] {
            n += 1;
            sum += (0..3)
                .map(|k| (pa[k] as f64 - pb[k] as f64).powi(2))
                .sum::<f64>();
        }
    }
    10.0 * (255.0f64 * 255.0 / (sum / (3 * n.max(1)) as f64).max(1e-12)).log10()
}

/// PSNR over every pixel, over pixels where both are not background, and the count of pixels
/// where exactly one is background.
pub fn psnr_parts(a: &Image, b: &Image, background: [u8; 4]) -> (f64, f64, usize) {
    let (mut all, mut both, mut nboth, mut one) = (0.0f64, 0.0f64, 0usize, 0usize);
    for (pa, pb) in a.rgba.chunks(4).zip(b.rgba.chunks(4)) {
        let d: f64 = (0..3).map(|k| (pa[k] as f64 - pb[k] as f64).powi(2)).sum();
        all += d;
        match (pa == background, pb == background) {
            (false, false) => {
                both += d;
                nboth += 1;
            }
            (true, true) => {}
            _ => one += 1,
        }
    }
    let db = |s: f64, n: usize| 10.0 * (255.0f64 * 255.0 / (s / (3 * n) as f64).max(1e-12)).log10();
    (db(all, a.rgba.len() / 4), db(both, nboth), one)
}

/// Saves the `w × h` crop at `(x, y)` of `img`, enlarged `k` times (nearest), to look at.
pub fn save_crop(img: &Image, name: &str, (x, y, w, h): (u32, u32, u32, u32), k: u32) {
    let mut out = Image {
        width: w * k,
        height: h * k,
        rgba: Vec::with_capacity((w * h * k * k * 4) as usize),
    };
    for j in 0..h * k {
        for i in 0..w * k {
            out.rgba.extend_from_slice(&img.pixel(x + i / k, y + j / k));
        }
    }
    save(&out, name);
}

/// Background pixels of `img` with shape pixels within 4 px in each of the four axial
/// directions: holes (a silhouette's concave bay is open on at least one side).
pub fn holes(img: &Image, background: [u8; 4]) -> usize {
    let (w, h) = (img.width as i32, img.height as i32);
    let shape = |x: i32, y: i32| {
        x >= 0 && y >= 0 && x < w && y < h && img.pixel(x as u32, y as u32) != background
    };
    let mut n = 0;
    for y in 0..h {
        for x in 0..w {
            if shape(x, y) {
                continue;
            }
            let dirs = [(1, 0), (-1, 0), (0, 1), (0, -1)];
            if dirs
                .iter()
                .all(|(dx, dy)| (1..=4).any(|k| shape(x + k * dx, y + k * dy)))
            {
                n += 1;
            }
        }
    }
    n
}
