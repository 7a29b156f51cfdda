//! The second layer of configuration: turn a validated [`ServerConfig`] into things that touch
//! the environment (files, devices, certificates). `main` and tests share it.

use std::path::PathBuf;
use std::time::Duration;

use glam::Vec3;

use crate::config::{DeviceKind, ServerConfig};
use crate::device::axes::AxisMap;
use crate::device::fake::{FakeDevice, FakeParams, HandPath};
use crate::device::hid::{self, Profile, layout::Layout};
use crate::device::replay::ReplayDevice;
use crate::device::{Device, DeviceError, dhd, openhaptics};
use crate::servo::driver::DriverConfig;
use crate::servo::rt::RtRequest;
use crate::servo::{SafetyParams, ServoParams};
use crate::tls::{self, AuthorizedClients, Identity, TlsError};
use crate::transport::NetSettings;

/// `$XDG_CONFIG_HOME/haptics-server`, else `~/.config/haptics-server`, else `./haptics-server`.
pub fn default_cert_dir() -> PathBuf {
    let base = std::env::var_os("XDG_CONFIG_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".config")))
        .unwrap_or_else(|| PathBuf::from("."));
    base.join("haptics-server")
}

/// Where the certificate and key are, per the config (or the default location).
pub fn cert_paths(cfg: &ServerConfig) -> (PathBuf, PathBuf) {
    match (&cfg.network.cert, &cfg.network.key) {
        (Some(c), Some(k)) => (c.clone(), k.clone()),
        _ => {
            let d = default_cert_dir();
            (d.join("cert.pem"), d.join("key.pem"))
        }
    }
}

/// Load the identity; at the default location, create it on first use. Returns the identity,
/// the certificate path and whether it was just generated.
pub fn identity(cfg: &ServerConfig) -> Result<(Identity, PathBuf, bool), TlsError> {
    let (cert, key) = cert_paths(cfg);
    let explicit = cfg.network.cert.is_some();
    if !explicit && !cert.exists() && !key.exists() {
        let id = tls::generate()?;
        tls::write_pem(&id, &cert, &key)?;
        return Ok((id, cert, true));
    }
    Ok((tls::read_identity(&cert, &key)?, cert, false))
}

/// The authorized client list's path: `network.authorized_clients`, else
/// `authorized_clients.pem` next to the certificate.
pub fn authorized_clients_path(cfg: &ServerConfig) -> PathBuf {
    cfg.network.authorized_clients.clone().unwrap_or_else(|| {
        let (cert, _) = cert_paths(cfg);
        cert.with_file_name("authorized_clients.pem")
    })
}

/// The authorized clients and the local client identity. When the list is at its default
/// place and does not exist yet, a client identity is created next to the certificate
/// (`client.pem`, `client.key`) and becomes the list's first entry: a workstation on this
/// machine that pins `cert.pem` finds it there (zero steps on loopback). A configured list
/// must exist. Returns the list, its path, the local identity if there is one, and whether it
/// was just created.
pub fn authorized_clients(
    cfg: &ServerConfig,
) -> Result<(AuthorizedClients, PathBuf, Option<Identity>, bool), TlsError> {
    let path = authorized_clients_path(cfg);
    let (cert, _) = cert_paths(cfg);
    let dir = cert.parent().map(PathBuf::from).unwrap_or_default();
    let (client_cert, client_key) = (dir.join(tls::CLIENT_FILES.0), dir.join(tls::CLIENT_FILES.1));
    let mut created = false;
    if cfg.network.authorized_clients.is_none() && !path.exists() {
        if !client_cert.exists() && !client_key.exists() {
            let id = tls::generate_client()?;
            tls::write_pem(&id, &client_cert, &client_key)?;
        }
        let id = tls::read_identity(&client_cert, &client_key)?;
        tls::append_certificate(&path, &id.cert)?;
        created = true;
    }
    let list = AuthorizedClients::read(&path).map_err(|e| match e {
        TlsError::File { path, reason } => TlsError::File {
            path,
            reason: format!("network.authorized_clients: {reason}"),
        },
        other => other,
    })?;
    let local = tls::read_identity(&client_cert, &client_key)
        .ok()
        .filter(|id| list.contains(&id.cert));
    Ok((list, path, local, created))
}

/// Open the configured device.
pub fn open_device(cfg: &ServerConfig) -> Result<Box<dyn Device>, DeviceError> {
    let d = &cfg.device;
    Ok(match d.kind {
        DeviceKind::Fake => {
            let f = &d.fake;
            let start = Vec3::ZERO;
            let path = match f.path.as_str() {
                "idle" => HandPath::Idle { at: start },
                "line" => HandPath::Line {
                    from: start - Vec3::X * f.size_m / 2.0,
                    to: start + Vec3::X * f.size_m / 2.0,
                    period_s: f.period_s,
                },
                "press" => HandPath::Press {
                    at: start,
                    depth: f.size_m,
                    approach_s: f.period_s / 4.0,
                    hold_s: f.period_s / 4.0,
                },
                "file" => {
                    HandPath::load(f.path_file.as_deref().unwrap_or(std::path::Path::new("")))?
                }
                _ => HandPath::Circle {
                    center: start,
                    radius: f.size_m,
                    period_s: f.period_s,
                },
            };
            let axes = AxisMap::parse(&f.axes)
                .map_err(|e| DeviceError::Open(format!("device.fake.axes: {e}")))?;
            Box::new(FakeDevice::new(FakeParams {
                path,
                seed: f.seed,
                tremor_m: f.tremor_m,
                axes,
                ..FakeParams::default()
            }))
        }
        DeviceKind::Replay => {
            let file = d
                .replay
                .file
                .as_deref()
                .ok_or_else(|| DeviceError::Open("device.replay.file is not set".into()))?;
            Box::new(ReplayDevice::open(file, d.replay.looped)?)
        }
        DeviceKind::Hid => {
            let profile = match d.hid.profile.as_str() {
                "layout" => Profile::Layout(Box::new(Layout::load(
                    d.hid
                        .layout_file
                        .as_deref()
                        .unwrap_or(std::path::Path::new("")),
                )?)),
                _ => Profile::SpaceMouse { speed_m_s: 0.1 },
            };
            Box::new(hid::open(d.hid.vendor_id, d.hid.product_id, profile)?)
        }
        DeviceKind::Openhaptics => Box::new(openhaptics::OpenHapticsDevice::open(
            &d.openhaptics.library,
            &d.openhaptics.device_name,
        )?),
        DeviceKind::Dhd => Box::new(dhd::DhdDevice::open(&d.dhd.library, d.dhd.index)?),
    })
}

/// Servo settings from the config.
pub fn driver_config(cfg: &ServerConfig) -> DriverConfig {
    let (s, f) = (&cfg.servo, &cfg.safety);
    let ms = |v: f32| (f64::from(v) * 1e6) as u64;
    DriverConfig {
        params: ServoParams {
            rate_hz: s.rate_hz,
            safety: SafetyParams {
                max_force_n: f.max_force_n,
                engage_threshold_n: f.engage_threshold_n,
                ramp_ns: u64::from(f.ramp_ms) * 1_000_000,
                slew_n_per_s: f.slew_n_per_s,
                watchdog_fade_start_ns: ms(f.watchdog_fade_start_ms),
                watchdog_zero_ns: ms(f.watchdog_zero_ms),
            },
            smoothing_alpha: f.smoothing_alpha,
            device_max_force_n: f.max_force_n,
            max_stiffness_n_per_m: f.max_stiffness_n_per_m,
            max_damping_n_s_per_m: f.max_damping_n_s_per_m,
            estop_button_mask: s.estop_button_mask,
            passivity: s.passivity,
        },
        rt: RtRequest {
            fifo_priority: (s.realtime_priority > 0).then_some(s.realtime_priority),
            cpu: s.cpu,
            mlockall: s.mlockall,
        },
        spin: Duration::from_micros(u64::from(s.spin_us)),
        log_every: Duration::from_secs_f32(cfg.telemetry.log_interval_s),
        record: cfg.telemetry.record.clone(),
        cursor_deadband: cfg.network.cursor_deadband,
    }
}

/// Network timeouts from the config.
pub fn net_settings(cfg: &ServerConfig) -> NetSettings {
    NetSettings {
        idle_timeout: Duration::from_millis(cfg.network.idle_timeout_ms),
        stats_interval: Duration::from_millis(cfg.network.stats_interval_ms),
        ..NetSettings::default()
    }
}
