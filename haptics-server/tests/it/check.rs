//! `haptics-server check` and `devices` run as a lab would run them: the binary, its exit
//! code, its summary and its JSON report, on the fake, replay and stand-in backends.

use std::path::Path;
use std::process::{Command, Output, Stdio};

use crate::common::build_standin;

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_haptics-server"));
    c.env("NO_COLOR", "1").stdin(Stdio::null());
    c
}

fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("run haptics-server")
}

fn text(out: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).expect("report written"))
        .expect("report is JSON")
}

/// A region like the demo scene's: the upper half of a 10 cm ball.
const REGION: &str = "-0.05,0,-0.05,0.05,0.06,0.05";

#[test]
fn a_correct_fake_passes_the_force_test_and_prints_the_scene_transform() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("day-one.json");
    let out = run(&[
        "check",
        "--device",
        "fake",
        "--no-realtime",
        "--seconds",
        "0.5",
        "--force-test",
        "--yes",
        "--region",
        REGION,
        "--out",
        report.to_str().unwrap(),
    ]);
    let (stdout, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(0), "{stdout}\n{stderr}");
    for want in [
        "PASS axes",
        "commanded +x, moved mostly +x",
        "commanded -z, moved mostly -z",
        "PASS watchdog",
        "PASS clamp",
        "PASS slew",
        "[device]\nscale = 0.625\ntranslation = [0.0, 0.03, 0.0]\nrotation_deg = [0.0, 0.0, 0.0]\n",
        "result: PASS",
    ] {
        assert!(stdout.contains(want), "lacks {want:?}:\n{stdout}");
    }
    assert!(
        stderr.contains("--yes: starting the force test"),
        "{stderr}"
    );
    let r = json(&report);
    assert_eq!(r["passed"], true);
    assert_eq!(r["device"]["kind"], "fake");
    assert_eq!(r["force_test"]["axis_map"], "x,y,z");
    assert_eq!(r["force_test"]["axes"].as_array().unwrap().len(), 6);
    assert_eq!(r["force_test"]["watchdog"]["late_nonzero_ticks"], 0);
    assert_eq!(r["workspace"]["transforms"][0]["scale"], 0.625);
    assert!(
        r["read"]["rate_hz"].as_f64().unwrap() > 300.0,
        "{}",
        r["read"]
    );
}

#[test]
fn a_fake_with_swapped_and_inverted_axes_fails_and_names_them() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("r.json");
    let out = run(&[
        "check",
        "--device",
        "fake",
        "--fake-axes",
        "-x,z,y",
        "--no-realtime",
        "--seconds",
        "0.3",
        "--force-test",
        "--yes",
        "--out",
        report.to_str().unwrap(),
    ]);
    let (stdout, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{stdout}\n{stderr}");
    for want in [
        "FAIL axes",
        "commanded +x, moved mostly -x",
        "mm: axis x inverted",
        "commanded +y, moved mostly +z",
        "moved along +z instead of +y",
        "force axes as measured: -x,z,y (axis x inverted, axes y and z swapped)",
        "--fake-axes",
        "result: FAIL (axes)",
    ] {
        assert!(stdout.contains(want), "lacks {want:?}:\n{stdout}");
    }
    let r = json(&report);
    assert_eq!(r["passed"], false);
    assert_eq!(r["force_test"]["axis_map"], "-x,z,y");
    assert_eq!(r["force_test"]["diagnosis"][1], "axes y and z swapped");
    // The safety stages still held while the axes were wrong.
    assert!(stdout.contains("PASS watchdog"), "{stdout}");
}

#[test]
fn the_force_test_is_refused_without_a_terminal_or_yes() {
    let out = run(&["check", "--device", "fake", "--force-test"]);
    let (stdout, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(2), "{stdout}\n{stderr}");
    assert!(
        stderr.contains("stdin is not a terminal") && stderr.contains("--yes"),
        "{stderr}"
    );
    assert!(stdout.is_empty(), "nothing ran, nothing reported: {stdout}");
    // --yes without --force-test is a usage error (clap's exit code 2).
    let out = run(&["check", "--device", "fake", "--yes"]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn a_replay_reads_back_and_cannot_force() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("session.csv");
    // 1.5 s of a 6 cm stroke along x and 3 cm along y, button 0 pressed from 0.5 to 0.8 s.
    let mut s = String::from(
        "# haptics-server recording v1\nt_ns,px,py,pz,qx,qy,qz,qw,vx,vy,vz,buttons,fx,fy,fz,engaged\n",
    );
    for i in 0..1500u64 {
        let t = i as f64 * 1e-3;
        let b = u8::from((0.5..0.8).contains(&t));
        s.push_str(&format!(
            "{},{},{},{},0,0,0,1,0,0,0,{b},0,0,0,0\n",
            i * 1_000_000,
            -0.03 + 0.04 * t,
            0.02 * t,
            0.025 * t
        ));
    }
    std::fs::write(&rec, s).unwrap();
    let report = dir.path().join("r.json");
    let out = run(&[
        "check",
        "--device",
        "replay",
        "--replay-file",
        rec.to_str().unwrap(),
        "--no-realtime",
        "--seconds",
        "1.2",
        "--region",
        REGION,
        "--out",
        report.to_str().unwrap(),
    ]);
    let (stdout, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(0), "{stdout}\n{stderr}");
    assert!(
        stdout.contains("PASS buttons         1 presses"),
        "{stdout}"
    );
    assert!(stdout.contains("workspace seen:"), "{stdout}");
    // The range seen spans 2 cm on every axis: a second transform from it.
    assert!(
        stdout.contains("scene transform from the seen workspace"),
        "{stdout}"
    );
    let r = json(&report);
    assert_eq!(r["read"]["button_presses"], 1);
    assert_eq!(r["workspace"]["transforms"].as_array().unwrap().len(), 2);
    let seen_min = r["workspace"]["seen"]["min"][0].as_f64().unwrap();
    assert!((seen_min + 0.03).abs() < 1e-3, "{seen_min}");

    let out = run(&[
        "check",
        "--device",
        "replay",
        "--replay-file",
        rec.to_str().unwrap(),
        "--no-realtime",
        "--seconds",
        "0.3",
        "--force-test",
        "--yes",
    ]);
    let (stdout, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{stdout}\n{stderr}");
    assert!(
        stdout.contains("FAIL force test") && stdout.contains("has no force output"),
        "{stdout}"
    );
}

#[test]
fn the_dhd_stand_in_passes_and_a_miswired_one_is_caught() {
    let dir = tempfile::tempdir().unwrap();
    let good = build_standin("dhd_standin.c", dir.path(), "libdhd.so", &[]);
    let swapped = build_standin(
        "dhd_standin.c",
        dir.path(),
        "libdhd_swapped.so",
        &["STANDIN_SWAP_XY"],
    );
    let args = |lib: &Path| {
        vec![
            "check".to_owned(),
            "--device".into(),
            "dhd".into(),
            "--dhd-library".into(),
            lib.to_str().unwrap().into(),
            "--no-realtime".into(),
            "--seconds".into(),
            "0.3".into(),
            "--force-test".into(),
            "--yes".into(),
            "--region".into(),
            REGION.into(),
        ]
    };
    let out = bin().args(args(&good)).output().unwrap();
    let (stdout, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(0), "{stdout}\n{stderr}");
    assert!(
        stdout.contains("omega.7 (stand-in)") && stdout.contains("6-DOF in / 3-DOF force out"),
        "{stdout}"
    );
    assert!(
        stdout.contains("frame:  Force Dimension: x toward the user, y right, z up"),
        "{stdout}"
    );
    // The vendor frame is z-up: the scene transform turns it y-up (device x, y, z become
    // scene z, x, y; unit-tested in check::calibration).
    assert!(
        stdout.contains(
            "[device]\nscale = 0.666666667\ntranslation = [0.0, 0.03, 0.0]\nrotation_deg = [-90.0, 0.0, -90.0]\n"
        ),
        "{stdout}"
    );

    let out = bin().args(args(&swapped)).output().unwrap();
    let (stdout, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{stdout}\n{stderr}");
    assert!(
        stdout.contains("commanded +x, moved mostly +y")
            && stdout.contains("axes x and y swapped")
            && stdout.contains("HapticDesk"),
        "{stdout}"
    );
}

#[test]
fn the_openhaptics_stand_in_passes_under_its_own_scheduler() {
    let dir = tempfile::tempdir().unwrap();
    let lib = build_standin("hd_standin.c", dir.path(), "libHD.so", &[]);
    let out = run(&[
        "check",
        "--device",
        "openhaptics",
        "--openhaptics-library",
        lib.to_str().unwrap(),
        "--no-realtime",
        "--seconds",
        "0.3",
        "--force-test",
        "--yes",
    ]);
    let (stdout, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(0), "{stdout}\n{stderr}");
    assert!(
        stdout.contains("PASS axes") && stdout.contains("PASS watchdog"),
        "{stdout}"
    );
}

#[test]
fn a_missing_library_cannot_run_and_says_where_it_looked() {
    let out = run(&[
        "check",
        "--device",
        "dhd",
        "--dhd-library",
        "libdhd-not-installed.so",
    ]);
    let (_, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("opening the device")
            && stderr.contains("looked for libdhd-not-installed.so and libdhd-not-installed.so.*"),
        "{stderr}"
    );
}

#[test]
fn devices_lists_the_libraries_and_where_they_load_from() {
    let dir = tempfile::tempdir().unwrap();
    let dhd = build_standin("dhd_standin.c", dir.path(), "libdhd.so", &[]);
    let out = run(&[
        "devices",
        "--dhd-library",
        dhd.to_str().unwrap(),
        "--openhaptics-library",
        "libHD-not-installed.so",
    ]);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stdout}\n{stderr}");
    // Each library: a header line, then its detail indented on the next.
    let section = |name: &str| {
        let lines: Vec<&str> = stdout.lines().collect();
        let at = lines
            .iter()
            .position(|l| l.starts_with(&format!("{name}: ")))
            .unwrap_or_else(|| panic!("no {name} section:\n{stdout}"));
        format!("{}\n{}", lines[at], lines[at + 1])
    };
    let dhd_text = section("dhd");
    assert!(
        dhd_text.starts_with(&format!(
            "dhd: {} loads from {}\n",
            dhd.display(),
            dhd.display()
        )) && dhd_text.contains("loads and exports every function")
            && dhd_text.contains("SDK 3.17.0-9999")
            && dhd_text.contains("dhdGetDeviceCount() = 1"),
        "{dhd_text}"
    );
    let oh_text = section("openhaptics");
    assert!(
        oh_text.contains("DOES NOT LOAD")
            && oh_text.contains("looked for libHD-not-installed.so and libHD-not-installed.so.*")
            && oh_text.contains("device.openhaptics.library (--openhaptics-library)"),
        "{oh_text}"
    );
    assert!(stdout.contains("fake: always available"), "{stdout}");
    assert!(stdout.contains("next: `haptics-server check"), "{stdout}");

    let out = run(&[
        "devices",
        "--json",
        "--all",
        "--dhd-library",
        dhd.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let libs = v["libraries"].as_array().unwrap();
    assert_eq!(libs.len(), 2);
    assert_eq!(libs[1]["backend"], "dhd");
    assert_eq!(libs[1]["ok"], true);
    assert_eq!(libs[1]["path"], dhd.to_str().unwrap());
    assert_eq!(libs[0]["ok"], false);
    assert!(v["hid"].is_array() && v["usb"].is_array(), "{v}");
}

#[test]
fn help_teaches_the_day_one_commands() {
    let out = run(&["check", "--help"]);
    let (help, _) = text(&out);
    for want in [
        "--force-test",
        "--yes",
        "--region",
        "--out",
        "--fake-axes",
        "--dhd-library",
        "axis x",
        "Exit code: 0",
    ] {
        assert!(help.contains(want), "check --help lacks {want}:\n{help}");
    }
    let out = run(&["devices", "--help"]);
    let (help, _) = text(&out);
    for want in ["--all", "--json", "70-haptics.rules", "libdhd.so"] {
        assert!(help.contains(want), "devices --help lacks {want}:\n{help}");
    }
    let out = run(&["--help"]);
    let (help, _) = text(&out);
    for want in ["dhd", "check", "devices", "Day one"] {
        assert!(help.contains(want), "--help lacks {want}:\n{help}");
    }
}
