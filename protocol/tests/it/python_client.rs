//! A Python client written from `docs/PROTOCOL.md` alone decodes the golden packets to the
//! same values: the byte tables are complete enough to implement the protocol elsewhere.

use std::path::PathBuf;
use std::process::Command;

use crate::examples;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn python_decode(golden: &str, mac: bool) -> serde_json::Value {
    let script = root().join("docs/examples/hp_packet.py");
    let hex = root()
        .join("protocol/tests/golden")
        .join(format!("{golden}.hex"));
    let mut cmd = Command::new("python3");
    cmd.arg(&script).arg(&hex);
    if mac {
        cmd.arg("--mac");
    }
    let out = cmd
        .output()
        .expect("python3 is on every project machine (CPython 3.11)");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("python prints JSON")
}

fn close(v: &serde_json::Value, want: &[f32]) -> bool {
    let got: Vec<f64> = v
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    got.len() == want.len()
        && got
            .iter()
            .zip(want)
            .all(|(g, w)| (g - f64::from(*w)).abs() < 1e-6)
}

#[test]
fn python_decodes_the_golden_cursor_and_force() {
    for (name, mac) in [("cursor_udp", true), ("cursor_quic", false)] {
        let v = python_decode(name, mac);
        let c = examples::cursor();
        assert_eq!(v["session"], examples::SESSION);
        assert_eq!(v["sequence"], 7);
        assert!(close(&v["position"], &c.position.to_array()), "{name}: {v}");
        assert!(
            close(&v["orientation"], &c.orientation.to_array()),
            "{name}: {v}"
        );
        assert!(
            close(&v["output_force"], &c.output_force.to_array()),
            "{name}: {v}"
        );
        assert_eq!(v["servo_tick"], c.servo_tick);
        assert_eq!(v["buttons"], c.buttons);
        assert_eq!(v["engaged"], true);
        let ack = c.ack.expect("the example acknowledges a command");
        assert_eq!(v["ack"]["sequence"], ack.sequence, "{name}: {v}");
        assert_eq!(v["ack"]["arrival_ns"], ack.arrival_ns, "{name}: {v}");
    }
    let v = python_decode("force_udp", true);
    let f = examples::force();
    assert!(close(&v["force"], &f.force.to_array()), "{v}");
    assert_eq!(v["torque"], serde_json::Value::Null);
    assert_eq!(v["answers_sequence"], f.answers_sequence);
    assert_eq!(v["answers_timestamp_ns"], f.answers_timestamp_ns);
    assert_eq!(v["model"], "plane");
    assert!(close(&v["normal"], &f.model.normal.to_array()), "{v}");
    assert!(
        close(
            &serde_json::json!([v["stiffness"], v["friction"]]),
            &[500.0, 0.25]
        ),
        "{v}"
    );
    assert_eq!(v["lifetime_us"], f.model.lifetime_us);
}
