//! What surface splatting is for (issue 19): a sparse and a dense sampling of one smooth shape
//! render alike (no disk rims, no scales), a paint edge stays an edge, tiny far splats neither
//! vanish nor leave holes. On the software renderer: it runs the same passes and math as the
//! GPU (`backends.rs` checks they agree), and it is fast at 200k splats.

use glam::Vec3;
use render::{Camera, Image, Overlay, SoftwareRenderer, Splat, Style};

use crate::scenes::{self, Sample, gradient_energy, psnr, save};

/// The bounds every sparse/dense pair meets: the issue's ≥ 35 dB over the frame (here ≥
/// `min_psnr`, set under what each scene measured: 41.7 dB torus, 41.4 and 42.0 dB the
/// ellipsoids, docs/BENCHMARKS.md), ≥ 48 dB inside the silhouettes (51.2–54.5), the issue's
/// gradient-energy ratio 0.8–1.25 inside them (1.03) and over the whole frame, outlines included
/// (1.05–1.10), and no holes. Over the frame it was 1.48–1.75 (light flecks along every
/// outline) before the outlines' pixels took the curved surface's normal where the eye's ray
/// meets it (`ewa::hit_normal`), splats just behind an outline kept their own normal
/// (`ewa::TURN_BELOW`), pixels only a cut splat's pre-filter covers took its grazing normal
/// (`ewa::graze_normal`), and pixels next to the background whose normal is near grazing took
/// the grazing one (`ewa::CONTOUR_BELOW`): 1.16–1.29 before the last. With flat splats (before
/// `Splat::curvature`: no silhouette cut, the plane's normal everywhere) the torus measured
/// 31.4 dB over the frame and 41.9 dB inside.
fn assert_alike(c: &Comparison, min_psnr: f64) {
    assert_eq!(c.holes, 0, "{c:?}");
    assert!(c.psnr >= min_psnr, "{c:?}");
    assert!(c.psnr_inside >= 48.0, "{c:?}");
    assert!((0.8..=1.25).contains(&c.energy_inside), "{c:?}");
    assert!((0.8..=1.25).contains(&c.energy), "{c:?}");
}

const W: u32 = 1280;
const H: u32 = 720;

fn render(splats: &[Splat], camera: &Camera, (w, h): (u32, u32)) -> Image {
    let mut r = SoftwareRenderer::new(w, h).unwrap();
    r.render(splats, &Overlay::default(), camera).unwrap()
}

fn bounds(samples: &[Sample]) -> ([f32; 3], [f32; 3]) {
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for s in samples {
        (lo, hi) = (lo.min(s.0), hi.max(s.0));
    }
    (lo.to_array(), hi.to_array())
}

/// How a sparse render compares with a dense one of the same shape.
#[derive(Debug)]
#[allow(dead_code)] // `silhouette_px` is reported (Debug), not bounded.
struct Comparison {
    /// PSNR over the whole frame (background included, as the issue measured the disks).
    psnr: f64,
    /// PSNR over the shape's inside (both not background, 3 px from any silhouette).
    psnr_inside: f64,
    /// Sparse / dense gradient energy over that inside: > 1 is rims and scales.
    energy_inside: f64,
    /// Sparse / dense gradient energy over the whole frame (silhouettes included).
    energy: f64,
    /// Pixels that are background in exactly one of the two (silhouette bulges).
    silhouette_px: usize,
    /// Holes in either render (see `scenes::holes`).
    holes: usize,
}

/// Renders `sparse` and `dense` from one camera and compares them.
fn compare(name: &str, sparse: &[Sample], dense: &[Sample], view: [f32; 3]) -> Comparison {
    let (lo, hi) = bounds(dense);
    let camera = Camera::framing(lo, hi, view);
    let a = render(&scenes::splats(sparse), &camera, (W, H));
    let b = render(&scenes::splats(dense), &camera, (W, H));
    save(&a, &format!("{name}_sparse"));
    save(&b, &format!("{name}_dense"));
    scenes::save_crop(&a, &format!("{name}_sparse_crop"), (520, 180, 200, 130), 4);
    scenes::save_crop(&b, &format!("{name}_dense_crop"), (520, 180, 200, 130), 4);
    let bg = Style::default().background;
    let everywhere = vec![true; (W * H) as usize];
    let inside = scenes::interior(&a, &b, bg, 3);
    let (psnr, _, silhouette_px) = scenes::psnr_parts(&a, &b, bg);
    let c = Comparison {
        psnr,
        psnr_inside: scenes::psnr_masked(&a, &b, &inside),
        energy_inside: gradient_energy(&a, &inside) / gradient_energy(&b, &inside),
        energy: gradient_energy(&a, &everywhere) / gradient_energy(&b, &everywhere),
        silhouette_px,
        holes: scenes::holes(&a, bg) + scenes::holes(&b, bg),
    };
    eprintln!("{name}: {} vs {} points: {c:?}", sparse.len(), dense.len());
    c
}

/// A colour that varies smoothly over the shape (so colour interpolation is compared too).
fn clay(p: Vec3) -> [u8; 4] {
    let t = 0.5 + 0.5 * (p.x * 25.0).sin() * (p.z * 18.0).cos();
    [
        (200.0 - 60.0 * t) as u8,
        (140.0 + 40.0 * t) as u8,
        (100.0 + 20.0 * t) as u8,
        255,
    ]
}

/// A 3,000-point torus against a 200,000-point one: the case (see `assert_alike`).
#[test]
fn sparse_and_dense_torus_render_alike() {
    let sparse = scenes::torus(3_000, 0.06, 0.025, 1, clay);
    let dense = scenes::torus(200_000, 0.06, 0.025, 2, clay);
    assert_alike(&compare("torus", &sparse, &dense, [0.2, -0.5, -1.0]), 39.0);
}

/// Anisotropic sampling: a lat-long grid crowds its points along the parallels near the poles;
/// the splats stretch across them (`splat_shape`) and must still match a dense random sampling.
#[test]
fn anisotropic_ellipsoid_grid_renders_like_a_dense_sampling() {
    let axes = Vec3::new(0.07, 0.045, 0.035);
    let color = [120, 170, 210, 255];
    let sparse = scenes::ellipsoid_grid(40, 80, axes, color);
    let dense = scenes::ellipsoid_random(200_000, axes, 3, color);
    assert_alike(
        &compare("ellipsoid", &sparse, &dense, [0.3, -0.8, -1.0]),
        40.0,
    );
}

/// A random sampling of the same ellipsoid, sparse against dense.
#[test]
fn sparse_and_dense_random_ellipsoid_render_alike() {
    let axes = Vec3::new(0.07, 0.045, 0.035);
    let sparse = scenes::ellipsoid_random(3_000, axes, 4, [200, 160, 120, 255]);
    let dense = scenes::ellipsoid_random(200_000, axes, 5, [200, 160, 120, 255]);
    assert_alike(
        &compare("ellipsoid_random", &sparse, &dense, [0.3, -0.8, -1.0]),
        40.0,
    );
}

/// Points uniformly random on the square `[-l, l]²` in the z = 0 plane (normal +z), red left of
/// the slanted line `x = 0.15·y`, blue right of it: paint.
fn painted_square(n: usize, l: f32, seed: u64) -> Vec<Sample> {
    let mut rng = scenes::Rng::new(seed);
    (0..n)
        .map(|_| {
            let p = Vec3::new(
                l * (2.0 * rng.next() - 1.0),
                l * (2.0 * rng.next() - 1.0),
                0.0,
            );
            let c = if p.x < 0.15 * p.y {
                [220, 40, 40, 255]
            } else {
                [40, 60, 220, 255]
            };
            (p, Vec3::Z, c)
        })
        .collect()
}

/// Per image row through the square's middle: where the red→blue transition crosses half way
/// (pixels, interpolated) and its 10–90 % width. The paint fraction of a pixel is its red minus
/// blue byte, scaled between the row's pure ends.
fn edge_profile(
    img: &Image,
    rows: std::ops::Range<u32>,
    cols: std::ops::Range<u32>,
) -> Vec<(f32, f32)> {
    rows.map(|y| {
        let t: Vec<f32> = cols
            .clone()
            .map(|x| {
                let p = img.pixel(x, y);
                p[0] as f32 - p[2] as f32
            })
            .collect();
        let (red, blue) = (t[0], t[t.len() - 1]);
        let frac: Vec<f32> = t.iter().map(|v| (red - v) / (red - blue)).collect();
        let cross = |level: f32| {
            let i = frac.iter().position(|&f| f >= level).expect("crosses");
            let (a, b) = (frac[i.max(1) - 1], frac[i]);
            (i.max(1) - 1) as f32 + if b > a { (level - a) / (b - a) } else { 0.0 }
        };
        (cross(0.5) + cols.start as f32, cross(0.9) - cross(0.1))
    })
    .collect()
}

/// RMS distance of the crossings from their least-squares line, and the mean 10–90 % width.
fn edge_stats(profile: &[(f32, f32)]) -> (f32, f32) {
    let n = profile.len() as f32;
    let ys: Vec<f32> = (0..profile.len()).map(|i| i as f32).collect();
    let (my, mx) = (
        ys.iter().sum::<f32>() / n,
        profile.iter().map(|p| p.0).sum::<f32>() / n,
    );
    let sxy: f32 = ys
        .iter()
        .zip(profile)
        .map(|(y, p)| (y - my) * (p.0 - mx))
        .sum();
    let syy: f32 = ys.iter().map(|y| (y - my) * (y - my)).sum();
    let slope = sxy / syy;
    let rms = (ys
        .iter()
        .zip(profile)
        .map(|(y, p)| (p.0 - (mx + slope * (y - my))).powi(2))
        .sum::<f32>()
        / n)
        .sqrt();
    let width = profile.iter().map(|p| p.1).sum::<f32>() / n;
    (rms, width)
}

/// A paint stroke's edge on a sparse random sampling: the crossing of the blended colours
/// wanders < 0.5 h (RMS) from a straight line and the 10–90 % transition is < 2 h wide, `h` the
/// sparse spacing in pixels (measured: 0.3 h and 1.75 h; the Gaussian's σ is half a splat
/// radius, ~h/2, and the samples' own randomness puts the reconstructed edge ~h/3 off the
/// line). The dense sampling's edge is within a pixel of straight and < 3 px wide. The
/// Poisson sampling's gaps are covered (splats grow to their Voronoi cells' corners where they
/// face the eye; before that one gap of 12 pixels stayed open): no hole pixel.
#[test]
fn paint_edge_stays_an_edge() {
    let l = 0.05;
    let (n_sparse, n_dense) = (3_000, 200_000);
    let sparse = painted_square(n_sparse, l, 5);
    let dense = painted_square(n_dense, l, 6);
    let camera = Camera::framing([-l, -l, 0.0], [l, l, 0.0], [0.0, 0.0, -1.0]);
    let a = render(&scenes::splats(&sparse), &camera, (W, H));
    let b = render(&scenes::splats(&dense), &camera, (W, H));
    save(&a, "edge_sparse");
    save(&b, "edge_dense");
    scenes::save_crop(&a, "edge_sparse_crop", (540, 260, 200, 200), 3);
    let px_per_m = {
        let p0 = camera.project([0.0; 3], W, H).unwrap();
        let p1 = camera.project([l, 0.0, 0.0], W, H).unwrap();
        (p1[0] - p0[0]) / l
    };
    let h = (4.0 * l * l / n_sparse as f32).sqrt() * px_per_m;
    let c = camera.project([0.0; 3], W, H).unwrap();
    let half = (0.6 * l * px_per_m) as u32;
    let rows = c[1] as u32 - half..c[1] as u32 + half;
    let cols = c[0] as u32 - half..c[0] as u32 + half;
    let (rms_a, width_a) = edge_stats(&edge_profile(&a, rows.clone(), cols.clone()));
    let (rms_b, width_b) = edge_stats(&edge_profile(&b, rows.clone(), cols.clone()));
    let p = psnr(&a, &b, Style::default().background);
    let window = {
        let mut w = Image {
            width: cols.len() as u32,
            height: rows.len() as u32,
            rgba: Vec::new(),
        };
        for y in rows.clone() {
            for x in cols.clone() {
                w.rgba.extend_from_slice(&a.pixel(x, y));
            }
        }
        w
    };
    let holes = scenes::holes(&window, Style::default().background);
    eprintln!(
        "paint edge: {holes} holes; spacing {h:.1} px; sparse: RMS wander {rms_a:.2} px, width {width_a:.2} px; \
         dense: {rms_b:.2} px, {width_b:.2} px; PSNR {p:.1} dB"
    );
    assert!(
        rms_a < 0.5 * h,
        "edge wanders {rms_a:.2} px (spacing {h:.1} px)"
    );
    assert!(
        width_a < 2.0 * h,
        "edge {width_a:.2} px wide (spacing {h:.1} px)"
    );
    assert_eq!(holes, 0, "{holes} hole pixels");
    assert!(
        rms_b < 1.0 && width_b < 3.0,
        "dense edge {rms_b:.2} px, {width_b:.2} px"
    );
}

/// Far away, 200k splats are each much smaller than a pixel: the pre-filter keeps every one at
/// least a pixel's footprint, so the silhouette's inside has no holes and the picture is close
/// to the sparse sampling's at the same size (≥ 28 dB: at 160×90 a quarter of the shape's
/// pixels are silhouette, where the sparse splats protrude; measured 30.8 dB, 28.3 before
/// outline pixels took the grazing normal).
#[test]
fn tiny_far_splats_neither_vanish_nor_leave_holes() {
    let dense = scenes::torus(200_000, 0.06, 0.025, 8, clay);
    let sparse = scenes::torus(3_000, 0.06, 0.025, 9, clay);
    let (lo, hi) = bounds(&dense);
    let camera = Camera::framing(lo, hi, [0.2, -0.5, -1.0]);
    let size = (160, 90);
    let a = render(&scenes::splats(&dense), &camera, size);
    let b = render(&scenes::splats(&sparse), &camera, size);
    save(&a, "far_dense");
    let bg = Style::default().background;
    // Pixels of the sparse render's shape, away from its silhouette, are covered in the dense.
    let mut inside = 0;
    for y in 1..size.1 - 1 {
        for x in 1..size.0 - 1 {
            let ring = [(0, 0), (1, 0), (0, 1), (-1, 0), (0, -1)];
            if ring
                .iter()
                .all(|(dx, dy)| b.pixel((x as i32 + dx) as u32, (y as i32 + dy) as u32) != bg)
            {
                inside += 1;
                assert_ne!(a.pixel(x, y), bg, "hole at ({x}, {y})");
            }
        }
    }
    assert!(inside > 1000, "{inside} pixels inside");
    let p = psnr(&a, &b, bg);
    eprintln!("far torus 160x90: dense vs sparse PSNR {p:.1} dB");
    assert!(p >= 28.0, "PSNR {p:.1} dB");
    // One splat far smaller than a pixel still shows.
    let mut r = SoftwareRenderer::new(64, 48).unwrap();
    let cam = Camera::framing([-1.0; 3], [1.0; 3], [0.0, 0.0, -1.0]);
    let img = r
        .render(
            &[Splat::disk(
                [0.013, 0.021, 0.0],
                [0.0, 0.0, 1.0],
                1e-7,
                [255; 4],
            )],
            &Overlay::default(),
            &cam,
        )
        .unwrap();
    assert!(img.rgba.chunks(4).any(|p| p != bg), "a tiny splat vanished");
}

/// The window's stand-in while the view moves at 10⁶ points (`render::thin_splats`): a random
/// 200,000-point ellipsoid thinned to 20,000 (every 10th, axes grown) draws the same shape with
/// no holes, close to the full set's picture; random order is the worst case for the stride.
#[test]
fn a_thinned_splat_set_draws_the_same_shape_without_holes() {
    let axes = Vec3::new(0.07, 0.045, 0.035);
    let dense = scenes::ellipsoid_random(200_000, axes, 3, [120, 170, 210, 255]);
    let (lo, hi) = bounds(&dense);
    let camera = Camera::framing(lo, hi, [0.3, -0.8, -1.0]);
    let full = scenes::splats(&dense);
    let mut thinned = Vec::new();
    assert_eq!(render::thin_splats(&full, 20_000, &mut thinned), 10);
    let a = render(&thinned, &camera, (W, H));
    let b = render(&full, &camera, (W, H));
    save(&a, "thinned");
    let bg = Style::default().background;
    let (psnr, psnr_inside, silhouette_px) = scenes::psnr_parts(&a, &b, bg);
    let holes = scenes::holes(&a, bg);
    eprintln!(
        "thinned 200k -> {}: PSNR {psnr:.1} dB (inside {psnr_inside:.1}), {silhouette_px} outline px, {holes} holes",
        thinned.len()
    );
    assert_eq!(holes, 0);
    assert!(psnr >= 40.0, "{psnr}");
}

/// A random sampling leaves gaps wider than its neighbours' ellipses reach (issue 19: the
/// demo's 6,000-point random ball showed the back of the object through one, a light fleck in
/// the middle of a paint stroke). Splats grow to their Voronoi cells' corners where they face
/// the eye (`Splat::cell_growth`), so no pixel of the front shows the back: the back half of a
/// random sphere is blue, the front white, seen face on; inside the front's disc (away from
/// its outline, where growth fades out) not one blue pixel. Without the growth the second seed
/// shows 9.
#[test]
fn the_gaps_of_a_random_sampling_never_show_the_back() {
    for seed in [11, 12, 13] {
        let mut samples = scenes::ellipsoid_random(6_000, Vec3::splat(0.05), seed, [230; 4]);
        for s in &mut samples {
            if s.0.z < 0.0 {
                s.2 = [0, 0, 255, 255];
            }
        }
        let camera = Camera::framing([-0.05; 3], [0.05; 3], [0.0, 0.0, -1.0]);
        let img = render(&scenes::splats(&samples), &camera, (W, H));
        save(&img, &format!("gaps_{seed}"));
        let c = camera.project([0.0, 0.0, 0.05], W, H).unwrap();
        let edge = camera.project([0.05, 0.0, 0.0], W, H).unwrap();
        // Within 0.8 of the disc's radius the front faces the eye within 53°.
        let r = 0.8 * (edge[0] - c[0]);
        let mut blue = 0;
        for y in 0..H {
            for x in 0..W {
                let (dx, dy) = (x as f32 + 0.5 - c[0], y as f32 + 0.5 - c[1]);
                let p = img.pixel(x, y);
                if dx.hypot(dy) < r && p[2] > p[0].saturating_add(60) {
                    blue += 1;
                }
            }
        }
        assert_eq!(
            blue, 0,
            "seed {seed}: {blue} pixels of the back show through the front"
        );
    }
}
