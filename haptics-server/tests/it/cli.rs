//! The binary's checked interfaces: flags in `--help`, config errors, `gen-cert`, startup.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_haptics-server"))
}

#[test]
fn help_explains_every_checked_flag_and_command() {
    let out = bin().arg("--help").output().unwrap();
    let help = String::from_utf8_lossy(&out.stdout);
    for word in [
        "--device",
        "--transport",
        "--listen",
        "--config",
        "--record",
        "gen-cert",
        "devices",
        "loop-bench",
        "openhaptics",
        "quic",
        "default",
    ] {
        assert!(help.contains(word), "--help lacks {word}:\n{help}");
    }
}

#[test]
fn an_invalid_config_names_the_field_and_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("bad.toml");
    std::fs::write(&f, "[safety]\nslew_n_per_s = -1.0\n").unwrap();
    let out = bin()
        .args(["--config"])
        .arg(&f)
        .arg("--print-config")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("safety.slew_n_per_s") && err.contains("> 0"),
        "{err}"
    );
    std::fs::write(&f, "[network]\ntransport = \"tcp\"\n").unwrap();
    let out = bin()
        .args(["--config"])
        .arg(&f)
        .arg("--print-config")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("transport") && err.contains("tcp"),
        "{err}"
    );
}

#[test]
fn gen_cert_writes_a_pinnable_certificate() {
    let dir = tempfile::tempdir().unwrap();
    let out = bin()
        .args(["gen-cert", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let id = haptics_server::tls::read_identity(
        &dir.path().join("cert.pem"),
        &dir.path().join("key.pem"),
    )
    .unwrap();
    haptics_server::tls::server_config(&id).unwrap();
    // Refuses to overwrite without --force.
    let out = bin()
        .args(["gen-cert", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(!out.status.success());
}

#[test]
fn the_first_run_command_starts_and_says_what_it_does() {
    let dir = tempfile::tempdir().unwrap();
    let mut child = bin()
        .args([
            "--device",
            "fake",
            "--transport",
            "udp",
            "--listen",
            "127.0.0.1:0",
            "--no-realtime",
        ])
        .env("XDG_CONFIG_HOME", dir.path())
        .env("NO_COLOR", "1")
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut text = String::new();
        let mut buf = [0u8; 4096];
        let start = Instant::now();
        while start.elapsed() < Duration::from_secs(30) && !text.contains("pins it") {
            match std::io::Read::read(&mut stderr, &mut buf) {
                Ok(0) | Err(_) => break,
                Ok(n) => text.push_str(&String::from_utf8_lossy(&buf[..n])),
            }
        }
        text
    });
    let text = reader.join().unwrap();
    let _ = child.kill();
    let _ = child.wait();
    assert!(
        text.contains("listening on 127.0.0.1:") && text.contains("via udp"),
        "{text}"
    );
    assert!(
        text.contains("generated a new self-signed certificate"),
        "{text}"
    );
    assert!(dir.path().join("haptics-server/cert.pem").exists());
}
