//! The `workstation` binary as a user runs it. (Also makes `cargo test --workspace` build the
//! binary, which the end-to-end tests in `tests/` start as a process.)

use std::process::Command;

fn workstation() -> Command {
    Command::new(env!("CARGO_BIN_EXE_workstation"))
}

#[test]
fn help_lists_the_live_commands() {
    let out = workstation().arg("--help").output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for cmd in [
        "demo",
        "run",
        "view",
        "hand-path",
        "render",
        "sculpt",
        "fit",
    ] {
        assert!(text.contains(cmd), "`{cmd}` missing from --help:\n{text}");
    }
}

#[test]
fn hand_path_writes_the_demo_strokes_for_the_fake_device() {
    let dir = std::env::temp_dir().join(format!("ws-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("hand.txt");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/live/demo.toml");
    let out = workstation()
        .args(["hand-path", scene, "--lead-in", "2", "-o"])
        .arg(&file)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&file).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect())
        .collect();
    assert!(
        rows.iter().all(|r| r.len() == 5),
        "t x y z buttons per line"
    );
    assert!(
        rows.windows(2).all(|w| w[0][0] <= w[1][0]),
        "time never goes back"
    );
    // Three strokes: the button goes down three times, the first after the lead-in.
    let presses: Vec<f64> = rows
        .windows(2)
        .filter(|w| w[0][4] == 0.0 && w[1][4] == 1.0)
        .map(|w| w[1][0])
        .collect();
    assert_eq!(presses.len(), 3, "{text}");
    assert!(presses[0] >= 2.0);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn view_without_a_display_says_what_to_do_instead() {
    let out = workstation()
        .arg("view")
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("no display") && err.contains("xvfb-run"),
        "{err}"
    );
}

#[test]
fn a_headless_render_without_a_login_session_prints_no_wayland_error() {
    // Over ssh or in a service there is no XDG_RUNTIME_DIR; Mesa's Vulkan device-select layer
    // then made libwayland print "error: XDG_RUNTIME_DIR is invalid…" on the GPU probe.
    let dir = std::env::temp_dir().join(format!("ws-cli-xdg-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let png = dir.join("bunny.png");
    let bunny = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/bunny.ply");
    let out = workstation()
        .args(["render", bunny, "--size", "64", "48", "--out"])
        .arg(&png)
        .env_remove("XDG_RUNTIME_DIR")
        .env_remove("NODEVICE_SELECT")
        .env_remove("MESA_VK_DEVICE_SELECT")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(png.is_file());
    assert!(!err.contains("XDG_RUNTIME_DIR"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn view_rejects_a_bad_window_size_naming_the_flag() {
    let out = workstation()
        .args(["view", "--size", "10x10"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--size") && err.contains("200..=8192"),
        "{err}"
    );
}
