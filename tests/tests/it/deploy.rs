//! `deploy/` as a lab uses it: the example server configurations load through the real config
//! loader and validate; both systemd units pass `systemd-analyze verify` (on copies whose
//! ExecStart names the built binaries, since nothing is installed under /usr/local/bin here) and
//! name only flags the binaries have; the udev rules are well formed, name the vendor ids the
//! code knows and give the `haptics` group access (`udevadm verify` too where udevadm has it);
//! the netem script builds two namespaces with the promised round trip and removes them again.
//!
//! Checks that need a tool this machine lacks (systemd-analyze, udevadm ≥ 254, root with ip, tc
//! and ping, a kernel with netem) print `skipped: …` to stderr and check what they still can;
//! none passes as if it had verified what it did not.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use haptics_server::config::{DeviceKind, ServerConfig};

fn deploy_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../deploy")
}

fn on_path(tool: &str) -> bool {
    std::env::var_os("PATH")
        .is_some_and(|p| std::env::split_paths(&p).any(|d| d.join(tool).is_file()))
}

fn text(out: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

// ---------------------------------------------------------------------------------------------
// Example configurations.

#[test]
fn every_example_server_config_loads_and_validates() {
    let dir = deploy_dir().join("examples");
    let mut checked = Vec::new();
    let mut workstation_files = Vec::new();
    for entry in std::fs::read_dir(&dir).expect("deploy/examples") {
        let path = entry.expect("dir entry").path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        // Every TOML here is a server config unless its name says workstation, so a misnamed
        // server config cannot slip past the loader; workstation ones go through theirs.
        if name.contains("workstation") {
            let f = workstation::live::net::ConnectionFile::load(&path)
                .unwrap_or_else(|e| panic!("{name} does not load: {e}"));
            assert!(
                f.server.client_cert.is_some() && f.server.client_key.is_some(),
                "{name}: a lab workstation names its client identity"
            );
            workstation_files.push(name);
            continue;
        }
        let src = std::fs::read_to_string(&path).expect("read example");
        let cfg = ServerConfig::from_toml(&src, &name)
            .unwrap_or_else(|e| panic!("{name} does not parse: {e}"));
        cfg.validate()
            .unwrap_or_else(|e| panic!("{name} does not validate: {e}"));
        checked.push((name, cfg));
    }
    checked.sort_by(|a, b| a.0.cmp(&b.0));
    let names: Vec<&str> = checked.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "lab-server.toml",
            "latency-server.toml",
            "loopback-fake-server.toml"
        ],
        "the examples deploy/README.md walks through"
    );
    let get = |n: &str| &checked.iter().find(|(name, _)| name == n).unwrap().1;
    let lab = get("lab-server.toml");
    assert!(
        lab.network.listen.ip().is_unspecified(),
        "the lab server serves another machine"
    );
    assert_eq!(lab.device.kind, DeviceKind::Openhaptics);
    assert!(
        lab.network.cert.is_some(),
        "the lab server names its certificate"
    );
    let lb = get("loopback-fake-server.toml");
    assert!(lb.network.listen.ip().is_loopback());
    assert_eq!(lb.device.kind, DeviceKind::Fake);
    let lat = get("latency-server.toml");
    assert_eq!(lat.device.kind, DeviceKind::Fake);
    assert_eq!(lat.device.fake.path, "idle");
    workstation_files.sort();
    assert_eq!(
        workstation_files,
        ["lab-workstation.toml", "latency-workstation.toml"]
    );
    eprintln!("deploy: loaded and validated {names:?} and {workstation_files:?}");
}

// ---------------------------------------------------------------------------------------------
// systemd units.

/// A unit file's ExecStart= with continuation lines joined.
fn exec_start(unit: &str) -> String {
    let joined = unit.replace("\\\n", " ");
    joined
        .lines()
        .find_map(|l| l.strip_prefix("ExecStart="))
        .expect("an ExecStart= line")
        .to_owned()
}

/// A workspace binary of the running test's profile, if it has been built.
fn built_binary(name: &str) -> Option<PathBuf> {
    let exe = std::env::current_exe().ok()?;
    let path = exe.parent()?.parent()?.join(name);
    path.is_file().then_some(path)
}

/// `systemd-analyze verify` of `files`; its complaints about them (it exits 0 on unknown keys
/// and bad values, so the output is what tells).
fn systemd_verify(files: &[PathBuf]) -> Result<(), String> {
    let out = Command::new("systemd-analyze")
        .args(["verify", "--man=no"])
        .args(files)
        .output()
        .expect("run systemd-analyze");
    let all = text(&out);
    let names: Vec<String> = files
        .iter()
        .map(|f| f.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    let complaints: Vec<&str> = all
        .lines()
        .filter(|l| names.iter().any(|n| l.contains(n.as_str())))
        .collect();
    if out.status.success() && complaints.is_empty() {
        Ok(())
    } else {
        Err(format!("exit {:?}:\n{all}", out.status.code()))
    }
}

#[test]
fn both_systemd_units_verify_and_name_real_flags() {
    let units: [(&str, &str, &[&str]); 2] = [
        ("haptics-server.service", "haptics-server", &[]),
        ("workstation.service", "workstation", &["run"]),
    ];
    let dir = tempfile::tempdir().expect("tempdir");
    let mut copies = Vec::new();
    for (unit, bin, subcommand) in units {
        let src = std::fs::read_to_string(deploy_dir().join(unit)).expect("read unit");
        let installed = format!("/usr/local/bin/{bin}");
        let exec = exec_start(&src);
        assert!(
            exec.starts_with(&format!("{installed} ")),
            "{unit}: ExecStart should run {installed}: {exec}"
        );
        // The built binary stands in for the installed one: verify checks that it is executable.
        let stand_in = match built_binary(bin) {
            Some(b) => {
                // Every --flag the unit passes must be one the binary has.
                let help = Command::new(&b)
                    .args(subcommand)
                    .arg("--help")
                    .output()
                    .expect("run --help");
                let help = text(&help);
                for flag in exec.split_whitespace().filter(|w| w.starts_with("--")) {
                    assert!(
                        help.contains(&format!("{flag} ")) || help.contains(&format!("{flag}\n")),
                        "{unit}: {bin} {} has no {flag}:\n{help}",
                        subcommand.join(" ")
                    );
                }
                eprintln!(
                    "deploy: {unit}: every ExecStart flag is in `{}`",
                    [&[bin][..], subcommand, &["--help"]].concat().join(" ")
                );
                b
            }
            None => {
                eprintln!(
                    "skipped: {unit}: the ExecStart flags against `{bin} --help` ({bin} is not built \
                     in this profile: `cargo build -p {bin}`); verifying the unit with this test's own \
                     executable standing in for {installed}"
                );
                std::env::current_exe().expect("test exe")
            }
        };
        let copy = dir.path().join(unit);
        std::fs::write(
            &copy,
            src.replace(&installed, &stand_in.display().to_string()),
        )
        .expect("write copy");
        copies.push(copy);
    }
    if !on_path("systemd-analyze") {
        eprintln!(
            "skipped: systemd-analyze verify: systemd-analyze not installed (Debian package systemd)"
        );
        return;
    }
    // The checker catches what it should, or a clean result would mean nothing.
    let bad = dir.path().join("bad-example.service");
    std::fs::write(
        &bad,
        "[Service]\nExecStart=/bin/sh -c true\nRestart=sometimes\nLimitRTPRI=90\n",
    )
    .expect("write bad unit");
    assert!(
        systemd_verify(std::slice::from_ref(&bad)).is_err(),
        "systemd-analyze verify accepted a unit with a bad value and an unknown key"
    );
    if let Err(e) = systemd_verify(&copies) {
        panic!("systemd-analyze verify: {e}");
    }
    eprintln!(
        "deploy: systemd-analyze verify: haptics-server.service and workstation.service clean"
    );
}

// ---------------------------------------------------------------------------------------------
// udev rules.

const MATCH_KEYS: [&str; 12] = [
    "ACTION",
    "KERNEL",
    "KERNELS",
    "SUBSYSTEM",
    "SUBSYSTEMS",
    "DRIVER",
    "DRIVERS",
    "ATTR",
    "ATTRS",
    "ENV",
    "TAG",
    "TAGS",
];
const ASSIGN_KEYS: [&str; 8] = [
    "GROUP", "MODE", "OWNER", "TAG", "SYMLINK", "ENV", "RUN", "OPTIONS",
];

/// One `KEY{attr}OP"value"` of a rule.
#[derive(Debug)]
struct Pair {
    key: String,
    attr: Option<String>,
    op: String,
    value: String,
}

/// Parse one rule line the way udev reads it: comma-separated pairs with a known key, an
/// operator that fits it (match keys `==`/`!=`, assignments `=`/`+=`/`-=`/`:=`) and a quoted
/// value. The error names what is wrong.
fn parse_rule(line: &str) -> Result<Vec<Pair>, String> {
    let mut pairs = Vec::new();
    let mut rest = line.trim();
    while !rest.is_empty() {
        let key_end = rest
            .find(|c: char| !(c.is_ascii_uppercase() || c == '_'))
            .ok_or_else(|| format!("no operator after {rest:?}"))?;
        let key = &rest[..key_end];
        rest = &rest[key_end..];
        let mut attr = None;
        if let Some(r) = rest.strip_prefix('{') {
            let close = r.find('}').ok_or("unclosed {")?;
            attr = Some(r[..close].to_owned());
            rest = &r[close + 1..];
        }
        let op = ["==", "!=", "+=", "-=", ":=", "="]
            .into_iter()
            .find(|op| rest.starts_with(op))
            .ok_or_else(|| format!("{key}: no operator"))?;
        rest = &rest[op.len()..];
        let r = rest
            .strip_prefix('"')
            .ok_or_else(|| format!("{key}: value not quoted"))?;
        let close = r
            .find('"')
            .ok_or_else(|| format!("{key}: unclosed quote"))?;
        let value = r[..close].to_owned();
        rest = r[close + 1..].trim_start();
        let is_match = op == "==" || op == "!=";
        let known = if is_match {
            MATCH_KEYS.contains(&key)
        } else {
            ASSIGN_KEYS.contains(&key)
        };
        if !known {
            return Err(format!("{key}{op}: not a udev key for that operator"));
        }
        if matches!(key, "ATTR" | "ATTRS" | "ENV") && attr.is_none() {
            return Err(format!("{key} needs {{name}}"));
        }
        pairs.push(Pair {
            key: key.to_owned(),
            attr,
            op: op.to_owned(),
            value,
        });
        if !rest.is_empty() {
            rest = rest
                .strip_prefix(',')
                .ok_or_else(|| format!("expected ',' before {rest:?}"))?
                .trim_start();
        }
    }
    Ok(pairs)
}

#[test]
fn the_udev_rules_are_well_formed_and_cover_the_known_vendors() {
    let path = deploy_dir().join("70-haptics.rules");
    let src = std::fs::read_to_string(&path).expect("read rules");
    // The parser rejects what udev rejects, or a clean parse would mean nothing.
    for bad in [
        r#"KERNEL="hidraw*", GROUP="haptics""#,
        r#"KERNEL=="hidraw*", GROUP==haptics"#,
        r#"KERNEL=="hidraw*" GROUP="haptics""#,
        r#"ATTRS=="256f", GROUP="haptics""#,
        r#"KERNAL=="hidraw*", GROUP="haptics""#,
    ] {
        assert!(parse_rule(bad).is_err(), "accepted: {bad}");
    }
    let mut hidraw_vendors = Vec::new();
    let mut usb_ids: Vec<(u16, Option<u16>)> = Vec::new();
    let mut rules = 0;
    for (n, line) in src.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let pairs = parse_rule(line).unwrap_or_else(|e| panic!("line {}: {e}: {line}", n + 1));
        rules += 1;
        let get = |k: &str, op: &str| {
            pairs
                .iter()
                .find(|p| p.key == k && p.op == op)
                .map(|p| p.value.as_str())
        };
        assert_eq!(get("GROUP", "="), Some("haptics"), "line {}", n + 1);
        assert_eq!(get("MODE", "="), Some("0660"), "line {}", n + 1);
        assert_eq!(get("TAG", "+="), Some("uaccess"), "line {}", n + 1);
        if get("KERNEL", "==") == Some("hidraw*") {
            let vendor = pairs
                .iter()
                .find(|p| p.key == "ATTRS" && p.attr.as_deref() == Some("idVendor"))
                .unwrap_or_else(|| panic!("line {}: a hidraw rule without a vendor", n + 1));
            hidraw_vendors.push(u16::from_str_radix(&vendor.value, 16).expect("hex vendor id"));
        }
        if get("SUBSYSTEM", "==") == Some("usb") {
            let attr = |a: &str| {
                pairs
                    .iter()
                    .find(|p| p.key == "ATTRS" && p.attr.as_deref() == Some(a))
                    .map(|p| u16::from_str_radix(&p.value, 16).expect("hex id"))
            };
            let vendor = attr("idVendor")
                .unwrap_or_else(|| panic!("line {}: a usb rule without a vendor", n + 1));
            usb_ids.push((vendor, attr("idProduct")));
        }
    }
    // Every vendor `haptics-server devices` says the rules cover is in them (USB-level vendors
    // by a usb rule, exactly as narrow as the inventory's product list).
    for k in haptics_server::inventory::KNOWN
        .iter()
        .filter(|k| k.in_rules)
    {
        let covered = hidraw_vendors.contains(&k.vendor_id)
            || usb_ids.iter().any(|&(v, p)| {
                v == k.vendor_id
                    && match (k.products, p) {
                        (None, None) => true,
                        (Some(list), Some(p)) => list.contains(&p),
                        _ => false,
                    }
            });
        assert!(covered, "no rule for {} ({:04x})", k.name, k.vendor_id);
    }
    for v in haptics_server::device::hid::SPACEMOUSE_VENDORS {
        assert!(
            hidraw_vendors.contains(&v),
            "no hidraw rule for vendor {v:04x}, which the hid device opens by default"
        );
    }
    eprintln!(
        "deploy: 70-haptics.rules: {rules} rules parse; hidraw vendors {hidraw_vendors:04x?}"
    );

    if !on_path("udevadm") {
        eprintln!(
            "skipped: udevadm verify: udevadm not installed (Debian package udev); checked with \
             this test's own parser only"
        );
        return;
    }
    let has_verify = Command::new("udevadm")
        .args(["verify", "--help"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !has_verify {
        eprintln!(
            "skipped: udevadm verify: this udevadm has no `verify` (systemd < 254); checked with \
             this test's own parser only"
        );
        return;
    }
    let out = Command::new("udevadm")
        .arg("verify")
        .arg(&path)
        .output()
        .expect("run udevadm verify");
    assert!(out.status.success(), "udevadm verify:\n{}", text(&out));
    eprintln!("deploy: udevadm verify: 70-haptics.rules clean");
}

// ---------------------------------------------------------------------------------------------
// The netem script.

fn script() -> PathBuf {
    deploy_dir().join("netem/two-hosts.sh")
}

/// Runs `two-hosts.sh down` for its prefix when dropped, so a failing test leaves nothing.
#[derive(Debug)]
struct TwoHosts {
    prefix: String,
    /// The first three octets of the pair's /24.
    subnet: &'static str,
}

impl TwoHosts {
    fn run(&self, action: &str, delay_ms: u32) -> Output {
        Command::new("bash")
            .arg(script())
            .arg(action)
            .env("NETEM_PREFIX", &self.prefix)
            .env("DELAY_MS", delay_ms.to_string())
            .env("JITTER_MS", "0")
            .env("LOSS_PCT", "0")
            .env("SUBNET", self.subnet)
            .output()
            .expect("run two-hosts.sh")
    }

    /// Namespaces and links whose names carry the prefix.
    fn leftovers(&self) -> Vec<String> {
        let mut left = Vec::new();
        for args in [&["netns", "list"][..], &["-o", "link", "show"][..]] {
            let out = Command::new("ip").args(args).output().expect("run ip");
            left.extend(
                String::from_utf8_lossy(&out.stdout)
                    .lines()
                    .filter(|l| l.contains(&format!("{}-", self.prefix)))
                    .map(str::to_owned),
            );
        }
        left
    }

    /// `ping` from the workstation namespace to the server: (min, avg, max) RTT in ms.
    fn ping(&self, count: u32) -> (f64, f64, f64) {
        let out = Command::new("ip")
            .args(["netns", "exec", &format!("{}-ws", self.prefix)])
            .args(["ping", "-c", &count.to_string(), "-i", "0.2", "-W", "2"])
            .arg(format!("{}.1", self.subnet))
            .output()
            .expect("run ping");
        let all = text(&out);
        assert!(out.status.success(), "ping failed:\n{all}");
        assert!(all.contains(" 0% packet loss"), "lost packets:\n{all}");
        parse_ping_rtt(&all).unwrap_or_else(|| panic!("no rtt line in:\n{all}"))
    }
}

impl Drop for TwoHosts {
    fn drop(&mut self) {
        let _ = self.run("down", 0);
    }
}

/// `rtt min/avg/max/mdev = 20.1/20.3/20.6/0.2 ms` → (min, avg, max).
fn parse_ping_rtt(out: &str) -> Option<(f64, f64, f64)> {
    let line = out
        .lines()
        .find(|l| l.starts_with("rtt ") || l.starts_with("round-trip"))?;
    let nums: Vec<f64> = line
        .split('=')
        .nth(1)?
        .trim()
        .trim_end_matches(" ms")
        .split('/')
        .map(|s| s.parse().ok())
        .collect::<Option<_>>()?;
    (nums.len() >= 3).then(|| (nums[0], nums[1], nums[2]))
}

#[test]
fn ping_rtt_lines_parse() {
    let out = "5 packets transmitted, 5 received, 0% packet loss, time 803ms\n\
               rtt min/avg/max/mdev = 20.112/20.334/20.601/0.180 ms\n";
    assert_eq!(parse_ping_rtt(out), Some((20.112, 20.334, 20.601)));
    assert_eq!(parse_ping_rtt("no reply"), None);
}

fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
}

#[test]
fn the_netem_script_builds_two_hosts_with_the_round_trip_and_removes_them() {
    let _slot = e2e_tests::wall_clock_slot();
    let missing: Vec<&str> = ["ip", "tc", "ping"]
        .into_iter()
        .filter(|t| !on_path(t))
        .collect();
    if !is_root() || !missing.is_empty() {
        eprintln!(
            "skipped: the netem script: needs root (is root: {}) and ip, tc, ping (missing: \
             {missing:?}; Debian packages iproute2, iputils-ping)",
            is_root()
        );
        return;
    }
    // Unique per test run, so concurrent runs on one machine do not collide.
    let pair = TwoHosts {
        prefix: format!("e2e{}", std::process::id()),
        subnet: "10.77.0",
    };
    assert!(
        pair.leftovers().is_empty(),
        "prefix {} already in use",
        pair.prefix
    );
    let status = pair.run("status", 0);
    assert_eq!(
        status.status.code(),
        Some(4),
        "status before up:\n{}",
        text(&status)
    );

    let up = pair.run("up", 10);
    match up.status.code() {
        Some(0) => {
            // Idempotent: a second `up` changes nothing and succeeds.
            let again = pair.run("up", 10);
            assert!(again.status.success(), "second up:\n{}", text(&again));
            let (min, avg, max) = pair.ping(5);
            eprintln!("deploy: netem 10 ms each way: ping rtt min {min} avg {avg} max {max} ms");
            assert!(
                (19.0..30.0).contains(&avg) && min >= 19.0,
                "10 ms each way should give ≈ 20 ms round trips, got min {min} avg {avg} ms"
            );
        }
        Some(5) => {
            // The script removed what it had made; check, then test what this kernel allows.
            assert!(
                pair.leftovers().is_empty(),
                "a failed up left {:?}",
                pair.leftovers()
            );
            eprintln!(
                "skipped: the 20 ms round trip: this kernel has no netem qdisc ({}); checking the \
                 namespaces and their link without delay instead",
                text(&up).trim()
            );
            let up0 = pair.run("up", 0);
            assert!(up0.status.success(), "up with DELAY_MS=0:\n{}", text(&up0));
            let again = pair.run("up", 0);
            assert!(again.status.success(), "second up:\n{}", text(&again));
            let (min, avg, max) = pair.ping(3);
            eprintln!("deploy: no netem: ping rtt min {min} avg {avg} max {max} ms");
            assert!(
                avg < 5.0,
                "an unshaped veth should answer within 5 ms, got {avg} ms"
            );
        }
        code => panic!("two-hosts.sh up exited {code:?}:\n{}", text(&up)),
    }
    let status = pair.run("status", 0);
    assert!(
        status.status.success(),
        "status while up:\n{}",
        text(&status)
    );

    let down = pair.run("down", 0);
    assert!(down.status.success(), "down:\n{}", text(&down));
    assert!(
        pair.leftovers().is_empty(),
        "down left {:?}",
        pair.leftovers()
    );
    let again = pair.run("down", 0);
    assert!(again.status.success(), "a second down:\n{}", text(&again));
    let status = pair.run("status", 0);
    assert_eq!(
        status.status.code(),
        Some(4),
        "status after down:\n{}",
        text(&status)
    );
    eprintln!(
        "deploy: netem script: up, status, down and nothing left (prefix {})",
        pair.prefix
    );
}

/// A latency run between the two namespaces (server and `udp-echo` in one, `workstation
/// latency` in the other) sees the configured delay: 5 ms each way gives a 10 ms network round
/// trip and 5 ms one way each direction, within the run's own bound.
#[test]
fn a_latency_run_through_netem_reproduces_the_configured_delay() {
    let _slot = e2e_tests::wall_clock_slot();
    if !is_root() || !on_path("ip") || !on_path("tc") {
        eprintln!("skipped: latency through netem: needs root, ip and tc (Debian iproute2)");
        return;
    }
    const DELAY_MS: f64 = 5.0;
    let pair = TwoHosts {
        prefix: format!("lat{}", std::process::id()),
        subnet: "10.78.0",
    };
    let up = pair.run("up", DELAY_MS as u32);
    match up.status.code() {
        Some(0) => {}
        Some(5) => {
            eprintln!(
                "skipped: latency through netem: this kernel has no netem qdisc, so no delay can \
                 be emulated ({})",
                text(&up).trim()
            );
            return;
        }
        code => panic!("two-hosts.sh up exited {code:?}:\n{}", text(&up)),
    }
    let dir = tempfile::tempdir().unwrap();
    let made = Command::new(e2e_tests::binary("haptics-server"))
        .args(["gen-cert", "--out"])
        .arg(dir.path())
        .output()
        .expect("gen-cert");
    assert!(made.status.success(), "gen-cert: {}", text(&made));
    let in_ns = |ns: &str, bin: &str| {
        let mut c = Command::new("ip");
        c.args(["netns", "exec", &format!("{}-{ns}", pair.prefix)])
            .arg(e2e_tests::binary(bin));
        c
    };
    let mut server = in_ns("server", "haptics-server");
    server
        .args(["--device", "fake", "--fake-path", "idle", "--no-realtime"])
        .args(["--listen", "10.78.0.1:7700", "--cert"])
        .arg(dir.path().join("cert.pem"))
        .arg("--key")
        .arg(dir.path().join("key.pem"));
    let _server = e2e_tests::ChildGuard::spawn(server);
    let mut echo = in_ns("server", "workstation");
    echo.args(["udp-echo", "--listen", "10.78.0.1:7701"]);
    let _echo = e2e_tests::ChildGuard::spawn(echo);
    // The server creates the local client identity beside its certificate on start.
    let start = std::time::Instant::now();
    while !dir.path().join("client.key").exists() {
        assert!(start.elapsed().as_secs() < 20, "the server did not start");
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    std::thread::sleep(std::time::Duration::from_millis(300));
    let out = dir.path().join("out");
    let run = in_ns("ws", "workstation")
        .args(["latency", "--server", "10.78.0.1:7700", "--cert"])
        .arg(dir.path().join("cert.pem"))
        .args(["--echo", "10.78.0.1:7701", "--duration", "3", "--out"])
        .arg(&out)
        .output()
        .expect("run workstation latency");
    assert!(run.status.success(), "latency run:\n{}", text(&run));
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let f = |a: &str, b: &str| r[a][b].as_f64().unwrap_or_else(|| panic!("{a}.{b} in {r}"));
    let rtt_ms = f("network_rtt_us", "p50") / 1e3;
    let base_ms = f("baseline_udp_rtt_us", "p50") / 1e3;
    eprintln!(
        "deploy: netem {DELAY_MS} ms each way: network rtt p50 {rtt_ms} ms, bare UDP {base_ms} ms"
    );
    for (what, ms) in [("network round trip", rtt_ms), ("bare UDP", base_ms)] {
        assert!(
            (2.0 * DELAY_MS..2.0 * DELAY_MS + 3.0).contains(&ms),
            "{what} p50 {ms} ms, configured {} ms",
            2.0 * DELAY_MS
        );
    }
    for dir in ["server_to_workstation", "workstation_to_server"] {
        let w = &r["one_way_us"][dir];
        let (p50, bound) = (
            w["p50"].as_f64().unwrap() / 1e3,
            w["bound"].as_f64().unwrap() / 1e3,
        );
        assert!(
            (p50 - DELAY_MS).abs() <= bound + 1.5,
            "{dir}: one way p50 {p50} ms ± {bound} ms, configured {DELAY_MS} ms"
        );
    }
    assert_eq!(r["sessions"], 1);
}

#[test]
fn the_second_sites_zenohd_configuration_loads_and_names_our_keys() {
    let path = deploy_dir().join("zenohd/site-router.json5");
    let config =
        zenoh::Config::from_file(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let json = |key: &str| {
        config
            .get_json(key)
            .unwrap_or_else(|e| panic!("{key}: {e}"))
    };
    assert_eq!(json("mode"), "\"router\"");
    assert_eq!(json("scouting/multicast/enabled"), "false");
    assert_eq!(json("transport/link/tls/enable_mtls"), "true");
    assert_eq!(json("transport/link/tls/verify_name_on_connect"), "true");
    let acl = json("access_control");
    assert!(acl.contains("haptic-sculpt/*/propose/"), "{acl}");
    assert!(acl.contains("\"deny\""), "{acl}");
}
