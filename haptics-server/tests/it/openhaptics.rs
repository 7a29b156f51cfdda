//! The OpenHaptics backend against a stand-in `libHD.so` built here from C
//! (`tests/stand-ins/hd_standin.c`) with the `cc` crate's compiler detection.

use std::path::{Path, PathBuf};
use std::time::Duration;

use glam::Vec3;
use haptics_server::device::openhaptics::{OpenHapticsDevice, probe};
use haptics_server::server::{Server, ServerOptions, TransportKind};

use crate::common::{build_standin, config, constant, stream_until};

/// Compile the HD stand-in into `dir`; `defines` adds `-D` flags.
pub fn build(dir: &Path, name: &str, defines: &[&str]) -> PathBuf {
    build_standin("hd_standin.c", dir, name, defines)
}

#[test]
fn without_the_library_the_backend_says_what_is_missing() {
    let e = probe("/nonexistent/libHD.so").unwrap_err().to_string();
    assert!(
        e.contains("cannot load the OpenHaptics HD library") && e.contains("/nonexistent/libHD.so"),
        "{e}"
    );
    let dir = tempfile::tempdir().unwrap();
    let lib = build(dir.path(), "libHD_partial.so", &["OMIT_UNSCHEDULE"]);
    let e = probe(lib.to_str().unwrap()).unwrap_err().to_string();
    assert!(e.ends_with("lacks hdUnschedule"), "{e}");
    let e = OpenHapticsDevice::open(
        build(dir.path(), "libHD.so", &[]).to_str().unwrap(),
        "missing",
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("hdInitDevice(\"missing\") failed") && e.contains("0x0201"),
        "{e}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_hd_scheduler_drives_the_servo_loop_and_forces_reach_the_device() {
    let dir = tempfile::tempdir().unwrap();
    let path = build(dir.path(), "libHD.so", &[]);
    let dev = OpenHapticsDevice::open(path.to_str().unwrap(), "").expect("stand-in opens");
    assert!(
        (haptics_server::device::Device::info(&dev).max_stiffness_n_per_m - 700.0).abs() < 1e-3
    );
    // Test hooks the stand-in exports besides the HD API.
    // SAFETY: the stand-in is our own C file; the hooks take/return plain values.
    let lib = unsafe { libloading::Library::new(&path) }.unwrap();
    // SAFETY: the signature matches `long standin_frames(void)` in hd_standin.c.
    let frames =
        unsafe { lib.get::<unsafe extern "C" fn() -> std::ffi::c_long>(b"standin_frames") };
    // SAFETY: the signature matches `void standin_force(double *)` in hd_standin.c.
    let applied = unsafe { lib.get::<unsafe extern "C" fn(*mut f64)>(b"standin_force") };
    let (frames, applied) = (frames.unwrap(), applied.unwrap());
    let read_force = || {
        let mut f = [0f64; 3];
        // SAFETY: writes 3 doubles into `f`.
        unsafe { applied(f.as_mut_ptr()) };
        Vec3::new(f[0] as f32, f[1] as f32, f[2] as f32)
    };

    let server = Server::start(dev, ServerOptions::for_tests(TransportKind::Udp).unwrap()).unwrap();
    let mut client = haptics_server::client::Client::connect(&config(&server, TransportKind::Udp))
        .await
        .unwrap();
    let f = Vec3::new(0.0, 0.0, 0.5);
    let at_device = |_: &protocol::CursorSample| (read_force() - f).length() < 1e-5;
    stream_until(
        &mut client,
        "the stand-in outputs the force",
        |_| constant(f, (0, 0)),
        at_device,
    )
    .await;
    // SAFETY: plain C call.
    let before = unsafe { frames() };
    let ticks = server.servo_stats().ticks;
    assert!(
        ticks > 10 && ticks <= before as u64,
        "every servo tick ran in an HD frame: {ticks} ticks, {before} frames"
    );
    // The stylus moved under the force (closed loop through the stand-in's dynamics).
    let pushed = |c: &protocol::CursorSample| c.position.z > 0.001;
    stream_until(
        &mut client,
        "the stylus pushed along +z",
        |_| constant(f, (0, 0)),
        pushed,
    )
    .await;
    drop(client);
    server.shutdown();
    tokio::time::sleep(Duration::from_millis(20)).await;
    assert_eq!(read_force(), Vec3::ZERO, "shutdown leaves zero force");
}
