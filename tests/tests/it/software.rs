//! A machine without a Vulkan driver, as a fresh install meets it: with no Vulkan ICD visible
//! (`VK_ICD_FILENAMES` pointing at a file that does not exist), `workstation demo` still runs
//! the whole networked session and writes every output, its PNG frames drawn by the CPU
//! splatting path, and says once how to get the fast path; `workstation render` likewise.

use std::path::Path;
use std::process::{Command, Output};

use e2e_tests::binary;

/// `workstation ARGS` with no Vulkan driver in sight and no display.
fn without_vulkan(args: &[&str], dir: &Path) -> Output {
    Command::new(binary("workstation"))
        .args(args)
        .current_dir(dir)
        .env("VK_ICD_FILENAMES", dir.join("no-such-icd.json"))
        .env("VK_DRIVER_FILES", dir.join("no-such-icd.json"))
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .expect("run workstation")
}

fn text(out: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// Width, height and the count of pixels that differ from the top-left (background) pixel.
fn png_summary(path: &Path) -> (u32, u32, usize) {
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(path).expect("open png"),
    ));
    let mut reader = decoder.read_info().expect("png header");
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).expect("png frame");
    let px = info.color_type.samples();
    let pixels: Vec<&[u8]> = buf[..info.buffer_size()].chunks(px).collect();
    let background = pixels[0];
    let drawn = pixels.iter().filter(|p| p[..3] != background[..3]).count();
    (info.width, info.height, drawn)
}

#[test]
fn the_demo_runs_and_writes_its_frames_without_a_vulkan_driver() {
    let _slot = e2e_tests::busy_slot();
    let dir = tempfile::tempdir().unwrap();
    let out = without_vulkan(&["demo", "--no-window", "--out", "out"], dir.path());
    let log = text(&out);
    assert!(out.status.success(), "the demo failed:\n{log}");
    // Said once, with the way to the fast path.
    assert_eq!(
        log.matches("mesa-vulkan-drivers").count(),
        1,
        "the fallback is said exactly once:\n{log}"
    );
    let demo = dir.path().join("out");
    for file in ["summary.json", "final.ply", "final_mesh.ply"] {
        assert!(demo.join(file).exists(), "{file} missing:\n{log}");
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(demo.join("summary.json")).unwrap()).unwrap();
    assert!(
        summary["frames"].as_u64().unwrap_or(0) >= 2,
        "frames in the summary: {}",
        summary["frames"]
    );
    // Every cursor counted once by the age of the command its servo tick applied.
    let age = &summary["applied_age_ticks"];
    let sum: f64 = ["next_tick", "two_ticks", "three_or_more", "no_command"]
        .iter()
        .map(|k| age[k].as_f64().unwrap())
        .sum();
    assert!((sum - 1.0).abs() < 1e-9, "{age}");
    assert!(age["ticks"].as_u64().unwrap() > 1000, "{age}");
    let mut frames: Vec<_> = std::fs::read_dir(demo.join("frames"))
        .expect("frames/")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    frames.sort();
    assert!(frames.len() >= 2, "{} frames", frames.len());
    let (w, h, drawn) = png_summary(frames.last().unwrap());
    assert_eq!((w, h), (1280, 720), "the demo's frames are 1280x720");
    assert!(
        drawn > (w * h / 50) as usize,
        "the last frame shows the object: {drawn} pixels drawn"
    );
}

#[test]
fn render_draws_a_saved_model_on_the_cpu_without_a_vulkan_driver() {
    let _slot = e2e_tests::busy_slot();
    let dir = tempfile::tempdir().unwrap();
    let model = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/bunny.ply");
    let out = without_vulkan(&["render", model, "-o", "bunny.png"], dir.path());
    let log = text(&out);
    assert!(out.status.success(), "render failed:\n{log}");
    assert!(log.contains("mesa-vulkan-drivers"), "{log}");
    let (w, h, drawn) = png_summary(&dir.path().join("bunny.png"));
    assert_eq!((w, h), (1280, 720));
    assert!(drawn > (w * h / 50) as usize, "{drawn} pixels drawn");
}
