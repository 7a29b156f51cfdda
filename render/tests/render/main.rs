//! Renders small scenes on the real device (lavapipe in CI) and checks pixels where geometry
//! projects. A machine without a Vulkan adapter fails every GPU test here with the install
//! hint. The modules: `quality` (sparse vs dense, paint edges, pre-filter; software renderer),
//! `backends` (GPU against software, the headless facade and its fallback).

mod backends;
mod quality;
mod scenes;

use render::{
    Camera, Ellipsoid, Image, Overlay, RenderError, Renderer, Splat, Style, linear_to_srgb,
    srgb_to_linear,
};

const W: u32 = 320;
const H: u32 = 240;

fn renderer() -> Renderer {
    Renderer::headless(W, H).unwrap_or_else(|e| panic!("{e}"))
}

/// `n` points of a Fibonacci lattice on a sphere, outward normals, disks sized to cover it.
fn sphere(n: usize, center: [f32; 3], radius: f32, color: [u8; 4]) -> Vec<Splat> {
    let spacing = (4.0 * std::f32::consts::PI / n as f32).sqrt() * radius;
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * i as f32;
            let normal = [r * phi.cos(), r * phi.sin(), z];
            let position = [0, 1, 2].map(|k| center[k] + radius * normal[k]);
            Splat::disk(position, normal, 0.8 * spacing, color)
        })
        .collect()
}

fn framing(radius: f32) -> Camera {
    Camera::framing([-radius; 3], [radius; 3], [0.0, 0.0, -1.0])
}

fn background() -> [u8; 4] {
    Style::default().background
}

fn px(img: &Image, p: [f32; 2]) -> [u8; 4] {
    img.pixel(p[0] as u32, p[1] as u32)
}

fn close(a: [u8; 4], b: [u8; 4], tol: u8) -> bool {
    a.iter().zip(&b).all(|(x, y)| x.abs_diff(*y) <= tol)
}

fn luminance(c: [u8; 4]) -> f32 {
    0.2126 * srgb_to_linear(c[0]) + 0.7152 * srgb_to_linear(c[1]) + 0.0722 * srgb_to_linear(c[2])
}

/// The colour the lighting model predicts for sRGB `albedo` at `n_dot_l`.
fn expected(albedo: [u8; 4], n_dot_l: f32) -> [u8; 4] {
    let lin = [albedo[0], albedo[1], albedo[2]].map(srgb_to_linear);
    let c = Style::default()
        .lighting
        .shade(lin, n_dot_l)
        .map(linear_to_srgb);
    [c[0], c[1], c[2], 255]
}

#[test]
fn sphere_centre_is_the_lit_splat_colour_and_corners_are_background() {
    let mut r = renderer();
    let color = [200, 120, 40, 255];
    let img = r.render(
        &sphere(2000, [0.0; 3], 0.05, color),
        &Overlay::default(),
        &framing(0.05),
    );
    let img = img.unwrap();
    assert_eq!(
        (img.width, img.height, img.rgba.len()),
        (W, H, (W * H * 4) as usize)
    );
    let centre = img.pixel(W / 2, H / 2);
    // Head-on, |n·l| is within 1e-3 of 1 (the splat there is tilted by less than its spacing).
    assert!(
        close(centre, expected(color, 1.0), 6),
        "centre {centre:?}, expected {:?}",
        expected(color, 1.0)
    );
    for (x, y) in [(0, 0), (W - 1, 0), (0, H - 1), (W - 1, H - 1)] {
        assert_eq!(img.pixel(x, y), background(), "corner ({x}, {y})");
    }
}

#[test]
fn a_splat_is_a_round_disk_in_its_tangent_plane() {
    let mut r = renderer();
    let cam = framing(0.05);
    let radius = 0.03;
    let facing = Splat::disk([0.0; 3], [0.0, 0.0, 1.0], radius, [255; 4]);
    let img = r.render(&[facing], &Overlay::default(), &cam).unwrap();
    let at = |p: [f32; 3]| px(&img, cam.project(p, W, H).unwrap());
    for k in [0.0, 0.5, 0.95] {
        assert_ne!(at([k * radius, 0.0, 0.0]), background(), "inside at {k} r");
        assert_ne!(at([0.0, -k * radius, 0.0]), background(), "inside at {k} r");
    }
    // The corners of the quad around the disk are discarded; beyond the radius is empty.
    let d = 0.8 * radius;
    for p in [
        [d, d, 0.0],
        [-d, d, 0.0],
        [d, -d, 0.0],
        [-d, -d, 0.0],
        [1.1 * radius, 0.0, 0.0],
    ] {
        assert_eq!(at(p), background(), "outside the disk at {p:?}");
    }
    // Turned 80° about y, the disk is a narrow vertical ellipse (semi-axes r and r·cos 80°).
    let a = 80f32.to_radians();
    let turned = Splat {
        normal: [a.sin(), 0.0, a.cos()],
        ..facing
    };
    let img = r.render(&[turned], &Overlay::default(), &cam).unwrap();
    let at = |p: [f32; 3]| px(&img, cam.project(p, W, H).unwrap());
    assert_eq!(
        at([0.5 * radius, 0.0, 0.0]),
        background(),
        "nothing beside the turned disk"
    );
    assert_ne!(
        at([0.0, 0.9 * radius, 0.0]),
        background(),
        "it still spans its radius"
    );
}

#[test]
fn no_holes_between_splats_inside_the_silhouette() {
    let mut r = renderer();
    let cam = framing(0.05);
    let img = r.render(
        &sphere(2000, [0.0; 3], 0.05, [90, 200, 90, 255]),
        &Overlay::default(),
        &cam,
    );
    let img = img.unwrap();
    // Every pixel within 90 % of the projected radius is covered.
    let c = cam.project([0.0; 3], W, H).unwrap();
    let edge = cam.project([0.0, 0.05, 0.0], W, H).unwrap();
    let radius_px = (c[1] - edge[1]).abs();
    let mut inside = 0;
    for y in 0..H {
        for x in 0..W {
            let d = ((x as f32 + 0.5 - c[0]).powi(2) + (y as f32 + 0.5 - c[1]).powi(2)).sqrt();
            if d < 0.9 * radius_px {
                inside += 1;
                assert_ne!(img.pixel(x, y), background(), "hole at ({x}, {y})");
            }
        }
    }
    assert!(inside > 5000, "the sphere covers {inside} pixels");
}

#[test]
fn nearer_sphere_occludes_farther_whatever_the_draw_order() {
    let mut r = renderer();
    let red = sphere(2000, [0.0, 0.0, 0.0], 0.02, [230, 20, 20, 255]);
    let blue = sphere(2000, [0.0, 0.0, -0.06], 0.05, [20, 20, 230, 255]);
    let cam = framing(0.05);
    for splats in [
        [&red[..], &blue[..]].concat(),
        [&blue[..], &red[..]].concat(),
    ] {
        let img = r.render(&splats, &Overlay::default(), &cam).unwrap();
        let centre = img.pixel(W / 2, H / 2);
        let want = expected([230, 20, 20, 255], 1.0);
        assert!(
            close(centre, want, 6),
            "centre should be lit red {want:?}, got {centre:?}"
        );
        // Beside the red sphere the blue one shows.
        let beside = px(&img, cam.project([0.03, 0.0, 0.0], W, H).unwrap());
        assert!(
            beside[2] > 100 && beside[0] < 60,
            "beside the red sphere: {beside:?}"
        );
    }
}

#[test]
fn lit_side_is_brighter_than_grazing_side() {
    let mut r = renderer();
    let cam = framing(0.05);
    let img = r.render(
        &sphere(4000, [0.0; 3], 0.05, [180, 180, 180, 255]),
        &Overlay::default(),
        &cam,
    );
    let img = img.unwrap();
    let centre = img.pixel(W / 2, H / 2);
    // A point 65° round from the view axis (the silhouette is at 79°): |n·l| ≈ 0.25 there.
    let a = 65f32.to_radians();
    let p = [0.05 * a.sin(), 0.0, 0.05 * a.cos()];
    let to_eye = [0, 1, 2].map(|k| cam.eye[k] - p[k]);
    let len = to_eye.iter().map(|v| v * v).sum::<f32>().sqrt();
    let n_dot_l = (a.sin() * to_eye[0] + a.cos() * to_eye[2]) / len;
    assert!((0.2..0.3).contains(&n_dot_l), "{n_dot_l}");
    let grazing = px(&img, cam.project(p, W, H).unwrap());
    assert!(
        luminance(centre) > 2.0 * luminance(grazing),
        "centre {centre:?} should be much brighter than the grazing side {grazing:?}"
    );
    // And each matches the lighting model (the splat normals are within ~3° of the sphere's).
    assert!(
        close(centre, expected([180, 180, 180, 255], 1.0), 6),
        "centre {centre:?}"
    );
    let want = expected([180, 180, 180, 255], n_dot_l);
    assert!(
        close(grazing, want, 20),
        "grazing {grazing:?}, model {want:?}"
    );
    // Ambient keeps the grazing side visible.
    assert_ne!(grazing, background());
    assert!(
        luminance(grazing) > 0.1 * luminance(centre),
        "grazing side too dark: {grazing:?}"
    );
}

#[test]
fn region_box_and_force_arrow_appear_where_they_project() {
    let mut r = renderer();
    let style = Style::default();
    let cam = Camera::framing([-0.05; 3], [0.05; 3], [0.3, -0.4, -1.0]);
    let (min, max) = ([-0.04, -0.03, -0.02], [0.04, 0.03, 0.02]);
    let (origin, vector) = ([0.0, 0.0, 0.0], [0.0, 0.0, 0.04]);
    let overlay = Overlay {
        region: Some((min, max)),
        force: Some((origin, vector)),
        ..Default::default()
    };
    let img = r.render(&[], &overlay, &cam).unwrap();
    let rgb = |c: [u8; 3]| [c[0], c[1], c[2], 255];
    // The midpoint of each of the 12 edges.
    let mut checked = 0;
    for i in 0..8usize {
        for bit in [1usize, 2, 4] {
            if i & bit != 0 {
                continue;
            }
            let corner =
                |i: usize| [0, 1, 2].map(|k| if i & (1 << k) != 0 { max[k] } else { min[k] });
            let (a, b) = (corner(i), corner(i | bit));
            let mid = [0, 1, 2].map(|k| 0.5 * (a[k] + b[k]));
            let p = cam.project(mid, W, H).unwrap();
            assert!(
                close(px(&img, p), rgb(style.region_color), 2),
                "edge {a:?}-{b:?} at {p:?}: {:?}",
                px(&img, p)
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 12);
    // The shaft at 40 % of the vector, and nothing but background well off the lines.
    let shaft = cam.project(vector.map(|v| 0.4 * v), W, H).unwrap();
    assert!(
        close(px(&img, shaft), rgb(style.force_color), 2),
        "shaft at {shaft:?}: {:?}",
        px(&img, shaft)
    );
    let near_tip = cam.project(vector.map(|v| 0.97 * v), W, H).unwrap();
    let head = px(&img, near_tip);
    assert!(
        head[0] > 100 && head[2] > 60 && head[1] < 80,
        "arrow head near the tip: {head:?}"
    );
    let off = cam.project([0.02, 0.015, 0.0], W, H).unwrap();
    assert_eq!(px(&img, off), background(), "off the lines at {off:?}");
}

#[test]
fn translucent_probe_blends_with_what_is_behind_it() {
    let mut r = renderer();
    let cam = framing(0.05);
    let green = [40, 200, 60, 255];
    let splats = sphere(3000, [0.0; 3], 0.04, green);
    let probe = Ellipsoid {
        center: [0.04, 0.0, 0.05],
        rotation: [0.0, 0.0, 0.0, 1.0],
        semi_axes: [0.02, 0.01, 0.01],
    };
    let with = Overlay {
        probe: Some(probe),
        ..Default::default()
    };
    let plain = r.render(&splats, &Overlay::default(), &cam).unwrap();
    let img = r.render(&splats, &with, &cam).unwrap();
    let style = Style::default();
    let [pr, pg, pb, _] = style.probe_color;

    // Over the sphere (left end of the probe): between the splat colour and the probe colour.
    let over = cam.project([0.025, 0.0, 0.05], W, H).unwrap();
    let (before, after) = (px(&plain, over), px(&img, over));
    assert_ne!(before, background(), "the sphere is behind this pixel");
    assert_ne!(after, before, "the probe covers this pixel");
    for k in 0..3 {
        let (lo, hi) = (
            before[k].min([pr, pg, pb][k]),
            before[k].max([pr, pg, pb][k]),
        );
        assert!(
            after[k] >= lo && after[k] <= hi,
            "channel {k}: {after:?} not between {before:?} and the probe"
        );
    }
    // Over the background (right end of the probe): between background and probe colour.
    let out = cam.project([0.056, 0.0, 0.05], W, H).unwrap();
    assert_eq!(
        px(&plain, out),
        background(),
        "nothing behind the probe's right end"
    );
    let bg = background();
    let o = px(&img, out);
    for k in 0..3 {
        let (lo, hi) = (bg[k].min([pr, pg, pb][k]), bg[k].max([pr, pg, pb][k]));
        assert!(
            o[k] > lo && o[k] < hi,
            "channel {k}: {o:?} not strictly between {bg:?} and the probe"
        );
    }
    assert_eq!(o[3], 255, "blending keeps the target opaque");
    // Pixels the probe does not cover are untouched.
    assert_eq!(
        img.pixel(W / 2, H / 2),
        plain.pixel(W / 2, H / 2),
        "centre unaffected"
    );
}

#[test]
fn cursor_is_an_opaque_dot_of_the_styled_size() {
    let mut r = renderer();
    let cam = framing(0.05);
    let style = Style::default();
    let at = [0.01, 0.02, 0.0];
    let img = r
        .render(
            &[],
            &Overlay {
                cursor: Some(at),
                ..Default::default()
            },
            &cam,
        )
        .unwrap();
    let p = cam.project(at, W, H).unwrap();
    let c = px(&img, p);
    let [cr, cg, cb] = style.cursor_color;
    let want = expected([cr, cg, cb, 255], 1.0);
    assert!(
        close(c, want, 8),
        "cursor centre {c:?}, lit cursor colour {want:?}"
    );
    let r_px = style.cursor_radius_px;
    assert_ne!(
        px(&img, [p[0] + 0.6 * r_px, p[1]]),
        background(),
        "inside the radius"
    );
    assert_eq!(
        px(&img, [p[0] + 1.5 * r_px, p[1]]),
        background(),
        "outside the radius"
    );
}

#[test]
fn growing_and_shrinking_splat_counts_render_the_same_scene() {
    let mut r = renderer();
    let cam = framing(0.05);
    let small = sphere(1000, [0.0; 3], 0.05, [200, 200, 60, 255]);
    let big = sphere(20_000, [0.0; 3], 0.05, [200, 200, 60, 255]);
    let first = r.render(&small, &Overlay::default(), &cam).unwrap();
    r.render(&big, &Overlay::default(), &cam).unwrap();
    let again = r.render(&small, &Overlay::default(), &cam).unwrap();
    assert_eq!(first, again, "a grown buffer draws the same small frame");
    let mut reused = Image::default();
    r.render_into(&small, &Overlay::default(), &cam, &mut reused)
        .unwrap();
    assert_eq!(first, reused);
}

#[test]
fn invalid_inputs_are_errors_that_name_them() {
    let mut r = renderer();
    let cam = framing(0.05);
    let mut splats = sphere(100, [0.0; 3], 0.05, [255; 4]);
    splats[42].position[1] = f32::NAN;
    let e = r.render(&splats, &Overlay::default(), &cam).unwrap_err();
    assert!(
        matches!(
            e,
            RenderError::NonFinite {
                what: "splat",
                index: 42
            }
        ),
        "{e}"
    );
    let bad_cam = Camera { near: -1.0, ..cam };
    let e = r.render(&[], &Overlay::default(), &bad_cam).unwrap_err();
    assert!(matches!(e, RenderError::InvalidCamera(_)), "{e}");
    let probe = Ellipsoid {
        center: [0.0; 3],
        rotation: [0.0, 0.0, 0.0, 1.0],
        semi_axes: [f32::INFINITY; 3],
    };
    let e = r
        .render(
            &[],
            &Overlay {
                probe: Some(probe),
                ..Default::default()
            },
            &cam,
        )
        .unwrap_err();
    assert!(
        matches!(e, RenderError::NonFinite { what: "probe", .. }),
        "{e}"
    );
    assert!(matches!(
        r.resize(0, 10),
        Err(RenderError::InvalidSize { .. })
    ));
    // The renderer still works after the errors.
    r.render(&splats[..40], &Overlay::default(), &cam).unwrap();
}

#[test]
fn adapter_is_named() {
    let r = renderer();
    let info = r.adapter_info();
    assert!(info.contains("Vulkan"), "{info}");
}

#[test]
fn back_facing_splats_are_culled_only_when_asked() {
    let mut r = renderer();
    let cam = framing(0.05);
    let away = Splat::disk([0.0; 3], [0.0, 0.0, -1.0], 0.02, [255; 4]);
    let drawn = r.render(&[away], &Overlay::default(), &cam).unwrap();
    assert_ne!(
        drawn.pixel(W / 2, H / 2),
        background(),
        "two-sided by default"
    );
    r.set_style(Style {
        cull_back_facing: true,
        ..Style::default()
    });
    let culled = r.render(&[away], &Overlay::default(), &cam).unwrap();
    assert_eq!(
        culled.pixel(W / 2, H / 2),
        background(),
        "culled when asked"
    );
    // A closed surface with outward normals looks the same either way, bar its silhouette.
    let ball = sphere(2000, [0.0; 3], 0.05, [150, 150, 220, 255]);
    let front = r.render(&ball, &Overlay::default(), &cam).unwrap();
    r.set_style(Style::default());
    let both = r.render(&ball, &Overlay::default(), &cam).unwrap();
    assert_eq!(front.pixel(W / 2, H / 2), both.pixel(W / 2, H / 2));
    let differing = front
        .rgba
        .chunks(4)
        .zip(both.rgba.chunks(4))
        .filter(|(a, b)| a != b)
        .count();
    assert!(
        differing < (W * H / 100) as usize,
        "{differing} pixels differ"
    );
}

#[test]
fn renderer_can_move_to_a_rendering_thread() {
    fn assert_send<T: Send + 'static>() {}
    assert_send::<Renderer>();
    let mut r = renderer();
    let img = std::thread::spawn(move || r.render(&[], &Overlay::default(), &framing(0.05)))
        .join()
        .unwrap()
        .unwrap();
    assert_eq!(img.pixel(0, 0), background());
}
