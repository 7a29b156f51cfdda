//! The Force Dimension backend against a stand-in `libdhd.so` built here from C
//! (`tests/stand-ins/dhd_standin.c`).

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use glam::Vec3;
use haptics_server::device::Device;
use haptics_server::device::dhd::{DhdDevice, probe};
use haptics_server::server::{Server, ServerOptions, TransportKind};

use crate::common::{build_standin, config, constant, stream_until};

/// Compile the DHD stand-in into `dir`; `defines` adds `-D` flags.
pub fn build(dir: &Path, name: &str, defines: &[&str]) -> PathBuf {
    build_standin("dhd_standin.c", dir, name, defines)
}

#[test]
fn without_the_library_or_the_device_the_backend_says_why() {
    let e = probe("/nonexistent/libdhd.so").unwrap_err().to_string();
    assert!(
        e.contains("cannot load the Force Dimension DHD library")
            && e.contains("\"/nonexistent/libdhd.so\" does not exist")
            && e.contains("device.dhd.library (--dhd-library)"),
        "{e}"
    );
    // A bare name: the file names looked for, and where.
    let e = probe("libdhd-not-installed.so").unwrap_err().to_string();
    assert!(
        e.contains("looked for libdhd-not-installed.so and libdhd-not-installed.so.* in /")
            && e.contains("Force Dimension SDK"),
        "{e}"
    );
    let dir = tempfile::tempdir().unwrap();
    let lib = build(dir.path(), "libdhd_partial.so", &["OMIT_SETFORCE"]);
    let e = probe(lib.to_str().unwrap()).unwrap_err().to_string();
    assert!(e.contains("lacks dhdSetForce"), "{e}");
    let lib = build(dir.path(), "libdhd_none.so", &["STANDIN_NO_DEVICE"]);
    let e = DhdDevice::open(lib.to_str().unwrap(), None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("dhdOpen failed: no device found")
            && e.contains("no Force Dimension device is attached or powered"),
        "{e}"
    );
}

#[test]
fn the_stand_in_reads_position_orientation_and_takes_force() {
    let dir = tempfile::tempdir().unwrap();
    let path = build(dir.path(), "libdhd.so", &[]);
    let lib = probe(path.to_str().unwrap()).unwrap();
    assert_eq!(lib.device_count(), Some(1));
    assert_eq!(lib.sdk_version().as_deref(), Some("3.17.0-9999"));
    assert_eq!(lib.path().as_deref(), Some(path.as_path()));
    let mut dev = DhdDevice::open(path.to_str().unwrap(), None).unwrap();
    let info = dev.info().clone();
    assert!(info.name.contains("omega.7 (stand-in)"), "{}", info.name);
    assert_eq!((info.dof_input, info.dof_output), (6, 3));
    assert_eq!(info.max_force_n, 12.0);
    assert_eq!(info.workspace_max, Vec3::splat(0.075));

    // SAFETY: the stand-in is our own C file; the hook returns a plain int.
    let hooks = unsafe { libloading::Library::new(&path) }.unwrap();
    // SAFETY: matches `int standin_force_on(void)` in dhd_standin.c.
    let force_on =
        unsafe { hooks.get::<unsafe extern "C" fn() -> i32>(b"standin_force_on") }.unwrap();
    // SAFETY: plain C call.
    assert_eq!(unsafe { force_on() }, 0, "force stays off until start");
    dev.start().unwrap();
    // SAFETY: plain C call.
    assert_eq!(unsafe { force_on() }, 1);

    // 1 N along +x for 0.4 s at about 1 kHz: the 200 N/m hand gives way 5 mm.
    let t0 = Instant::now();
    let mut s = dev.read(0).unwrap();
    while t0.elapsed() < Duration::from_millis(400) {
        std::thread::sleep(Duration::from_millis(1));
        s = dev.read(t0.elapsed().as_nanos() as u64).unwrap();
        dev.write_force(Vec3::X).unwrap();
    }
    assert!((s.position.x - 0.005).abs() < 0.001, "{s:?}");
    assert!(
        s.position.y.abs() < 1e-4 && s.position.z.abs() < 1e-4,
        "{s:?}"
    );
    // The wrist turns with x (the stand-in's rule): a unit quaternion about z.
    let q = s.orientation;
    assert!((q.length() - 1.0).abs() < 1e-5, "{q:?}");
    assert!(
        (q.to_axis_angle().1 - s.position.x * 10.0).abs() < 1e-3,
        "{q:?}"
    );
    dev.stop();
    // SAFETY: plain C call.
    assert_eq!(unsafe { force_on() }, 0, "stop turns force off");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_session_drives_the_dhd_stand_in_at_the_servo_rate() {
    let dir = tempfile::tempdir().unwrap();
    let path = build(dir.path(), "libdhd.so", &[]);
    let dev = DhdDevice::open(path.to_str().unwrap(), None).unwrap();
    // SAFETY: the stand-in is our own C file.
    let hooks = unsafe { libloading::Library::new(&path) }.unwrap();
    // SAFETY: matches `long standin_sets(void)` in dhd_standin.c.
    let sets = unsafe { hooks.get::<unsafe extern "C" fn() -> std::ffi::c_long>(b"standin_sets") }
        .unwrap();
    let server = Server::start(dev, ServerOptions::for_tests(TransportKind::Udp).unwrap()).unwrap();
    let mut client = haptics_server::client::Client::connect(&config(&server, TransportKind::Udp))
        .await
        .unwrap();
    assert!(
        client.welcome.device_name.contains("omega.7"),
        "{:?}",
        client.welcome
    );
    let f = Vec3::new(0.0, 0.0, 0.5);
    stream_until(
        &mut client,
        "the stylus pushed along +z",
        |_| constant(f, (0, 0)),
        |c| c.position.z > 0.001,
    )
    .await;
    let ticks = server.servo_stats().ticks;
    // SAFETY: plain C call.
    let written = unsafe { sets() } as u64;
    assert!(
        ticks > 10 && written + 2 >= ticks,
        "a dhdSetForce per servo tick: {written} for {ticks} ticks"
    );
    drop(client);
    server.shutdown();
}
