//! Config parsing and validation.

use super::*;

#[test]
fn defaults_are_valid_and_round_trip() {
    let c = ServerConfig::default();
    c.validate().unwrap();
    let text = toml::to_string(&c).unwrap();
    assert_eq!(ServerConfig::from_toml(&text, "x").unwrap(), c);
}

#[test]
fn errors_name_the_field() {
    let c = ServerConfig::from_toml("[safety]\nwatchdog_zero_ms = 10\n", "c.toml").unwrap();
    let e = c.validate().unwrap_err().to_string();
    assert!(
        e.contains("safety.watchdog_zero_ms") && e.contains("exceed"),
        "{e}"
    );
    let e = ServerConfig::from_toml("[servo]\nrate = 5\n", "c.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("c.toml") && e.contains("rate"), "{e}");
    let e = ServerConfig::from_toml("[servo]\nrate_hz = \"fast\"\n", "c.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("rate_hz"), "{e}");
    let c = ServerConfig::from_toml("[servo]\nrate_hz = 50\n", "c.toml").unwrap();
    assert!(
        c.validate()
            .unwrap_err()
            .to_string()
            .contains("servo.rate_hz")
    );
}

#[test]
fn the_example_config_parses_and_is_valid() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../deploy/haptics-server.example.toml"
    );
    let text = std::fs::read_to_string(path).unwrap();
    let c = ServerConfig::from_toml(&text, path).unwrap();
    c.validate().unwrap();
}

#[test]
fn passivity_and_cursor_deadband_are_checked() {
    let c = ServerConfig::from_toml(
        "[servo]\npassivity = true\n[network]\ncursor_deadband = 0.1\n",
        "c.toml",
    )
    .unwrap();
    c.validate().unwrap();
    assert!(c.servo.passivity && c.network.cursor_deadband == 0.1);
    let c = ServerConfig::from_toml(
        "[servo]\npassivity = true\n[safety]\nmax_damping_n_s_per_m = 0.0\n",
        "c.toml",
    )
    .unwrap();
    let e = c.validate().unwrap_err().to_string();
    assert!(e.contains("servo.passivity"), "{e}");
    let c = ServerConfig::from_toml("[network]\ncursor_deadband = 1.5\n", "c.toml").unwrap();
    let e = c.validate().unwrap_err().to_string();
    assert!(e.contains("network.cursor_deadband"), "{e}");
}
