//! The GPU renderer against the software reference on one scene with splats and every overlay,
//! and the headless facade: backend choice, parsing, and the fallback without a Vulkan driver.

use glam::{Quat, Vec3};
use render::{
    Backend, BackendChoice, Camera, Ellipsoid, HeadlessRenderer, Image, Overlay, RenderError,
    Renderer, SoftwareRenderer, Splat, Style,
};

use crate::scenes::{self, psnr, save};

const W: u32 = 640;
const H: u32 = 480;

/// An ellipsoid of 20k random splats, half painted (a colour edge), with the probe resting on
/// it, the cursor at the probe's centre, the contact point, the region box and the force arrow.
fn scene() -> (Vec<Splat>, Overlay, Camera) {
    let axes = Vec3::new(0.05, 0.04, 0.045);
    let mut samples = scenes::ellipsoid_random(20_000, axes, 7, [214, 150, 112, 255]);
    for s in &mut samples {
        if s.0.x + 0.3 * s.0.y > 0.01 {
            s.2 = [40, 150, 170, 255];
        }
    }
    let splats = scenes::splats(&samples);
    let normal = Vec3::new(-0.6, 0.5, 0.62).normalize();
    let contact = normal * axes;
    let semi = [0.006, 0.008, 0.014];
    let tilt = Quat::from_axis_angle(normal.any_orthonormal_vector(), 0.5);
    let center = contact + normal * 0.012;
    let half = Vec3::splat(0.022);
    let overlay = Overlay {
        probe: Some(Ellipsoid {
            center: center.into(),
            rotation: (tilt * Quat::from_rotation_arc(Vec3::Z, normal)).to_array(),
            semi_axes: semi,
        }),
        cursor: Some(center.into()),
        contact: Some(contact.into()),
        region: Some(((contact - half).into(), (contact + half).into())),
        force: Some((center.into(), (normal * 0.035).into())),
    };
    let camera = Camera::framing([-0.05; 3], [0.05; 3], [0.25, -0.2, -1.0]);
    (splats, overlay, camera)
}

/// Fraction of pixels whose channels differ by more than `tol` between `a` and `b`.
fn differing(a: &Image, b: &Image, tol: u8) -> f64 {
    let n = a
        .rgba
        .chunks(4)
        .zip(b.rgba.chunks(4))
        .filter(|(p, q)| p.iter().zip(q.iter()).any(|(x, y)| x.abs_diff(*y) > tol))
        .count();
    n as f64 / (a.width * a.height) as f64
}

/// Same passes, same math, same overlays: the two backends differ only by float rounding (the
/// GPU sums in half floats, Rgba16Float: ~3 significant digits, ≤ 1 sRGB step on colours),
/// pixel-centre ties on triangle edges, and `exp`/`pow` ulps. 35 dB over the shape's pixels is
/// an RMS error of 4.5 sRGB steps; we measured far better (see the message) and also bound the
/// fraction of pixels off by more than 8 steps (edges of overlays and splat footprints).
#[test]
fn gpu_matches_the_software_reference() {
    let (splats, overlay, camera) = scene();
    let mut gpu = Renderer::headless(W, H).unwrap_or_else(|e| panic!("{e}"));
    let mut cpu = SoftwareRenderer::new(W, H).unwrap();
    for cull in [false, true] {
        let style = Style {
            cull_back_facing: cull,
            ..Style::default()
        };
        gpu.set_style(style);
        cpu.set_style(style);
        let g = gpu.render(&splats, &overlay, &camera).unwrap();
        let c = cpu.render(&splats, &overlay, &camera).unwrap();
        save(&g, &format!("backends_gpu_cull{cull}"));
        save(&c, &format!("backends_cpu_cull{cull}"));
        let p = psnr(&g, &c, style.background);
        let off = differing(&g, &c, 8);
        eprintln!(
            "GPU vs CPU (cull {cull}): PSNR {p:.1} dB, {:.3} % of pixels off by > 8",
            off * 100.0
        );
        assert!(p >= 35.0, "PSNR {p:.1} dB");
        assert!(
            off < 0.005,
            "{:.3} % of pixels differ by more than 8",
            off * 100.0
        );
    }
    // Overlays only (no splats): the meshes and lines alone.
    let g = gpu.render(&[], &overlay, &camera).unwrap();
    let c = cpu.render(&[], &overlay, &camera).unwrap();
    let p = psnr(&g, &c, Style::default().background);
    assert!(p >= 35.0, "overlays alone: PSNR {p:.1} dB");
}

#[test]
fn backend_choice_parses_and_software_is_chosen_when_asked() {
    assert_eq!(
        "auto".parse::<BackendChoice>().unwrap(),
        BackendChoice::Auto
    );
    assert_eq!(
        " GPU ".parse::<BackendChoice>().unwrap(),
        BackendChoice::Gpu
    );
    assert_eq!(
        "software".parse::<BackendChoice>().unwrap(),
        BackendChoice::Software
    );
    assert!(matches!(
        "metal".parse::<BackendChoice>(),
        Err(RenderError::UnknownBackend(s)) if s == "metal"
    ));
    let r = HeadlessRenderer::new(64, 48, BackendChoice::Software).unwrap();
    assert_eq!(r.backend(), Backend::Software);
    assert_eq!(r.fallback_reason(), None);
    let g = HeadlessRenderer::new(64, 48, BackendChoice::Gpu).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(g.backend(), Backend::Gpu);
}

#[test]
fn facade_renders_the_same_frame_on_both_backends() {
    let (splats, overlay, camera) = scene();
    let mut frames = Vec::new();
    for choice in [BackendChoice::Gpu, BackendChoice::Software] {
        let mut r = HeadlessRenderer::new(W / 2, H / 2, choice).unwrap();
        r.resize(W, H).unwrap();
        let mut img = Image::default();
        r.render_into(&splats, &overlay, &camera, &mut img).unwrap();
        assert_eq!((img.width, img.height), (W, H));
        frames.push(img);
    }
    let p = psnr(&frames[0], &frames[1], Style::default().background);
    assert!(p >= 35.0, "PSNR {p:.1} dB");
}

#[test]
fn auto_takes_a_gpu_but_prefers_software_over_a_cpu_vulkan_driver() {
    if std::env::var_os(render::BACKEND_ENV).is_some() {
        return; // the user forced a backend for this run
    }
    let gpu = render::Renderer::headless(64, 48).unwrap_or_else(|e| panic!("{e}"));
    let auto = HeadlessRenderer::new(64, 48, BackendChoice::Auto).unwrap();
    let expected = if gpu.is_cpu_adapter() {
        Backend::Software
    } else {
        Backend::Gpu
    };
    assert_eq!(auto.backend(), expected, "{}", gpu.adapter_info());
    assert_eq!(auto.fallback_reason(), None, "a choice, not a fallback");
}

const CHILD: &str = "RENDER_TEST_FALLBACK_CHILD";

/// Runs itself in a child process whose Vulkan loader finds no driver.
#[test]
fn auto_falls_back_to_software_without_a_vulkan_driver() {
    if std::env::var_os(CHILD).is_some() {
        let mut r = HeadlessRenderer::new(64, 48, BackendChoice::Auto).unwrap();
        assert_eq!(r.backend(), Backend::Software);
        let reason = r.fallback_reason().expect("a reason").to_string();
        assert!(
            reason.contains("apt-get install mesa-vulkan-drivers libvulkan1"),
            "{reason}"
        );
        let (splats, overlay, camera) = (
            vec![Splat::disk([0.0; 3], [0.0, 0.0, 1.0], 0.02, [255; 4])],
            Overlay::default(),
            Camera::framing([-0.05; 3], [0.05; 3], [0.0, 0.0, -1.0]),
        );
        let img = r.render(&splats, &overlay, &camera).unwrap();
        assert_ne!(img.pixel(32, 24), Style::default().background);
        let e = HeadlessRenderer::new(64, 48, BackendChoice::Gpu).unwrap_err();
        assert!(matches!(e, RenderError::NoAdapter(_)), "{e}");
        println!("fallback reason: {reason}");
        return;
    }
    let out = std::process::Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "backends::auto_falls_back_to_software_without_a_vulkan_driver",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(CHILD, "1")
        .env("VK_ICD_FILENAMES", "/nonexistent.json")
        .env("VK_DRIVER_FILES", "/nonexistent.json")
        .env_remove(render::BACKEND_ENV)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && stdout.contains("1 passed") && stdout.contains("fallback reason"),
        "child failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
