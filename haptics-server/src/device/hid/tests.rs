//! Both profiles against recorded report bytes, through the same `Device` code as hardware.

use glam::Vec3;

use super::layout::Layout;
use super::{HidDevice, Profile, RecordedReports};
use crate::device::Device;

const LAYOUT: &str = r#"
name = "bench rig"
max_force_n = 2.0
[input]
report_id = 1
x = { offset = 1, size = 2, signed = true, scale = 1e-5 }
y = { offset = 3, size = 2, signed = true, scale = 1e-5 }
z = { offset = 5, size = 2, signed = true, scale = 1e-5 }
buttons = { offset = 7, size = 1 }
[force]
report_id = 2
length = 7
x = { offset = 1, size = 2, signed = true, scale = 1e-3 }
y = { offset = 3, size = 2, signed = true, scale = 1e-3 }
z = { offset = 5, size = 2, signed = true, scale = 1e-3 }
"#;

fn reports(input: &[&[u8]]) -> RecordedReports {
    RecordedReports {
        input: input.iter().map(|r| r.to_vec()).collect(),
        output: Vec::new(),
    }
}

#[test]
fn spacemouse_reports_drive_a_rate_controlled_cursor() {
    // Recorded from a SpaceMouse-class device: translation +175 counts on x (half scale),
    // rotation report, then button 1 pressed.
    let io = reports(&[
        &[1, 0xaf, 0x00, 0x00, 0x00, 0x00, 0x00],
        &[2, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00],
        &[3, 0x01, 0x00],
    ]);
    let mut dev = HidDevice::new(io, Profile::SpaceMouse { speed_m_s: 0.1 }, "SpaceMouse");
    assert_eq!(dev.info().dof_output, 0);
    dev.read(0).unwrap();
    // 100 ms (two reads 50 ms apart) at half deflection × 0.1 m/s = 5 mm along x.
    dev.read(50_000_000).unwrap();
    let s = dev.read(100_000_000).unwrap();
    assert!((s.position.x - 0.005).abs() < 1e-6, "{}", s.position);
    assert_eq!(s.buttons, 1);
    assert!((s.velocity.x - 0.05).abs() < 1e-4);
    // Holding still: the cursor stays inside the workspace however long it runs.
    let s = dev.read(60_000_000_000).unwrap();
    assert!(s.position.x <= dev.info().workspace_max.x);
}

#[test]
fn spacemouse_combined_six_axis_report() {
    let io = reports(&[&[1, 0, 0, 0x5e, 0x01, 0, 0, 0, 0, 0, 0, 0x5e, 0x01]]);
    let mut dev = HidDevice::new(io, Profile::SpaceMouse { speed_m_s: 0.1 }, "SpaceMouse");
    dev.read(0).unwrap();
    let s = dev.read(10_000_000).unwrap();
    assert!((s.position.y - 0.001).abs() < 1e-6, "{}", s.position);
    assert!(s.orientation.z.abs() > 0.0 && s.orientation.is_normalized());
}

#[test]
fn layout_profile_decodes_encoders_and_encodes_forces() {
    let layout = Layout::from_toml(LAYOUT, "rig.toml").unwrap();
    // x = 1000 counts = 10 mm, y = −500 = −5 mm, z = 0; button 0b101; then a foreign report.
    let io = reports(&[&[1, 0xe8, 0x03, 0x0c, 0xfe, 0, 0, 0b101], &[9, 1, 2, 3]]);
    let mut dev = HidDevice::new(io, Profile::Layout(Box::new(layout)), "bench rig");
    assert_eq!((dev.info().dof_output, dev.info().max_force_n), (3, 2.0));
    let s = dev.read(0).unwrap();
    assert!(
        (s.position - Vec3::new(0.01, -0.005, 0.0)).length() < 1e-7,
        "{}",
        s.position
    );
    assert_eq!(s.buttons, 0b101);
    dev.write_force(Vec3::new(1.5, -0.25, 100.0)).unwrap();
    dev.write_force(Vec3::NAN).unwrap();
    let out = &dev.io().output;
    // 1.5 N = 1500 counts; −0.25 N = −250; 100 N saturates at i16::MAX.
    assert_eq!(out[0], vec![2, 0xdc, 0x05, 0x06, 0xff, 0xff, 0x7f]);
    assert_eq!(
        out[1],
        vec![2, 0, 0, 0, 0, 0, 0],
        "non-finite is written as zero"
    );
}

#[test]
fn layout_errors_name_the_field() {
    let bad = LAYOUT.replace("length = 7", "length = 4");
    let e = Layout::from_toml(&bad, "rig.toml").unwrap_err().to_string();
    assert!(e.contains("force.y") && e.contains("does not fit"), "{e}");
    let bad = LAYOUT.replace(
        "size = 2, signed = true, scale = 1e-5 }\ny",
        "size = 3, signed = true, scale = 1e-5 }\ny",
    );
    let e = Layout::from_toml(&bad, "rig.toml").unwrap_err().to_string();
    assert!(e.contains("input.x.size"), "{e}");
}
